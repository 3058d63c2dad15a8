"""
Your own robot: a setup file, from certificate to tuner
=======================================================

Everything in teleopkit defaults to the source paper's teleoperator. This tutorial brings
another one: a 2-link arm with other link lengths and masses, a remote arm whose links carry
their mass at their centres with a link inertia, softer joints and other local gains, behind a
0.05-0.6 s network, driven by a recorded hand motion. It is described once, in a *setup file*,
and every step takes that file: ``--setup FILE`` on the command line, ``setup=`` in Python,
with the same numbers either way. We certify gains for it, simulate it with two recorded delay
traces, train a tuner on it and evaluate the tuner against comparators searched for this
setup (not the paper's).
"""

# %%
# Budget
# ------
# ``TELEOPKIT_DOCS_BUDGET=small`` (the documentation build) trains 4 rounds of 8 scenarios on
# 4 s episodes and evaluates on 8 held-out scenarios: a minute or two, and far too little
# training for a good tuner. ``full`` trains 20 rounds of 16 scenarios of 20 s.
import os
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import torch

import teleopkit as tk
from teleopkit.certification.certifier import certify_gains, default_certificate
from teleopkit.certification.gain_sets import GainBox
from teleopkit.rl.comparison import REFERENCE, compare
from teleopkit.rl.env import COVERING_CLASS, FlexTeleopConfig
from teleopkit.rl.evaluation import summarise, to_markdown
from teleopkit.rl.policy import GainPolicy
from teleopkit.rl.training import BEST_POLICY, TrainConfig, train

torch.set_num_threads(1)  # small networks; the simulator needs the other core

SMALL = os.environ.get("TELEOPKIT_DOCS_BUDGET", "full") == "small"
EPISODE = 4.0 if SMALL else 20.0  # seconds
ENVS, ROUNDS = (8, 4) if SMALL else (16, 20)
SCENARIOS = 8 if SMALL else 32  # held-out evaluation scenarios
folder = Path(tempfile.mkdtemp(prefix="own_robot_"))

# %%
# Recorded data
# -------------
# A setup refers to data files by ``csv:PATH``, relative to the setup file. A recorded hand
# motion is a CSV with a time column ``t`` and one column per joint, ``q1..qn`` in radians. We
# make one here (sines standing in for a recording) and two delay traces, one per direction,
# with a column ``t`` and a column ``delay_ms``.
t = np.arange(0.0, 60.01, 0.01)
pd.DataFrame({"t": t, "q1": 0.5 * np.sin(0.8 * t) + 0.15 * np.sin(2.3 * t + 1.0),
              "q2": 0.35 * np.sin(1.3 * t + 0.4)}).to_csv(folder / "hand.csv", index=False)
pd.DataFrame({"t": t, "delay_ms": 320 + 250 * np.sin(0.5 * t)}).to_csv(folder / "to_remote.csv",
                                                                       index=False)
pd.DataFrame({"t": t, "delay_ms": 300 + 240 * np.cos(0.37 * t)}).to_csv(folder / "to_local.csv",
                                                                        index=False)

# %%
# The setup file
# --------------
# ``teleopkit setup`` prints the paper's setup file, to copy and edit; ``teleopkit setup FILE``
# checks a file and says what it describes. Only ``plant`` and its ``local_arm`` are required,
# with the arm's ``lengths`` and ``masses`` (``com`` and ``inertia`` are optional: point masses
# at the link tips by default); a ``remote_arm`` left out is a copy of the local arm, and every
# other key left out takes the paper's value (per joint of the arm). Each
# direction of the network has a range ``[min, max]``, which certificates must cover, and a
# profile (any delay spec, a CSV trace, or a list of them drawn per scenario); every profile is
# checked against its range. A mistake is reported in one line naming the key path, for example
# ``plant.remote_arm.masses[1]: must be positive, got -0.6``.
(folder / "my_robot.yaml").write_text("""\
plant:
  local_arm:   {lengths: [0.30, 0.25], masses: [0.8, 0.5]}
  remote_arm:  {lengths: [0.45, 0.35], masses: [1.2, 0.6], com: [0.22, 0.17],
                inertia: [0.02, 0.006]}
  joints:      {stiffness: [60, 60], rotor_inertia: [0.2, 0.2]}
  local_gains: {stiffness: [20, 20], damping: [9, 9]}
network:
  forward:  {min: 0.05, max: 0.6, profile: csv:to_remote.csv}
  backward: {min: 0.05, max: 0.6, profile: csv:to_local.csv}
operator: {stiffness: 10, damping: 2, motion: csv:hand.csv}
start: {local: {min: [-0.3, -0.3], max: [0.3, 0.3]}}
""")
setup = tk.Setup.from_file(folder / "my_robot.yaml")
print("\n".join(setup.describe()))

# %%
# Certify
# -------
# The closed form of Nuño et al. answers for the setup's plant and delay bounds at once. The
# same question on the command line is
# ``teleopkit certify --setup my_robot.yaml --kr 1:20 --br 20:100``, whose first line names the
# plant. Its margin depends on the local gains' ratio ``B_l / K_l`` (0.45 here, 0.4 for the
# paper's), and its verdict on the network's bounds: the box is certified for this setup's
# 0.6 s, not for the paper's plant behind its 1 s network. ``--method lmi`` answers from the
# linearisation of this plant, its inertia (centres of mass and link inertias included) too.
box = GainBox.uniform((1.0, 20.0), (20.0, 100.0))
ours = certify_gains(setup.params, box, *setup.network.bounds, method="nuno")
paper = certify_gains(tk.paper_setup(), box, 1.0, 1.0, method="nuno")
print(f"this setup:  certified {ours.certified}, delay margin {ours.delay_margin:.4f} s "
      f"(bounds {setup.network.bounds} s)")
print(f"the paper's: certified {paper.certified}, delay margin {paper.delay_margin:.4f} s "
      "(bounds (1, 1) s)")

# %%
# Simulate
# --------
# :func:`teleopkit.simulate` draws what the setup leaves random (here the start) from the seed
# and runs its network and its operator; ``teleopkit simulate --setup my_robot.yaml --kr 5
# --br 30 --seed 1 --out run.csv`` writes the same numbers.
run = tk.simulate((5.0, 30.0), duration=20.0, seed=1, setup=setup)
fig, axes = plt.subplots(3, 1, figsize=(7, 6.5), sharex=True)
axes[0].plot(run["t"], run["Tl"], label="T_l (to remote)")
axes[0].plot(run["t"], run["Tr"], label="T_r (to local)")
axes[0].set_ylabel("delay [s]")
axes[0].legend(loc="upper right")
for joint, ax in zip((1, 2), axes[1:], strict=True):
    ax.plot(run["t"], run[f"ql_{joint}"], label="local q_l")
    ax.plot(run["t"], run[f"qr_{joint}"], label="remote q_r")
    ax.set_ylabel(f"joint {joint} [rad]")
    ax.legend(loc="upper right")
axes[-1].set_xlabel("t [s]")
fig.suptitle("Your robot with the recorded hand motion and delay traces")
fig.tight_layout()

# %%
# Several plants
# --------------
# A tuner meets more than one robot: ``plant`` may be a list of plants, each scenario running
# one of them (here the robot, the robot carrying a load on its last link, and the robot
# against a wall its first joint meets at 0.1 rad). The closed form's set depends on the plant
# only through the local gains, so one certificate covers all three; it records each and is
# derived again for each when it is read back. An LMI certificate covers one plant only.
data = setup.to_data(folder)
loaded = {**data["plant"], "remote_arm": {**data["plant"]["remote_arm"], "masses": [1.2, 0.9]}}
walled = {**data["plant"], "environment": {"wall": [0.1, float("inf")], "stiffness": 1000}}
fleet = tk.Setup.from_data({**data, "plant": [data["plant"], loaded, walled]}, folder)
covering = default_certificate(fleet.params, fleet.network.reached_bounds, COVERING_CLASS,
                               fleet.plants)
covering.check(fleet.plants, *fleet.network.reached_bounds)
batch = fleet.scenarios(0, batch=6)
print(f"{len(covering.other_plants) + 1} plants under one certificate; the plant of each "
      f"scenario: {batch.plant_of.tolist()}")

# %%
# A value known only within bounds (a payload, a joint's stiffness) is a range,
# ``{min: [...], max: [...]}`` per joint, on the remote arm's and the joints' entries: every
# scenario draws its own plant inside it, and the certificate records the range and covers
# every plant of it (the closed form is derived again at both ends).
payload = {**data["plant"], "remote_arm": {**data["plant"]["remote_arm"],
                                           "masses": {"min": [0.6, 0.4], "max": [1.2, 0.9]}}}
uncertain = tk.Setup.from_data({**data, "plant": payload}, folder)
ranged = default_certificate(uncertain.params, uncertain.network.reached_bounds,
                             COVERING_CLASS, uncertain.plants, uncertain.ranges)
drawn = uncertain.scenarios(0, batch=4).plants
ranged.check(drawn, *uncertain.network.reached_bounds)
print("remote masses drawn for four scenarios:",
      [[round(m, 3) for m in plant.remote_arm.masses] for plant in drawn])

# %%
# Train
# -----
# The environments draw their episodes from the setup: its plant, its two delay traces, its
# operator motion and its random starts. The tuner trains under the recipe's covering class on
# the closed form's certificate for the delays the network reaches; the policy file records the
# certificate and the setup (``teleopkit train --setup my_robot.yaml``).
certificate = default_certificate(setup.params, setup.network.reached_bounds, COVERING_CLASS)
env_config = FlexTeleopConfig(setup, certificate, episode_length=EPISODE)
per_round = ENVS * env_config.max_steps
config = TrainConfig(total_steps=ROUNDS * per_round, num_envs=ENVS, seed=0,
                     episode_length=EPISODE, learning_starts=per_round,
                     buffer_size=ROUNDS * per_round, validation_scenarios=8)
result = train(config, folder / "run", env_config=env_config, progress=False)
policy = GainPolicy.load(folder / "run" / BEST_POLICY)
print(f"trained on setup {policy.metadata['setup']['network']['forward']['profile']} ...; "
      f"best validation cost {result.log['validation_cost'].min():.4g}")

# %%
# Evaluate
# --------
# :func:`~teleopkit.rl.comparison.compare` runs the tuner and its comparators on held-out
# scenarios of the setup. The comparators, the best constant gains of the frozen class on the
# certificate's box (``best static``, the reference) and of the tuner's class, the tuned
# semi-active law and the tuner's own schedule replayed open loop, are searched for this setup
# (and cached by its fingerprint), never reused from the paper's. On the command line:
# ``teleopkit evaluate --setup my_robot.yaml --policy run/best_policy.npz``.
table = compare([policy], SCENARIOS, certificate=certificate, duration=EPISODE, setup=setup,
                progress=False)
print(to_markdown(summarise(table), baseline=REFERENCE))
