r"""The safety layer of the polytope classes: frozen, switching and rate-bounded gains.

Every action ``a = [K_r^1..K_r^n, B_r^1..B_r^n]`` that reaches the plant is replaced by

.. math::

    P(a_{raw}) = \arg\min_a \|a - a_{raw}\|^2 \quad \text{s.t.} \quad G a \le h
    \;[\,\text{and } |a - a_{prev}| \le \rho T_s\,],

where ``{a : G a <= h}`` is the polytope of a
:class:`~teleopkit.certification.gain_certificate.GainCertificate` and the optional rate box comes
from a rate-bounded certificate (``gain_variation = "rate:R"``). The projection is exact and
allocation-free (:mod:`teleopkit.safety.polygons`); one sample costs a few microseconds including
the Python call, a batch runs in one compiled loop. :meth:`PolytopeLayer.project` and
:meth:`PolytopeLayer.project_batch` are pure (the previous action is an argument);
:meth:`PolytopeLayer.step` is the control step, which keeps the applied action as the next step's
previous one. :meth:`PolytopeLayer.project_qp` solves the same QP with cvxpy and Clarabel (one
parametrised DPP problem, re-solved) to check the fast path.

The layer is total: a non-finite raw action yields a certified fallback (the projection of the
previous action when one is given and finite, else a fixed interior point: the Chebyshev centre of
each joint's polygon), and every call reports what it did
(:class:`~teleopkit.safety.layer.Projection`). Finite actions are projected exactly up to magnitudes
of about 1e150 (beyond, squared distances overflow and the result is a vertex of the set: still
certified, no longer the nearest point).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from teleopkit.certification.gain_sets import GainPolytope
from teleopkit.safety.layer import FLAGS, Projection, SafetyLayer, kkt_polish
from teleopkit.safety.polygons import (
    chebyshev_centre,
    check_bounded,
    finite,
    joint_rows,
    project_many,
    project_one,
)

__all__ = ["PolytopeLayer"]


class PolytopeLayer(SafetyLayer):
    """Exact projection of remote gains onto a certified gain polytope.

    Build it with :func:`~teleopkit.safety.factory.layer_for` (the documented path): the set is
    the certificate's polytope, never hand-typed numbers. The constructor takes a
    :class:`~teleopkit.certification.gain_sets.GainPolytope` directly (for tests and for
    polytopes checked elsewhere). The layer holds scratch buffers, so one instance must not be
    shared between threads.

    Parameters
    ----------
    polytope : GainPolytope
        The admissible set ``{a : G a <= h}``: bounded, non-empty, one polygon per joint (no row
        may couple two joints).
    max_step : float or ndarray of shape (2 n,), optional
        Largest change ``rho T_s`` of each gain per control step; ``None`` for no rate bound.
    tol : float
        Distance to a constraint's hyperplane below which it is reported active, and slack of the
        rate-bound report.

    Raises
    ------
    ValueError
        If the polytope is empty, unbounded, couples joints, or ``max_step`` is not positive.

    Examples
    --------
    >>> from teleopkit.certification import certify_gains
    >>> from teleopkit.certification.gain_sets import GainBox
    >>> from teleopkit.model.params import paper_setup
    >>> cert = certify_gains(paper_setup(), GainBox.uniform((1.0, 50.0), (1.0, 150.0)))
    >>> layer = PolytopeLayer(cert.polytope)
    >>> result = layer.project(np.array([40.0, 10.0, 60.0, 30.0]))
    >>> result.action.round(3).tolist(), bool(result.fallback)
    ([26.207, 10.0, 65.517, 30.0], False)
    """

    def __init__(self, polytope: GainPolytope, max_step: float | np.ndarray | None = None,
                 tol: float = 1e-9) -> None:
        if polytope.is_empty():
            raise ValueError("the gain polytope is empty: no certified gain to project onto")
        self.polytope = polytope
        self.tol = float(tol)
        n = polytope.dimension // 2
        self._rows = joint_rows(polytope)
        for i in range(n):
            check_bounded(self._rows, i)
        self._row_norm = np.hypot(self._rows[:, 1], self._rows[:, 2])
        polygons = [polytope.joint_vertices(i) for i in range(n)]
        self._counts = np.array([len(p) for p in polygons], dtype=np.int64)
        self._vertices = np.zeros((n, self._counts.max(), 2))
        for i, polygon in enumerate(polygons):
            self._vertices[i, :len(polygon)] = polygon
        self.max_step = None if max_step is None else self._check_step(max_step)
        centres = np.array([chebyshev_centre(self._rows, i) for i in range(n)])
        self._geometry = self._pack(np.zeros(2 * n))  # a finite action never falls back
        self._centre = self.project(np.concatenate([centres[:, 0], centres[:, 1]])).action
        self._geometry = self._pack(self._centre)
        self._qp: dict[bool, tuple[Any, Any, Any, Any]] = {}
        self._prev: np.ndarray | None = None

    def _pack(self, centre: np.ndarray) -> tuple[Any, ...]:
        """The kernels' trailing arguments (see :mod:`teleopkit.safety.polygons`)."""
        step = np.zeros(self.dimension) if self.max_step is None else self.max_step
        work = np.zeros((2, self._counts.max() + 4, 2))
        return (step, self.max_step is not None, self._rows, self._row_norm, self._vertices,
                self._counts, centre, self.tol, work)

    def _check_step(self, max_step: float | np.ndarray) -> np.ndarray:
        step = np.broadcast_to(np.asarray(max_step, dtype=float), (self.dimension,)).copy()
        if not (np.all(np.isfinite(step)) and np.all(step > 0)):
            raise ValueError(f"rate bound per step must be positive and finite, got {max_step}")
        return step

    @property
    def labels(self) -> tuple[str, ...]:
        """The polytope's row labels: what each entry of :attr:`Projection.active` stands for."""
        return self.polytope.labels

    @property
    def admissible_set(self) -> GainPolytope:
        """The certified polytope."""
        return self.polytope

    def reset(self) -> None:
        """Start an episode: no previous action (no rate box, the centre as fallback)."""
        self._prev = None

    def step(self, raw: np.ndarray) -> Projection:
        """One control step: project with the last applied action as ``prev``, then keep it.

        Parameters
        ----------
        raw : ndarray, shape (B, 2 n) or (2 n,)
            Raw actions; NaN and inf are allowed (fallback).

        Returns
        -------
        Projection
            As :meth:`project_batch` (or :meth:`project` for one action).

        Raises
        ------
        ValueError
            On a batch size other than the episode's (call :meth:`reset` to start another).
        """
        raw = np.asarray(raw, dtype=np.float64)
        prev = self._prev
        if prev is not None and prev.shape != raw.shape:
            raise ValueError(f"the episode has actions of shape {prev.shape}, got {raw.shape}; "
                             "call reset() to start another")
        result = self.project(raw, prev) if raw.ndim == 1 else self.project_batch(raw, prev)
        self._prev = np.asarray(result.action)
        return result

    def project_set(self, raw: np.ndarray) -> np.ndarray:
        """The nearest points of the static set: no rate box, no floor, no state touched.

        What constant gains can be: the set a fixed-gain baseline or a search chooses from.

        Parameters
        ----------
        raw : ndarray, shape (B, 2 n) or (2 n,)
            Raw actions (finite).

        Returns
        -------
        ndarray, the shape of ``raw``
            Their projections.
        """
        raw = np.asarray(raw, dtype=float)
        return self.project_batch(np.atleast_2d(raw)).action.reshape(raw.shape)  # no prev

    def contains(self, actions: np.ndarray) -> np.ndarray:
        """Whether each action lies in the certified set (within ``1e-9``).

        Parameters
        ----------
        actions : ndarray, shape (..., 2 n)
            Gain vectors.

        Returns
        -------
        ndarray of bool, shape (...)
            Membership of each action.
        """
        return self.polytope.contains(actions)

    @property
    def fallback_action(self) -> np.ndarray:
        """The fixed interior action used when no finite action is available (a copy)."""
        return self._centre.copy()

    def project(self, raw: np.ndarray, prev: np.ndarray | None = None) -> Projection:
        """Project one raw action (exact, total, allocation-free kernel).

        Parameters
        ----------
        raw : ndarray, shape (2 n,)
            Raw action ``[K_r..., B_r...]``; NaN and inf are allowed (fallback).
        prev : ndarray, shape (2 n,), optional
            Previously applied action: centre of the rate box (if the layer has a rate bound) and
            the fallback for a non-finite ``raw``.

        Returns
        -------
        Projection
            Applied action, distance, active constraints and fallback flags.
        """
        dim = (self.dimension,)
        raw = self._actions(raw, dim, "raw action")
        prev_array = raw if prev is None else self._actions(prev, dim, "previous action")
        out = np.empty(dim)
        active = np.empty(self._rows.shape[0], dtype=np.bool_)
        rate_active = np.empty(dim, dtype=np.bool_)
        flags, distance = project_one(raw, prev_array, prev is not None, out, active,
                                       rate_active, *self._geometry)
        return Projection(out, distance, active, rate_active, FLAGS[flags])

    def project_batch(self, raw: np.ndarray, prev: np.ndarray | None = None) -> Projection:
        """Project a batch of raw actions in one compiled loop.

        Parameters
        ----------
        raw : ndarray, shape (B, 2 n)
            Raw actions; NaN and inf are allowed (fallback per row).
        prev : ndarray, shape (B, 2 n), optional
            Previously applied actions (rate box centres and fallbacks).

        Returns
        -------
        Projection
            Arrays with a leading batch axis; ``fallback`` holds integer :class:`Fallback` flags.
        """
        raw = np.atleast_2d(raw)
        shape = (raw.shape[0], self.dimension)
        raw = self._actions(raw, shape, "raw actions")
        prev_array = raw if prev is None else self._actions(prev, shape, "previous actions")
        out = np.empty(shape)
        active = np.empty((shape[0], self._rows.shape[0]), dtype=np.bool_)
        rate_active = np.empty(shape, dtype=np.bool_)
        flags = np.empty(shape[0], dtype=np.int64)
        distance = np.empty(shape[0])
        project_many(raw, prev_array, prev is not None, out, active, rate_active, flags,
                      distance, *self._geometry)
        return Projection(out, distance, active, rate_active, flags)

    def _qp_problem(self, rate: bool) -> tuple[Any, Any, Any, Any]:
        """The cvxpy QP (built once per variant): problem, variable, raw and previous action."""
        if rate not in self._qp:
            import cvxpy as cp

            dim = self.dimension
            a = cp.Variable(dim)
            a_raw, a_prev = cp.Parameter(dim), cp.Parameter(dim)
            constraints = [self.polytope.G @ a <= self.polytope.h]
            if rate:
                constraints += [a <= a_prev + self.max_step, a >= a_prev - self.max_step]
            problem = cp.Problem(cp.Minimize(cp.sum_squares(a - a_raw)), constraints)
            self._qp[rate] = (problem, a, a_raw, a_prev)
        return self._qp[rate]

    def project_qp(self, raw: np.ndarray, prev: np.ndarray | None = None) -> np.ndarray:
        """Solve the projection QP with cvxpy and Clarabel (reference for the fast path).

        The problem is a parametrised DPP problem built once (per use of the rate bound) and
        re-solved with new parameter values. An interior-point solution stalls near 1e-7 at
        degenerate points (a raw action on a vertex), so it is polished: the equality-constrained
        least-squares problem on its active set is solved exactly and kept when it satisfies the
        KKT conditions (then it is the optimum, to rounding). It is not total: non-finite input or
        an infeasible rate box raise.

        Parameters
        ----------
        raw : ndarray, shape (2 n,)
            Raw action (finite).
        prev : ndarray, shape (2 n,), optional
            Previous action; used only when the layer has a rate bound.

        Returns
        -------
        ndarray, shape (2 n,)
            The projection.

        Raises
        ------
        ValueError
            If an input is not finite or the solver does not reach optimality.
        """
        import cvxpy as cp

        dim = (self.dimension,)
        raw = self._actions(raw, dim, "raw action")
        rate = self.max_step is not None and prev is not None
        centre = raw if prev is None else self._actions(prev, dim, "previous action")
        if not (finite(raw) and finite(centre)):
            raise ValueError("the reference projection needs finite actions")
        problem, a, a_raw, a_prev = self._qp_problem(rate)
        a_raw.value, a_prev.value = raw, centre
        solved = (cp.OPTIMAL, cp.OPTIMAL_INACCURATE)
        for equilibrate in (True, False):  # each setting stalls at a few projections on a vertex
            problem.solve(solver=cp.CLARABEL, tol_gap_abs=1e-12, tol_gap_rel=1e-12,
                          tol_feas=1e-12, tol_ktratio=1e-10, equilibrate_enable=equilibrate)
            if problem.status in solved:
                break
        else:
            raise ValueError(f"reference projection failed: {problem.status}")
        g, h = self.polytope.G, self.polytope.h
        if rate:
            eye = np.eye(self.dimension)
            g = np.vstack([g, eye, -eye])
            h = np.concatenate([h, centre + self.max_step, self.max_step - centre])
        approx = np.asarray(a.value, dtype=float)
        exact = kkt_polish(g, h, raw, approx)
        if exact is None and problem.status != cp.OPTIMAL:
            raise ValueError(f"reference projection failed: {problem.status}")
        return approx if exact is None else exact


