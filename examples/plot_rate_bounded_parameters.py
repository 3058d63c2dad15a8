r"""
Parameters that switch, drift slowly, or stay constant
======================================================

A parameter of a delay system can be certified in three ways: constant, varying at a bounded
rate, or switching arbitrarily fast. The classes differ in what
the Lyapunov-Krasovskii functional may depend on, and a system can be stable in one class and
not in another. This tutorial takes the classic pair of oscillators

.. math::

    A(\theta) &= (1 - \theta) \begin{bmatrix} -0.5 & 1 \\ -10 & -0.5 \end{bmatrix}
               + \theta \begin{bmatrix} -0.5 & 10 \\ -1 & -0.5 \end{bmatrix}, \\
    x'(t) &= A(\theta(t))\, x(t) - 0.05\, e_2 e_2^\top x(t - \tau(t)),

with :math:`\theta \in [0, 1]`. Every constant :math:`\theta` is stable, but the two ellipses
the oscillators turn on are crossed: switching at the right moments pumps energy in.
"""

# %%
import math

import matplotlib.pyplot as plt
import numpy as np

import certify

A_LOW = np.array([[-0.5, 1.0], [-10.0, -0.5]])
A_HIGH = np.array([[-0.5, 10.0], [-1.0, -0.5]])
DELAYED = np.array([[0.0, 0.0], [0.0, -0.05]])


def family(rate: float) -> certify.PolytopicDelaySystem:
    """The oscillators with theta in [0, 1] and ``|theta'| <= rate``."""
    direction = certify.Direction(A_HIGH - A_LOW, [np.zeros((2, 2))])
    parameter = certify.AffineUncertainty([direction], [[0.0], [1.0]], ["theta"], [rate])
    return certify.PolytopicDelaySystem([certify.LinearDelaySystem(A_LOW, [DELAYED])],
                                        uncertainty=parameter)


# %%
# Certified delay margin against the rate bound
# ---------------------------------------------
# ``rates=[inf]`` (the default) asks for one functional for every :math:`\theta`: arbitrary
# switching. A finite rate lets the storage :math:`x^\top P(\theta) x` follow the parameter and
# pays for it with a bound on :math:`\dot P`; ``0`` is the constant case.

rates = [0.0, 0.003, 0.01, 0.03, 0.1, 0.3, math.inf]
margins = [certify.max_delay(family(rate), "rcc", rtol=1e-2) for rate in rates]
for rate, margin in zip(rates, margins, strict=True):
    print(f"rate {rate:>6g}: delay margin {margin:.3f} s")

fig, ax = plt.subplots(figsize=(6, 3.5))
finite = [r for r in rates if 0 < r < math.inf]
ax.semilogx(finite, [m for r, m in zip(rates, margins, strict=True) if 0 < r < math.inf], "o-",
            label="rate-bounded storage")
ax.axhline(margins[0], color="C2", ls="--", label="constant parameter")
ax.axhline(margins[-1], color="C3", ls=":", label="arbitrary switching")
ax.set_xlabel(r"rate bound $\rho$ on $|\dot\theta|$ (1/s)")
ax.set_ylabel("certified delay margin (s)")
ax.legend()
fig.tight_layout()

# %%
# Why switching is not certified: it really diverges
# --------------------------------------------------
# A certificate that fails is not a proof of instability, but here the failure is real. Switch
# :math:`\theta` to whichever oscillator makes :math:`|x|` grow fastest (the ``0.05`` delayed
# term is small against this), and compare with a slow sinusoid of rate 0.03/s, which is
# certified up to the delay below. A fixed-step Euler integration with a delay buffer is plenty
# for a picture.

DT, TAU, DURATION = 1e-3, 0.5, 30.0


def simulate(choose) -> np.ndarray:
    """Norm of ``x(t)`` with ``theta(t, x) = choose(t, x)``, from ``x = (1, 0)``."""
    steps, lag = int(DURATION / DT), int(TAU / DT)
    x = np.zeros((steps + 1, 2))
    x[0] = (1.0, 0.0)
    for k in range(steps):
        theta = choose(k * DT, x[k])
        a = (1 - theta) * A_LOW + theta * A_HIGH
        delayed = x[max(k - lag, 0)]
        x[k + 1] = x[k] + DT * (a @ x[k] + DELAYED @ delayed)
    return np.linalg.norm(x, axis=1)


def adversary(_t: float, x: np.ndarray) -> float:
    """The oscillator whose flow increases ``|x|^2`` more at this state."""
    return float(x @ A_HIGH @ x > x @ A_LOW @ x)


def slow(t: float, _x: np.ndarray) -> float:
    """A sinusoid through [0, 1] with largest rate 0.03/s."""
    return 0.5 + 0.5 * math.sin(0.06 * t)


print(f"certified with |theta'| <= 0.03 up to {margins[rates.index(0.03)]:.2f} s; "
      f"simulated delay {TAU} s")
times = np.linspace(0.0, DURATION, int(DURATION / DT) + 1)
fig, ax = plt.subplots(figsize=(6, 3.5))
ax.semilogy(times, simulate(adversary), label="state-dependent switching")
ax.semilogy(times, simulate(slow), label=r"slow drift, $|\dot\theta| \leq 0.03$")
ax.set_xlabel("time (s)")
ax.set_ylabel(r"$|x(t)|$")
ax.legend()
fig.tight_layout()
plt.show()

# %%
# The teleoperator's gains are held over each control period, so even a rate-limited gain jumps:
# ``teleopkit certify --gain-variation rate:R`` therefore certifies them as switching (see
# :doc:`/theory/certification`).
