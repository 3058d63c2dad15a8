"""
Falsify a certificate: the worst delays and gains an adversary finds
====================================================================

A certificate is a proof; a falsification search is the experiment that tries to break it. The
adversary of :func:`teleopkit.robustness.search.search` picks the delays (a square wave per
channel, anywhere up to the bounds), the remote gains (anywhere in the certified set) and the
operator's reference, and CMA-ES maximises how much the motion grows. Finding nothing proves
nothing; a divergence *inside* what a certificate covers would contradict it.

This tutorial searches twice on the paper's teleoperator under the closed-form certificate of
the default gain box for 1 s delays: once with constant gains, the class the certificate covers,
and once with the gains switching, which it does not cover.
"""

# %%
import os

import matplotlib.pyplot as plt

from teleopkit.certification.certifier import default_certificate
from teleopkit.model.params import paper_setup
from teleopkit.robustness.adversary import SearchSpace
from teleopkit.robustness.search import search

SMALL = os.environ.get("TELEOPKIT_DOCS_BUDGET", "full") == "small"
BUDGET, DURATION = (48, 8.0) if SMALL else (512, 20.0)

params = paper_setup()
certificate = default_certificate(params)
print(certificate.variation.describe())

# %%
# Two searches
# ------------
# The same budget of runs (simulated a population at a time, as one batch) for each: frozen
# gains (one point of the set per run) and gains switching between 8 points per run.
results = {}
for name, switching in (("frozen gains (covered)", False), ("switching gains (not covered)", True)):
    space = SearchSpace(params, certificate, switching=switching, duration=DURATION)
    results[name] = search(space, "energy_growth", budget=BUDGET, population=16, seed=0)
    found = results[name]
    print(f"{name}: worst energy growth {found.value:+.2f} (log ratio), diverged: "
          f"{found.diverged}, covered by the certificate: {found.covered}")

# %%
# What the adversary learned
# --------------------------
# The best objective of each generation, and the worst run found by each search: the tracking
# error of joint 1 along it (the delays the adversary chose are in its trajectory too).
fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.5), layout="constrained")
for (name, found), style in zip(results.items(), ("-", "--"), strict=True):
    best = found.history.groupby("generation")["objective"].max().cummax()
    left.plot(best.index, best.to_numpy(), ls=style, marker="o", label=name)
    run = found.trajectory
    right.plot(run["t"], run["e_track_1"], ls=style, lw=1, label=name)
left.axhline(0.0, color="k", lw=0.8)
left.set(xlabel="generation", ylabel="best energy growth so far",
         title="The search")
right.set(xlabel="time [s]", ylabel="tracking error joint 1 [rad]",
          title="The worst run found")
left.legend(loc="lower right", fontsize="small")
plt.show()

# %%
# The objective is the log ratio of the peak energy in the last quarter of a run to that in the
# second quarter: above zero the motion grew, which on a short run can still be the transient of
# the operator's reference; ``diverged`` applies the simulator's divergence criterion (the
# positions leaving a radius). A divergence with ``covered=True`` would contradict the
# certificate and must be reported; with ``covered=False`` it would refute only the use of the
# set outside its class. With a larger budget (``TELEOPKIT_DOCS_BUDGET=full``: 512 runs of 20 s)
# the searches go further, and
# the same call with ``objective="storage"`` checks a scheduled certificate's storage bound
# along the runs (:doc:`/auto_examples/plot_scheduled_gains`). From the command line:
# ``teleopkit falsify --kr 1:50 --br 1:150 --budget 256``.
