"""
Train a safe TD3 tuner and evaluate it against static gains
===========================================================

:func:`teleopkit.rl.training.train` trains a TD3 agent that retunes the remote gains
``[K_r^1, K_r^2, B_r^1, B_r^2]`` every control period (10 ms). Every action it takes, exploration
noise included, passes through the safety layer of the environment's certificate before it
reaches the simulator, so training never applies a gain outside the certified set. This tutorial
trains a tuner, reads its log, finds the best *constant* certified gains with
:func:`teleopkit.rl.baselines.best_static_gains`, and compares the trained policy, the shipped
pretrained policy, the paper's fixed gains and the best static gains on held-out scenarios with
:func:`teleopkit.rl.evaluation.evaluate`: the same comparison as ``teleopkit evaluate`` and
``teleopkit reproduce``.
"""

# %%
# Budget
# ------
# ``TELEOPKIT_DOCS_BUDGET=small`` (the documentation build) trains 8 rounds of 8 scenarios on
# 2 s episodes and evaluates on 16 held-out 2 s scenarios: well under a minute on one core, and
# far too little training for a good policy. ``full`` trains 5 rounds of 16 scenarios on the
# paper's 40 s episodes (a few minutes) and evaluates on 32 held-out 40 s scenarios, as
# ``teleopkit reproduce`` does.
import os
import shutil
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import torch

from teleopkit.certification.certifier import default_certificate
from teleopkit.rl.baselines import best_static_gains, fixed_gains
from teleopkit.rl.controllers import ConstantGains
from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.rl.evaluation import (
    EVAL_SEED,
    evaluate,
    rollout,
    summarise,
)
from teleopkit.rl.policy import GainPolicy
from teleopkit.rl.td3 import TD3Config
from teleopkit.rl.training import BEST_POLICY, TrainConfig, train

torch.set_num_threads(1)  # small networks; the simulator needs the other core

BUDGET = os.environ.get("TELEOPKIT_DOCS_BUDGET", "full")
SMALL = BUDGET == "small"
EPISODE = 2.0 if SMALL else 40.0  # seconds, for training and evaluation alike
ENVS = 8 if SMALL else 16  # scenarios simulated together during training
ROUNDS = 8 if SMALL else 5  # one round = one episode of every scenario
BATCH = 128 if SMALL else 512  # minibatch of each gradient update
VALIDATION = 8 if SMALL else 16  # validation scenarios, scored after every round
SCENARIOS = 16 if SMALL else 32  # held-out evaluation scenarios
# best static gains: (training scenarios, grid points per gain, Nelder-Mead evaluations)
STATIC = (8, 4, 30) if SMALL else (16, 8, 200)

# %%
# The training configuration
# --------------------------
# :class:`teleopkit.rl.recipes.TrainConfig` holds every setting of a run. Training proceeds in
# *rounds*, one episode of each of the ``num_envs`` scenarios simulated together, and
# ``total_steps`` (transitions over all scenarios) is rounded up to whole rounds. The first
# ``learning_starts`` transitions use uniform random gains (projected like every other action)
# and fill the replay buffer; the networks' input standardisation is fixed from them. The agent
# settings, :class:`teleopkit.rl.td3.TD3Config`, are the paper's except for the learning rates
# and the discount (the defaults of ``TrainConfig``; the docstring says why), here with a smaller
# minibatch on the small budget. These are the paper's recipe, ``teleopkit train``'s default;
# :data:`teleopkit.rl.recipes.RECIPES` also holds a fast one that trains on 10 s episodes and
# validates on 40 s ones (``--recipe fast``; ``replace(RECIPES["fast"], ...)`` in Python).
env_config = FlexTeleopConfig(episode_length=EPISODE)
per_round = ENVS * env_config.max_steps
config = TrainConfig(
    total_steps=ROUNDS * per_round,
    num_envs=ENVS,
    seed=0,
    episode_length=EPISODE,
    learning_starts=per_round,  # the first round explores with random gains
    buffer_size=ROUNDS * per_round,  # keeps every transition of this short run
    validation_scenarios=VALIDATION,
    td3=TD3Config(discount=0.95, actor_lr=1e-3, critic_lr=1e-3, batch_size=BATCH),
)
print(f"{config.total_steps} transitions in {ROUNDS} rounds of {per_round}")

# %%
# Training
# --------
# With an output directory, :func:`teleopkit.rl.training.train` writes a checkpoint, the log, the
# last and the best policy and the configuration, each atomically, after every round
# (``checkpoint_every``). ``train(config, out_dir, resume=True)`` (``teleopkit train --resume``)
# continues an interrupted run exactly where its last checkpoint left it, and a run can be
# extended by resuming with a larger ``total_steps``. ``progress=True`` (the default) shows a
# progress bar.
out_dir = Path(tempfile.mkdtemp(prefix="teleopkit_train_"))
result = train(config, out_dir, progress=False)
print(sorted(path.name for path in out_dir.iterdir()))

# %%
# The log has one row per round (the columns of ``train_log.csv``): the mean return of the
# *exploring* policy over the round's scenarios, the mean losses, the exploration noise, the cost
# of the deterministic policy on the fixed validation scenarios, the cumulative wall time, and
# the cumulative number of applied actions outside the certified set.
log = result.log
log.set_index("round")

# %%
# The return of the exploring policy and the validation cost of the deterministic one. Both are
# noisy over a few rounds: each round draws new scenarios, and the policy's held-out cost
# fluctuates from one round to the next, which is why the actor of the round with the lowest
# validation cost is kept as ``result.best_policy`` (``best_policy.npz``).
fig, axes = plt.subplots(1, 2, figsize=(8, 3), layout="constrained")
axes[0].plot(log["round"], log["episode_return"], "o-")
axes[0].set_xlabel("round")
axes[0].set_ylabel("mean episode return\n(exploring policy)")
axes[1].plot(log["round"], log["validation_cost"], "o-", color="C1")
best_round = int(log.loc[log["validation_cost"].idxmin(), "round"])
axes[1].axvline(best_round, color="0.5", ls="--", label=f"best: round {best_round}")
axes[1].set_xlabel("round")
axes[1].set_ylabel("validation cost\n(deterministic policy)")
axes[1].legend(fontsize="small")

# %%
# The best policy as a file: what ``teleopkit evaluate --policy`` reads. Its metadata records the
# training settings, the round it comes from and its validation cost.
trained = GainPolicy.load(out_dir / BEST_POLICY)
print({key: trained.metadata[key] for key in ("rounds", "validation_cost")})

# %%
# The best static certified gains
# -------------------------------
# An honest baseline for a tuner is not only the paper's fixed gains ``K_r = 10, B_r = 30`` but
# the best *constant* gains that the same safety layer allows.
# :func:`teleopkit.rl.baselines.best_static_gains` searches them on training scenarios (seed
# :data:`teleopkit.rl.baselines.BASELINE_SEED`, apart from the evaluation seed): a grid of uniform
# gains projected onto the certified set, then Nelder-Mead over all four gains, every candidate
# projected. The cost is the paper's: minus the episode return.
static_scenarios, grid_points, evaluations = STATIC
static = best_static_gains(scenarios=static_scenarios, grid_points=grid_points,
                           max_evaluations=evaluations, config=env_config)
print("best static gains [K_r1, K_r2, B_r1, B_r2]:", static.gains.round(3))
print(f"mean training cost {static.cost:.5g} ({static.evaluations} candidates simulated)")

# %%
# The pretrained policy
# ---------------------
# The package ships a policy trained with a much larger budget by ``examples/train_pretrained.py``
# (:meth:`teleopkit.rl.td3.GainPolicy.pretrained`); it is the one ``teleopkit reproduce`` uses.
# Its metadata records its training settings and the best static gains that ``reproduce``
# compares it with (found with the default search on 40 s episodes).
pretrained = GainPolicy.pretrained()
recipe = pretrained.metadata["train_config"]
print(f"trained on {recipe['total_steps']} transitions of {recipe['num_envs']} x "
      f"{recipe['episode_length']:g} s episodes; best validation at round "
      f"{pretrained.metadata['rounds']}")
print("its stored best static gains:", np.round(pretrained.metadata["best_static_gains"], 3))

# %%
# Held-out evaluation
# -------------------
# :func:`teleopkit.rl.evaluation.evaluate` runs every controller in closed loop through the same
# batched environment (so through the same safety layer) on the same held-out scenarios, drawn
# from :data:`teleopkit.rl.evaluation.EVAL_SEED`, which neither training nor the static search saw.
# :class:`teleopkit.rl.controllers.ConstantGains` turns a gain vector into a controller.
controllers = {
    "TD3 (this run)": trained,
    "TD3 (pretrained)": pretrained,
    "fixed": ConstantGains(fixed_gains()),
    "best static": ConstantGains(static.gains),
}
per_scenario = evaluate(controllers, SCENARIOS, EVAL_SEED, env_config)
summary = summarise(per_scenario)
relative = summary["cost"] / summary.loc["best static", "cost"] - 1.0
summary.assign(**{"cost vs best static": relative.map("{:+.1%}".format)})[
    ["cost", "rms_track", "rms_damp", "cost vs best static"]].round(4)

# %%
# The table has the mean over the scenarios; the last column compares mean costs with the best
# static gains (``teleopkit.rl.evaluation.to_markdown`` writes it with standard deviations). Read
# it with the budget in mind. On the small budget the policy trained above has had a few rounds of
# learning on 2 s episodes, the opening transient only: it is a weak policy, and nothing says it
# beats even the fixed gains. The pretrained policy was trained on 40 s episodes; on 2 s
# evaluation episodes it is scored on the transient alone. Only the full budget reproduces the
# pretrained, fixed and best static rows of ``teleopkit reproduce`` (same scenarios, same episode
# length, same search for the static gains).
#
# Safety: every applied action of training (exploration included), validation and evaluation was
# inside the certified set.
unsafe_training = int(log["unsafe_actions"].iloc[-1])
unsafe_evaluation = int(summary["unsafe_actions"].sum())
print(f"unsafe actions: training {unsafe_training}, evaluation {unsafe_evaluation}")
assert unsafe_training == 0 and unsafe_evaluation == 0

# %%
# Cost per scenario
# -----------------
# All controllers ran on the same scenarios, so costs compare scenario by scenario: here each
# cost divided by that of the best static gains on the same scenario (below 1: better).
costs = per_scenario.pivot(index="scenario", columns="controller", values="cost")
ratio = costs[list(controllers)].div(costs["best static"], axis=0)
fig, ax = plt.subplots(figsize=(7, 3.5), layout="constrained")
ax.boxplot([ratio[name] for name in controllers], showfliers=False)
for k, name in enumerate(controllers, start=1):
    jitter = np.linspace(-0.12, 0.12, len(ratio))
    ax.plot(k + jitter, ratio[name], ".", color=f"C{k - 1}", alpha=0.7)
ax.set_xticks(range(1, len(controllers) + 1), list(controllers))
ax.axhline(1.0, color="0.5", lw=0.8, ls="--")
ax.set_ylabel("cost / cost of best static gains")
ax.set_title(f"{SCENARIOS} held-out scenarios, {EPISODE:g} s episodes")

# %%
# What the certificate covers
# ---------------------------
# A tuner changes the gains every 10 ms. :func:`teleopkit.rl.evaluation.rollout` records the applied
# gains of a run; here joint 1 of the first held-out scenario under both policies, with the
# best static gains for reference. Every applied gain lies in the certified set, but the
# environment's default certificate (:func:`teleopkit.rl.env.default_certificate`, the closed form)
# is for *frozen* gains: it guarantees stability for every constant gain in the set, not for gains
# that vary in time within it. A tuner is covered by a ``switching`` LMI certificate (any change
# inside the set; ``rate:R`` is certified the same way, the safety layer then also limits the
# rate), or by the scheduled classes ``scheduled:L`` and ``tank`` of the closed form, passed to
# the environment as ``FlexTeleopConfig(certificate=...)`` (:doc:`/certified`).
print("gain variation covered by the default certificate:",
      default_certificate().gain_variation)
runs = {name: rollout(controllers[name], 1, EVAL_SEED, env_config).to_frame()
        for name in ("TD3 (this run)", "TD3 (pretrained)")}
fig, axes = plt.subplots(2, 1, figsize=(8, 4.5), sharex=True, layout="constrained")
for k, (name, frame) in enumerate(runs.items()):
    axes[0].plot(frame["t"], frame["Kr_1"], color=f"C{k}", label=name)
    axes[1].plot(frame["t"], frame["Br_1"], color=f"C{k}", label=name)
axes[0].axhline(static.gains[0], color="C3", ls="--", label="best static")
axes[1].axhline(static.gains[2], color="C3", ls="--", label="best static")
axes[0].set_ylabel(r"$K_{r,1}$")
axes[1].set_ylabel(r"$B_{r,1}$")
axes[1].set_xlabel("time [s]")
fig.legend(*axes[0].get_legend_handles_labels(), loc="outside upper center", ncol=3,
           fontsize="small")
plt.show()
shutil.rmtree(out_dir)  # the run's files are no longer needed
