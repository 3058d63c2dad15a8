"""
The certified gain classes side by side
=======================================

A certificate covers a *gain class*: what the remote gains may do over a run
(:doc:`/certified`). The closed form certifies constant gains; a tuner changes them every
control period, so it needs a class that allows change. This tutorial takes the default gain box
for 1 s delays under three classes, shows what each lets the gains do, and measures what the
shipped tuners gain under each.
"""

# %%
import os

import matplotlib.pyplot as plt
import numpy as np

from teleopkit.certification.certifier import default_certificate
from teleopkit.rl.baselines import fixed_gains
from teleopkit.rl.controllers import ConstantGains
from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.rl.evaluation import EVAL_SEED, evaluate, rollout, summarise
from teleopkit.rl.policy import PRETRAINED_SCHEDULED, GainPolicy

SMALL = os.environ.get("TELEOPKIT_DOCS_BUDGET", "full") == "small"
SCENARIOS = 4 if SMALL else 32

# %%
# Three certificates of one box
# -----------------------------
# The same box, ``K_r in [1, 50]``, ``B_r in [1, 150]`` on both joints, and the same per-joint
# cone ``B_r >= rho K_r`` of the closed form; the classes differ in what may change.
certificates = {name: default_certificate(variation=name)
                for name in ("frozen", "scheduled:2", "tank")}
for name, certificate in certificates.items():
    print(f"{name:12s} {certificate.variation.describe()}")

# %%
# What the tuners do with the gains
# ---------------------------------
# The paper's tuner, trained under the frozen-gain certificate, and the tuner trained under
# ``scheduled:2``, on one held-out scenario: the stiffness of joint 1 over the run. The first
# switches its stiffness up and down every few steps, which no constant-gain certificate
# covers; the second keeps the common shape and spends its falls from the budget.
frozen_tuner = GainPolicy.pretrained()
scheduled_tuner = GainPolicy.pretrained(PRETRAINED_SCHEDULED)
scheduled = FlexTeleopConfig(certificate=certificates["scheduled:2"])
runs = {"TD3 under frozen (not covered)": rollout(frozen_tuner, 1, EVAL_SEED).to_frame(),
        "TD3 under scheduled:2 (covered)": rollout(scheduled_tuner, 1, EVAL_SEED,
                                                   scheduled).to_frame()}
fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True, layout="constrained")
for ax, (name, run) in zip(axes, runs.items(), strict=True):
    ax.plot(run["t"], run["Kr_1"], lw=1, label="K_r joint 1")
    ax.plot(run["t"], run["Kr_2"], "--", lw=1, label="K_r joint 2")
    ax.set(ylabel="K_r [N m/rad]", title=name)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
axes[-1].set_xlabel("time [s]")
plt.show()

# %%
# What each class is worth
# ------------------------
# The paper's cost on held-out scenarios: fixed gains, the best constant gains of the frozen
# class, the paper's tuner (outside its certificate), and the tuner and best constant gains of
# the scheduled class. Hatched bars ran outside what their certificate covers.
controllers = {"fixed": ConstantGains(fixed_gains()),
               "best static (frozen)": ConstantGains(
                   np.asarray(frozen_tuner.metadata["best_static_gains"])),
               "TD3 (frozen)": frozen_tuner,
               "best static (scheduled:2)": ConstantGains(
                   np.asarray(scheduled_tuner.metadata["best_static_gains"])),
               "TD3 (scheduled:2)": scheduled_tuner}
summary = summarise(evaluate(controllers, SCENARIOS, configs={
    name: scheduled for name in controllers if "scheduled" in name}))
summary = summary.loc[list(controllers)]
fig, ax = plt.subplots(figsize=(8, 3.5), layout="constrained")
bars = ax.barh(summary.index, summary["cost"], color="tab:blue")
for bar, covered in zip(bars, summary["covered"], strict=True):
    if not covered:
        bar.set(hatch="//", facecolor="white", edgecolor="tab:red")
ax.invert_yaxis()
ax.set(xlabel="cost (lower is better)", title=f"{SCENARIOS} held-out scenarios")
plt.show()
summary[["certificate", "covered", "cost", "rms_track", "rms_damp"]].round(4)

# %%
# The paper's tuner is cheaper than the best constant gains only outside its certificate. Under
# the covering ``scheduled:2`` certificate the tuner and the best constant gains of that class
# cost about the same (on 32 scenarios, 9470 against 9468): the proof costs the tuner its
# advantage on this task. The ``tank`` class trades the fixed budget for one refilled by the
# dissipation the storage proves; it needs the remote arm's energy measured at every step.
