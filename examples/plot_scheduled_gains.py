"""
Certify what a tuner does: scheduled gains
==========================================

A tuner changes the remote gains during a run, so a certificate for *constant* gains does not
cover it. The class ``scheduled:L`` does (:doc:`/theory/scheduled`): the stiffness has the shape
of the local gains and may rise freely, its falls spend a log budget ``L`` per episode, and the
damping may switch anywhere in the closed form's cone. Its storage ``V`` then satisfies
``V(t) <= exp(L) V(0)`` on the nonlinear teleoperator, for any delays up to the bound. This
tutorial certifies the class and watches the storage along adversarial runs inside and outside
it.
"""

# %%
import dataclasses
import math
import os

import matplotlib.pyplot as plt
import numpy as np

from teleopkit.certification.certifier import default_certificate
from teleopkit.certification.nuno.lyapunov import ScheduledStorage
from teleopkit.delays import SwitchingDelay
from teleopkit.model.params import Operator, paper_setup
from teleopkit.sim import Scenario, Simulator

SMALL = os.environ.get("TELEOPKIT_DOCS_BUDGET", "full") == "small"
BUDGET = 2.0

# %%
# The certificate
# ---------------
# The closed form's certificate of the default box ``K_r in [1, 50]``, ``B_r in [1, 150]`` for
# the class. It states the class, the bound and what the proof assumes.
certificate = default_certificate(variation=f"scheduled:{BUDGET:g}")
print(certificate.variation.describe())
for text in certificate.assumptions:
    print("assumes:", text)

# %%
# The storage along adversarial runs
# ----------------------------------
# The operator holds the origin (a passive operator), the torques do not saturate, and both
# delays jump between 0 and 1 s every 50-60 ms. Inside the class the stiffness ``kappa`` rises
# now and then and the damping switches at random in the cone; outside it, the stiffness
# switches arbitrarily between 1 and 50.
params = dataclasses.replace(paper_setup(), operator=Operator(amplitudes=(0.0, 0.0)),
                             torque_limit=math.inf)
storage = ScheduledStorage.for_plant(params, 1.0, 1.0)
rng = np.random.default_rng(0)
duration, batch = (8.0, 4) if SMALL else (20.0, 8)
periods = round(duration / 0.01)


def gains_for(kappa: np.ndarray) -> np.ndarray:
    """Common-shape stiffness ``kappa`` and damping random in the cone, per period and run."""
    stiffness = kappa[..., None] * np.array(storage.shape)
    damping = np.array(storage.cone) * stiffness * rng.uniform(1.0, 3.0, stiffness.shape)
    return np.concatenate([stiffness, damping], axis=-1)


def storage_ratio(kappa: np.ndarray) -> np.ndarray:
    """``V(t) / V(0)`` of adversarial runs under the gains of ``kappa``."""
    scenario = Scenario(params, SwitchingDelay(0.0, 1.0, 0.06, "extremes", 1, batch),
                        SwitchingDelay(0.0, 1.0, 0.05, "extremes", 2, batch),
                        np.ones((batch, params.n_joints)))
    value = storage.value(params, Simulator(scenario).run(duration, gains_for(kappa)))
    return value / value[0]


rises = rng.random((periods, batch)) < 0.01
inside = storage_ratio(np.maximum.accumulate(1.0 + 40.0 * rng.random((periods, batch)) * rises))
outside = storage_ratio(rng.uniform(1.0, 50.0, (periods, batch)))
t = np.arange(inside.shape[0]) * 0.01

fig, ax = plt.subplots(figsize=(7, 3.5), layout="constrained")
ax.semilogy(t, outside, color="tab:red", lw=0.8, alpha=0.7)
ax.semilogy(t, inside, color="tab:blue", lw=0.8)
ax.axhline(math.exp(BUDGET), color="k", ls="--", lw=1)
ax.text(t[-1], math.exp(BUDGET) * 1.15, f"bound exp(L) = {math.exp(BUDGET):.2f}", ha="right")
ax.plot([], [], color="tab:blue", label="inside the class (kappa never falls)")
ax.plot([], [], color="tab:red", label="stiffness switching at random (outside)")
ax.set(xlabel="time [s]", ylabel="V(t) / V(0)", title="The storage along adversarial runs")
ax.legend(loc="lower left")
print(f"largest V/V0 inside the class: {inside.max():.3f}; outside: {outside.max():.1f}")

# %%
# Inside the class the storage only falls (a rising ``kappa`` lowers it too); with the
# stiffness switching freely it rises far above its start, so there the storage proves nothing.
# What a tuner gains under this class, beside the others, is in
# :doc:`/auto_examples/plot_gain_classes`.
