"""cvxpy/Clarabel solution of an LMI method, re-solvable for new delay bounds (DPP)."""

from __future__ import annotations

import math
import warnings
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import cvxpy as cp
import numpy as np
from numpy.typing import NDArray

from certify.certificate import Certificate
from certify.channels import Channels
from certify.check import RTOL, residuals
from certify.conditions import LMIMethod, check_mu, delay_class_text, lower_bounds
from certify.form_store import load_form, save_form
from certify.system import PolytopicDelaySystem
from certify.system_data import SystemData, system_data

__all__ = ["RETRIES", "SHARED_FORMS", "LMIProblem", "check_threads"]

SOLVER = "CLARABEL"
SOLVER_OPTIONS: dict[str, Any] = {"iterative_refinement_enable": False}
"""Clarabel settings of every solve. Iterative refinement of the KKT solves is off: on the
paper's two-joint teleoperator it made each solve some 1.7 times slower (the 115 solves of
``certify --kr 1:50 --br 1:150`` took 160 s with it and 96 s without, one process) for the same
iterations; a solution is certified only by the numpy re-check of every LMI
(:func:`certify.check.residuals`), whatever the solver's accuracy."""
MARGIN_CAP = 1e-4
"""Margin ``t`` beyond which the solver stops improving. A clearly feasible problem then has a
large optimal face, whose analytic centre interior-point methods reach in few iterations;
without the cap the Finsler slack drifts along an unbounded optimal face and the solver may
end ``optimal_inaccurate`` although the LMIs are comfortably feasible."""


def check_threads(threads: int) -> int:
    """``threads`` as a thread cap of Clarabel's linear algebra (0: Clarabel's default).

    Parameters
    ----------
    threads : int
        Most threads per solve; solves that run side by side should share the cores.

    Returns
    -------
    int
        The cap.

    Raises
    ------
    ValueError
        If ``threads`` is negative.
    """
    if int(threads) != threads or threads < 0:
        raise ValueError(f"threads must be 0 (automatic) or positive, got {threads}")
    return int(threads)


def _system_text(system: PolytopicDelaySystem) -> str:
    k = len(system.vertices)
    if k == 1:
        text = "system: linear, E x' = A0 x + sum_i A_i x(t - tau_i)"
    elif system.frozen:
        text = (f"system: every fixed (time-invariant) convex combination of {k} vertices "
                "(parameter-dependent functional, common slack)")
    else:
        text = (f"system: any convex combination of {k} vertices, possibly varying arbitrarily "
                "fast (common functional and slack at all vertices)")
    if system.uncertainty is None:
        return text
    unc = system.uncertainty
    assert unc.rates is not None
    speeds = ", ".join(f"{name} {_speed(rate)}" for name, rate in zip(unc.names, unc.rates,
                                                                      strict=True))
    return (f"{text}; plus {unc.p} affine parameters anywhere in the hull of {len(unc.points)} "
            f"points ({speeds}; full-block S-procedure multipliers, Scherer 2001, with a "
            "storage depending on every rate-bounded parameter)")


def _speed(rate: float) -> str:
    if math.isinf(rate):
        return "varying arbitrarily fast"
    return "constant" if rate == 0 else f"with |rate| <= {rate:g}"


class _Form:
    """The cvxpy problem of one method for every system of one structure (cvxpy's DPP).

    The delay bounds are parameters, and so are the system's numbers
    (:class:`~certify.system_data.SystemData`) of a ``shared`` form: it solves any system of
    the same structure and channels without building or compiling the problem again. (A
    storage that depends on rate-bounded parameters puts the points into products the
    parameters cannot enter; such a form holds its system's numbers as constants.)
    """

    def __init__(self, system: PolytopicDelaySystem, method: LMIMethod, mu: float | None,
                 channels: Channels, data: SystemData, shared: bool = True) -> None:
        self.method, self.mu, self.channels, self.shared = method, mu, channels, shared
        self.structure = data.structure()
        self.data = data.parameters() if shared else data
        self.vars = {
            s.name: cp.Variable(s.shape, symmetric=s.symmetric, name=s.name)
            for s in method.variables(channels, mu, system, data)
        }
        self.h = [cp.Parameter(nonneg=True, name=f"h{i}") for i in range(system.m)]
        self.h2 = [cp.Parameter(nonneg=True, name=f"h{i}_sq") for i in range(system.m)]
        conds = method.conditions(system, channels, self.vars, self.h, self.h2, mu, self.data)
        self.t = cp.Variable(name="t")
        constraints = [c.matrix >> self.t * np.eye(c.matrix.shape[0]) for c in conds]
        scale = cp.hstack([cp.trace(c.matrix) for c in conds if c.normalise])
        constraints += [cp.sum(scale) <= 1, self.t <= MARGIN_CAP]
        self.problem = cp.Problem(cp.Maximize(self.t), constraints)

    def compile(self) -> None:
        """Compile the problem for the solver now (cvxpy's DPP), rather than at the first solve."""
        self.problem.get_problem_data(SOLVER)

    def data_for(self, system: PolytopicDelaySystem) -> SystemData | None:
        """The numbers of ``system`` in this form, or ``None`` if the form cannot solve it."""
        if not self.channels.valid_for(system):
            return None
        data = system_data(self.method, system, self.channels, self.mu)
        return data if data.structure() == self.structure else None

    def solve(self, system: PolytopicDelaySystem, data: SystemData, bounds: tuple[float, ...],
              threads: int = 0) -> tuple[str, dict[str, np.ndarray], dict[str, float]]:
        """Status, decision matrices and numpy residuals (empty unless optimal with ``t > 0``)."""
        if self.shared:
            self.data.assign(data)
        for param, param_sq, value in zip(self.h, self.h2, bounds, strict=True):
            param.value = value
            param_sq.value = value * value
        try:
            with warnings.catch_warnings():  # an inaccurate status is reported, not warned
                warnings.simplefilter("ignore", UserWarning)
                # a fresh solver: updating the last one's data keeps its equilibration, which
                # is wrong for another system (a badly scaled one then spoils the next)
                self.problem.solve(solver=SOLVER, warm_start=False, **SOLVER_OPTIONS,
                                   **({"max_threads": threads} if threads else {}))
            status = str(self.problem.status)
        except cp.SolverError as exc:
            status = f"solver_error: {exc}"
        if status != cp.OPTIMAL or self.t.value is None or float(self.t.value) <= 0.0:
            return status, {}, {}
        matrices = {k: _value(v) for k, v in self.vars.items()}
        return status, matrices, residuals(self.method, system, self.channels, matrices,
                                           bounds, self.mu, data)


RETRIES = ("always", "accurate")
"""Values of :class:`LMIProblem`'s ``retry``."""

SHARED_FORMS = 16
"""Most problems a process keeps for systems of a structure it has solved before (the cells of
a cover share one per number of points and coordinates): building and compiling one takes
about a fifth of a two-joint cell's solve."""

_SHARED: OrderedDict[tuple[Any, ...], list[_Form]] = OrderedDict()


def _family(system: PolytopicDelaySystem, method: LMIMethod, mu: float | None,
            channels: Channels, scaling: NDArray[np.float64]) -> tuple[Any, ...]:
    """What systems must share before their forms are compared (structure, coordinates)."""
    unc = system.uncertainty
    spread = () if unc is None else (unc.p, len(unc.points), unc.scheduled)
    return (type(method).__name__, method.name, method.lower, mu, channels.r,
            channels.reduced, system.n, system.m, len(system.vertices), system.frozen, spread,
            scaling.tobytes())


def _shared_form(system: PolytopicDelaySystem, method: LMIMethod, mu: float | None,
                 channels: Channels, scaling: NDArray[np.float64]) -> tuple[_Form, SystemData]:
    """A kept form that solves ``system``, and its data.

    If none is kept, one is read from the directory of :func:`certify.form_store.share_forms`
    (compiled by another process) or else built, compiled and saved there.
    """
    key = _family(system, method, mu, channels, scaling)
    forms = _SHARED.setdefault(key, [])
    _SHARED.move_to_end(key)
    for form in forms:
        data = form.data_for(system)
        if data is not None:
            return form, data
    data = system_data(method, system, channels, mu)
    stored = (*key, data.structure())
    loaded = load_form(stored)
    shared = loaded.data_for(system) if isinstance(loaded, _Form) else None
    if isinstance(loaded, _Form) and shared is not None:
        form, data = loaded, shared  # its numbers in its own channels, which may differ
    else:
        form = _Form(system, method, mu, channels, data)
        form.compile()
        save_form(stored, form)
    forms.append(form)
    while sum(len(f) for f in _SHARED.values()) > SHARED_FORMS:
        oldest = next(iter(_SHARED))
        _SHARED[oldest].pop(0)
        if not _SHARED[oldest]:
            del _SHARED[oldest]
    return form, data


@dataclass(frozen=True)
class _Posed:
    """A form with the system it is solved for, in the form's coordinates."""

    form: _Form
    system: PolytopicDelaySystem
    data: SystemData
    scaling: NDArray[np.float64]

    @classmethod
    def of(cls, system: PolytopicDelaySystem, method: LMIMethod, mu: float | None,
           scaling: NDArray[np.float64], mode: str) -> _Posed:
        """Pose ``system`` in the coordinates ``x = diag(scaling) z``.

        The form is shared with earlier systems of the same structure posed in the same
        coordinates (the cells of a cover have the same balancing); a storage on rate-bounded
        parameters gets a form of its own, with the numbers as constants.
        """
        scaled = system.scaled(scaling)
        channels = Channels.of(scaled, mode)
        if scaled.uncertainty is None or not scaled.uncertainty.scheduled:
            form, data = _shared_form(scaled, method, mu, channels, scaling)
        else:
            data = system_data(method, scaled, channels, mu)
            form = _Form(scaled, method, mu, channels, data, shared=False)
        return cls(form, scaled, data, scaling)

    def solve(self, bounds: tuple[float, ...], threads: int = 0
              ) -> tuple[str, dict[str, np.ndarray], dict[str, float]]:
        """:meth:`_Form.solve` for this system."""
        return self.form.solve(self.system, self.data, bounds, threads)


def _value(var: cp.Variable) -> np.ndarray:
    value = np.asarray(var.value, dtype=np.float64)
    return 0.5 * (value + value.T) if var.is_symmetric() else value


class LMIProblem:
    """The LMIs of one method for one system and delay class, with the bounds as parameters.

    The cvxpy problem is built once; :meth:`solve` only updates the delay-bound parameters, so
    repeated solves (bisection) reuse the compiled problem. The problem maximises a common
    margin ``t <= MARGIN_CAP`` with every condition ``F >= t I`` under the scale normalisation
    ``sum trace(positivity conditions) <= 1``. A bound the LMIs fail in the system's own
    coordinates is tried again in the balanced coordinates of
    :meth:`~certify.PolytopicDelaySystem.balancing` (built on first need): badly scaled states
    can push the margin below the solver's tolerance, though balancing does not help every
    system.

    Parameters
    ----------
    system : PolytopicDelaySystem
        The system.
    method : LMIMethod
        The LMI method.
    mu : float or None
        Delay-derivative bound (``None`` fast-varying, ``0.0`` constant delays).
    lower : float or sequence of float, optional
        Lower delay bounds ``l_i`` (a minimum latency): the problem certifies
        ``l_i <= tau_i(t) <= h_i``. Default 0.
    channels : str, optional
        ``"reduced"`` (default): the functional acts on the delayed signals ``y_i = C_i x``
        (:mod:`certify.channels`); ``"full"``: on the whole state.
    retry : {"always", "accurate"}, optional
        When a bound that fails is tried again in balanced coordinates: after any failure
        (default), or only after an accurate solve (status ``optimal``) whose margin or
        re-check failed. A solve that ends ``optimal_inaccurate`` on a well scaled system is
        rarely rescued by balancing; a caller that can split a failed problem instead (a
        cover's cells) saves the second solve.
    threads : int, optional
        Most threads of Clarabel's linear algebra per solve (0, the default: Clarabel's own
        choice, every core); solves that run side by side should share the cores.
    """

    def __init__(self, system: PolytopicDelaySystem, method: LMIMethod, mu: float | None,
                 lower: float | Sequence[float] = 0.0, channels: str = "reduced",
                 retry: str = "always", threads: int = 0) -> None:
        if retry not in RETRIES:
            raise ValueError(f"retry must be one of {', '.join(RETRIES)}, got {retry!r}")
        self.retry = retry
        self.threads = check_threads(threads)
        self.system = system
        self.lower = lower_bounds(lower, system.m)
        self.method = method.with_lower(self.lower)
        self.mu = check_mu(mu)
        self.channels = channels
        self._forms = [_Posed.of(system, self.method, self.mu, np.ones(system.n), channels)]
        self.assumptions = (
            delay_class_text(self.mu, self.lower),
            _system_text(system),
            *self.method.assumptions(self.mu),
            ("functional on the whole state" if channels == "full" else
             "delay channel i acts through y_i = C_i x (row space of A_i over all vertices); "
             "the functional acts on y_i"),
            f"numerics: every LMI re-checked in numpy with relative eigenvalue margin >= {RTOL:g}",
        )

    @property
    def problem(self) -> cp.Problem:
        """The cvxpy problem in the system's own coordinates."""
        return self._forms[0].form.problem

    def _balanced(self) -> _Posed | None:
        """The balanced form (built on first use), or None if balancing changes nothing."""
        if len(self._forms) == 1:
            scaling = self.system.balancing()
            if np.all(scaling == 1.0):
                return None
            self._forms.append(_Posed.of(self.system, self.method, self.mu, scaling,
                                         self.channels))
        return self._forms[1]

    def solve(self, h: Sequence[float] | NDArray[np.float64]) -> Certificate:
        """Solve for the delay bounds ``h`` and re-check the result in numpy.

        Parameters
        ----------
        h : sequence of float
            Upper bound of each delay (positive).

        Returns
        -------
        Certificate
            ``certified`` is true only if the solver reports an optimal solution with a
            positive margin and every condition passes the numpy re-check, in the system's
            coordinates or else in balanced ones (``scaling``).
        """
        bounds = tuple(float(x) for x in h)
        if len(bounds) != self.system.m or any(b < low for b, low in zip(bounds, self.lower,
                                                                           strict=True)):
            raise ValueError(f"delay bounds {list(bounds)} must be {self.system.m} values, each "
                             f"at least its lower bound {list(self.lower)}")
        form = self._forms[0]
        status, matrices, res = form.solve(bounds, self.threads)
        certified = bool(res) and all(r >= RTOL for r in res.values())
        skip = certified or (self.retry == "accurate" and status != cp.OPTIMAL)
        balanced = None if skip else self._balanced()
        if balanced is not None:
            outcome = balanced.solve(bounds, self.threads)
            if outcome[2] and all(r >= RTOL for r in outcome[2].values()):
                form, (status, matrices, res), certified = balanced, outcome, True
        scaled = not np.all(form.scaling == 1.0)
        return Certificate(
            certified=certified,
            method=self.method.name,
            delay_bounds=bounds,
            delay_lower=self.lower if any(self.lower) else (),
            mu=self.mu,
            assumptions=self.assumptions + (
                ("numerics: states scaled by powers of two, x = diag(scaling) z; matrices and "
                 "channels refer to z",) if scaled else ()),
            system=self.system,
            scaling=tuple(float(x) for x in form.scaling) if scaled else (),
            solver=SOLVER,
            status=status,
            matrices=matrices if certified else {},
            channels=form.form.channels.C,
            residuals=res,
            eliminated=form.data.eliminated,
        )
