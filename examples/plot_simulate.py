"""
Simulate the paper's teleoperator
=================================

Run the delayed bilateral teleoperator of the paper (a rigid local arm, an elastic-joint remote
arm, P+d controllers on both sides, the paper's time-varying delays of up to 1 s) with constant
remote gains ``K_r = 10``, ``B_r = 30``, read the run as a table and plot it.
"""

# %%
# Budget
# ------
# ``TELEOPKIT_DOCS_BUDGET=small`` (the documentation build) simulates 10 s and 16 randomised
# scenarios; ``full`` simulates the paper's 40 s episode and 256 scenarios.
import os
from dataclasses import replace

import matplotlib.pyplot as plt
import numpy as np

import teleopkit as tk
from teleopkit.plots import plot_run

BUDGET = os.environ.get("TELEOPKIT_DOCS_BUDGET", "full")
SMALL = BUDGET == "small"
DURATION = 10.0 if SMALL else 40.0
BATCH = 16 if SMALL else 256

# %%
# One run as a table
# ------------------
# :func:`teleopkit.simulate` builds the paper's setup (:func:`teleopkit.paper_setup`), draws the
# operator's reference gains and the two delay scales from ``seed``, integrates at a fixed 2.5 ms
# step with a fifth-order Runge–Kutta method and holds the remote gains over each 10 ms control
# period. The result has one row per control period.
table = tk.simulate(gains=(10.0, 30.0), duration=DURATION, delay="paper", seed=0)
print(table.shape)
table[["t", "ql_1", "theta_1", "Tl", "Tr", "e_track_1", "e_damp_1"]].iloc[::200]

# %%
# The same figure as ``teleopkit simulate --plot``: the two delays, the remote motor angle
# against the delayed local position, and the tracking and damping errors per joint.
fig = plot_run(table, title="K_r = 10, B_r = 30, paper delays")

# %%
# Parameters are frozen dataclasses
# ---------------------------------
# Every number of the model lives in :class:`teleopkit.TeleoperatorParams`; change one with
# :func:`dataclasses.replace` and pass the result as ``params``. Here the remote joints are made
# twice as stiff.
params = tk.paper_setup()
print(params.joints)
stiff = replace(params, joints=tk.ElasticJoints(stiffness=(200.0, 200.0)))
stiff_table = tk.simulate(gains=(10.0, 30.0), duration=DURATION, delay="paper", seed=0,
                          params=stiff)

fig, ax = plt.subplots(figsize=(8, 3), layout="constrained")
ax.plot(table["t"], table["e_damp_1"], label=r"$S_r = 100$")
ax.plot(stiff_table["t"], stiff_table["e_damp_1"], label=r"$S_r = 200$")
ax.set_xlabel("time [s]")
ax.set_ylabel(r"$\theta_{r,1} - q_{r,1}$ [rad]")
ax.set_title("Damping (flexibility) error of joint 1")
ax.legend()

# %%
# Many scenarios at once
# ----------------------
# :class:`teleopkit.Simulator` integrates a batch of scenarios in one compiled loop.
# :func:`teleopkit.paper_scenarios` draws the paper's randomisation: operator reference gains in
# ``[-1, -0.5] U [0.5, 1]`` and delay scales in ``U[0.5, 1]`` per channel and scenario.
sim = tk.Simulator(tk.paper_scenarios(0, batch=BATCH))
trajectory = sim.run(DURATION, gains=np.array([10.0, 10.0, 30.0, 30.0]))
metrics = trajectory.metrics()
metrics.describe().loc[["mean", "std", "max"], ["rms_track", "iae_track", "rms_damp"]]

# %%
# The RMS tracking error over the batch:
fig, ax = plt.subplots(figsize=(6, 3), layout="constrained")
ax.hist(metrics["rms_track"], bins=12)
ax.set_xlabel("RMS tracking error [rad]")
ax.set_ylabel("scenarios")
plt.show()
