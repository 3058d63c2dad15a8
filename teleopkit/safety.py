r"""Safety layer: project raw remote gains onto a certified gain polytope.

Every action ``a = [K_r^1..K_r^n, B_r^1..B_r^n]`` that reaches the plant is replaced by

.. math::

    P(a_{raw}) = \arg\min_a \|a - a_{raw}\|^2 \quad \text{s.t.} \quad G a \le h
    \;[\,\text{and } |a - a_{prev}| \le \rho T_s\,],

where ``{a : G a <= h}`` is the polytope of a :class:`~teleopkit.certification.GainCertificate`
and the optional rate box comes from a rate-bounded certificate (``gain_variation = "rate:R"``).

The polytope is a product of one convex polygon per joint in the plane ``(K_r^i, B_r^i)``, and so
is its intersection with the rate box, so the projection splits into ``n`` exact 2-D projections:
a point inside the polygon stays; otherwise the nearest point of the polygon's edges is the
projection. With a rate bound the polygon is first clipped by the box (Sutherland–Hodgman). The
compiled kernel (numba) does not allocate; one sample costs a few microseconds including the Python
call, a batch runs in one compiled loop. :meth:`SafetyLayer.project_reference` solves the same QP
with cvxpy and Clarabel (one parametrised DPP problem, re-solved) to check the fast path.

The layer is total: a non-finite raw action yields a certified fallback (the projection of the
previous action when one is given and finite, else a fixed interior point: the Chebyshev centre of
each joint's polygon), and every call reports what it did (:class:`Projection`). Finite actions
are projected exactly up to magnitudes of about 1e150 (beyond, squared distances overflow and the
result is a vertex of the set: still certified, no longer the nearest point).
"""

from __future__ import annotations

import enum
import math
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from teleopkit.certification import GainCertificate, parse_gain_variation
from teleopkit.gains import GainPolytope

__all__ = ["Fallback", "Projection", "SafetyLayer"]

# The kernel never allocates, so it runs without numba's reference counting (``_nrt=False``):
# atomic reference-count updates were a third of its time.
_OPTIONS: dict[str, Any] = {"cache": True, "nogil": True, "error_model": "numpy", "_nrt": False}
_jit = njit(**_OPTIONS)
_inline = njit(forceinline=True, **_OPTIONS)

class Fallback(enum.IntFlag):
    """What the safety layer did beyond an exact projection (flags, combinable).

    Attributes
    ----------
    NONE
        Exact projection of the raw action.
    NONFINITE_INPUT
        The raw action had NaN or inf: the previous action (projected) or, without a finite
        previous action, the layer's fixed interior point was applied.
    RATE_INFEASIBLE
        The rate bound could not be applied (the rate box around the previous action misses the
        set, or the previous action is not finite): projected onto the polytope alone.
    """

    NONE = 0
    NONFINITE_INPUT = 1
    RATE_INFEASIBLE = 2


_FLAGS = tuple(Fallback(value) for value in range(4))


class Projection(NamedTuple):
    """What :meth:`SafetyLayer.project` (one sample) or :meth:`SafetyLayer.project_batch` did.

    Attributes
    ----------
    action : ndarray, shape (2 n,) or (B, 2 n)
        Applied (certified) action.
    distance : float or ndarray, shape (B,)
        ``||action - raw||`` (``inf`` when the raw action was not finite).
    active : ndarray of bool, shape (m,) or (B, m)
        Rows of ``G`` that hold with equality (distance to the hyperplane within the layer's
        tolerance) at the applied action.
    rate_active : ndarray of bool, shape (2 n,) or (B, 2 n)
        Coordinates at their rate bound ``|a - a_prev| = rho T_s``.
    fallback : Fallback or ndarray of int, shape (B,)
        :class:`Fallback` flags (integers for a batch); zero means an exact projection.
    """

    action: np.ndarray
    distance: float | np.ndarray
    active: np.ndarray
    rate_active: np.ndarray
    fallback: Fallback | np.ndarray


# --- compiled kernel --------------------------------------------------------------------------
# Geometry, packed once by SafetyLayer (its ``_geometry``, the kernels' trailing arguments): the
# per-step rate bound ``step`` (2 n,) and whether it applies, rows (m, 4) = [joint, g_K, g_B, h]
# in the joint's plane (joint -1 for an all-zero row), row_norm (m,), vertices (n, k_max, 2) in
# order around each polygon, counts (n,), the fallback ``centre`` (2 n,), the report tolerance,
# and work (2, k_max + 4, 2), scratch for clipping.


@_inline
def _finite(x: np.ndarray) -> bool:
    for value in x:
        if not math.isfinite(value):
            return False
    return True


@_inline
def _in_polygon(x: float, y: float, joint: int, rows: np.ndarray) -> bool:
    for r in range(rows.shape[0]):
        if rows[r, 0] == joint and rows[r, 1] * x + rows[r, 2] * y > rows[r, 3]:
            return False
    return True


@_inline
def _nearest_on_edges(x: float, y: float, polygons: np.ndarray, p: int,
                      k: int) -> tuple[float, float]:
    """Nearest point to ``(x, y)`` on the edges of polygon ``polygons[p, :k]``."""
    best, bx, by = math.inf, polygons[p, 0, 0], polygons[p, 0, 1]
    for e in range(k):
        f = (e + 1) % k
        ax, ay = polygons[p, e, 0], polygons[p, e, 1]
        dx, dy = polygons[p, f, 0] - ax, polygons[p, f, 1] - ay
        length2 = dx * dx + dy * dy
        t = 0.0
        if length2 > 0.0:
            t = min(1.0, max(0.0, ((x - ax) * dx + (y - ay) * dy) / length2))
        px, py = ax + t * dx, ay + t * dy
        d = (px - x) ** 2 + (py - y) ** 2
        if d < best:
            best, bx, by = d, px, py
    return bx, by


@_inline
def _clip(src: np.ndarray, s: int, k: int, axis: int, bound: float, sign: float,
          dst: np.ndarray, d: int) -> int:
    """Sutherland–Hodgman step: clip ``src[s, :k]`` to ``sign * (p[axis] - bound) <= 0``.

    The result goes to ``dst[d]``; returns its vertex count.
    """
    count = 0
    for e in range(k):
        f = (e + 1) % k
        sp = sign * (src[s, e, axis] - bound)
        sq = sign * (src[s, f, axis] - bound)
        if sp <= 0.0:
            dst[d, count, 0], dst[d, count, 1] = src[s, e, 0], src[s, e, 1]
            count += 1
        if (sp < 0.0 < sq) or (sq < 0.0 < sp):
            t = sp / (sp - sq)
            dst[d, count, 0] = src[s, e, 0] + t * (src[s, f, 0] - src[s, e, 0])
            dst[d, count, 1] = src[s, e, 1] + t * (src[s, f, 1] - src[s, e, 1])
            dst[d, count, axis] = bound
            count += 1
    return count


@_inline
def _clip_to_box(vertices: np.ndarray, joint: int, k: int,
                 box: tuple[float, float, float, float], work: np.ndarray) -> int:
    """Clip a joint's polygon by ``box = (K_lo, K_hi, B_lo, B_hi)`` into ``work[0]``."""
    k = _clip(vertices, joint, k, 0, box[1], 1.0, work, 1)
    k = _clip(work, 1, k, 0, box[0], -1.0, work, 0)
    k = _clip(work, 0, k, 1, box[3], 1.0, work, 1)
    return _clip(work, 1, k, 1, box[2], -1.0, work, 0)


@_inline
def _project_joint(x: float, y: float, joint: int, rate: bool,
                   box: tuple[float, float, float, float], rows: np.ndarray,
                   vertices: np.ndarray, counts: np.ndarray,
                   work: np.ndarray) -> tuple[float, float, bool]:
    """Project ``(x, y)`` onto the joint's polygon [clipped by the rate box].

    The flag is False when the clipped polygon was empty (then the polygon alone is used).
    """
    in_box = not rate or (box[0] <= x <= box[1] and box[2] <= y <= box[3])
    if in_box and _in_polygon(x, y, joint, rows):
        return x, y, True
    if rate:
        k = _clip_to_box(vertices, joint, counts[joint], box, work)
        if k > 0:
            px, py = _nearest_on_edges(x, y, work, 0, k)
            return px, py, True
    px, py = _nearest_on_edges(x, y, vertices, joint, counts[joint])
    return px, py, not rate


@_inline
def _mark_active(action: np.ndarray, rows: np.ndarray, row_norm: np.ndarray, tol: float,
                 active: np.ndarray) -> None:
    n = action.size // 2
    for r in range(rows.shape[0]):
        j = int(rows[r, 0])
        active[r] = False
        if j >= 0:
            residual = rows[r, 1] * action[j] + rows[r, 2] * action[n + j] - rows[r, 3]
            active[r] = residual >= -tol * row_norm[r]


@_inline
def _distance(a: np.ndarray, b: np.ndarray) -> float:
    total = 0.0
    for c in range(a.size):
        total += (a[c] - b[c]) ** 2
    return math.sqrt(total)


@_inline
def _project_one(raw: np.ndarray, prev: np.ndarray, has_prev: bool, out: np.ndarray,
                 active: np.ndarray, rate_active: np.ndarray, step: np.ndarray, has_rate: bool,
                 rows: np.ndarray, row_norm: np.ndarray, vertices: np.ndarray,
                 counts: np.ndarray, centre: np.ndarray, tol: float,
                 work: np.ndarray) -> tuple[int, float]:
    """Project one action into ``out``; fill the reports; return (flags, distance)."""
    n = raw.size // 2
    prev_ok = has_prev and _finite(prev)
    rate = has_rate and prev_ok
    flags = 2 if has_rate and has_prev and not prev_ok else 0
    raw_ok = _finite(raw)
    source = raw if raw_ok else prev
    if not raw_ok:
        flags |= 1
    if raw_ok or prev_ok:
        for i in range(n):
            box = (prev[i] - step[i], prev[i] + step[i], prev[n + i] - step[n + i],
                   prev[n + i] + step[n + i])
            out[i], out[n + i], ok = _project_joint(source[i], source[n + i], i, rate, box,
                                                    rows, vertices, counts, work)
            if not ok:
                flags |= 2
    else:
        for c in range(2 * n):
            out[c] = centre[c]
    for c in range(2 * n):
        rate_active[c] = rate and flags & 2 == 0 and abs(out[c] - prev[c]) >= step[c] - tol
    _mark_active(out, rows, row_norm, tol, active)
    return flags, _distance(out, raw) if raw_ok else math.inf


@_jit
def _project_many(raw: np.ndarray, prev: np.ndarray, has_prev: bool, out: np.ndarray,
                  active: np.ndarray, rate_active: np.ndarray, flags: np.ndarray,
                  distance: np.ndarray, step: np.ndarray, has_rate: bool, rows: np.ndarray,
                  row_norm: np.ndarray, vertices: np.ndarray, counts: np.ndarray,
                  centre: np.ndarray, tol: float, work: np.ndarray) -> None:
    for b in range(raw.shape[0]):
        flags[b], distance[b] = _project_one(raw[b], prev[b], has_prev, out[b], active[b],
                                             rate_active[b], step, has_rate, rows, row_norm,
                                             vertices, counts, centre, tol, work)


# --- geometry ---------------------------------------------------------------------------------


def _joint_rows(polytope: GainPolytope) -> np.ndarray:
    """Rows ``[joint, g_K, g_B, h]`` (joint -1 for all-zero rows); checks the product structure."""
    n = polytope.dimension // 2
    rows = np.zeros((polytope.h.size, 4))
    for r, (g, h) in enumerate(zip(polytope.G, polytope.h, strict=True)):
        joints = np.unique(np.flatnonzero(g) % n)
        if joints.size > 1:
            raise ValueError(f"constraint {polytope.labels[r]!r} couples joints "
                             f"{(joints + 1).tolist()}: the safety layer needs a product of "
                             "per-joint polygons")
        if joints.size == 0 and h < 0:
            raise ValueError(f"the gain polytope is empty (constraint {polytope.labels[r]!r} "
                             "reads 0 <= negative)")
        j = int(joints[0]) if joints.size else -1
        rows[r] = [j, g[j], g[n + j], h] if j >= 0 else [-1, 0.0, 0.0, h]
    return rows


def _check_bounded(rows: np.ndarray, joint: int) -> None:
    """Raise unless the outward normals of the joint's polygon leave no angular gap >= pi."""
    normals = rows[rows[:, 0] == joint, 1:3]
    angles = np.sort(np.arctan2(normals[:, 1], normals[:, 0]))
    gaps = np.diff(np.concatenate([angles, angles[:1] + 2 * np.pi]))
    if angles.size < 3 or gaps.max() >= np.pi - 1e-12:
        raise ValueError(f"joint {joint + 1}'s admissible gains are unbounded; bound K_r and B_r")


def _chebyshev_centre(rows: np.ndarray, joint: int) -> np.ndarray:
    """Centre ``(K, B)`` of the largest disc inside the joint's polygon (a linear program)."""
    from scipy.optimize import linprog  # deferred: importing it costs 0.7 s at ``import teleopkit``

    mine = rows[rows[:, 0] == joint]
    norms = np.hypot(mine[:, 1], mine[:, 2])
    result = linprog(c=[0.0, 0.0, -1.0], A_ub=np.column_stack([mine[:, 1:3], norms]),
                     b_ub=mine[:, 3], bounds=[(None, None), (None, None), (0.0, None)],
                     method="highs")
    if not result.success:
        raise ValueError(f"no interior point for joint {joint + 1}: {result.message}")
    return np.asarray(result.x[:2])


class SafetyLayer:
    """Exact projection of remote gains onto a certified gain polytope.

    Build it with :meth:`from_certificate` (the documented path): the set is the certificate's
    polytope, never hand-typed numbers. The constructor takes a
    :class:`~teleopkit.gains.GainPolytope` directly (for tests and for polytopes checked
    elsewhere). The layer holds scratch buffers, so one instance must not be shared between
    threads.

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
    >>> from teleopkit.gains import GainBox
    >>> from teleopkit.params import paper_setup
    >>> cert = certify_gains(paper_setup(), GainBox.uniform((1.0, 50.0), (1.0, 150.0)))
    >>> layer = SafetyLayer.from_certificate(cert)
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
        self._rows = _joint_rows(polytope)
        for i in range(n):
            _check_bounded(self._rows, i)
        self._row_norm = np.hypot(self._rows[:, 1], self._rows[:, 2])
        polygons = [polytope.joint_vertices(i) for i in range(n)]
        self._counts = np.array([len(p) for p in polygons], dtype=np.int64)
        self._vertices = np.zeros((n, self._counts.max(), 2))
        for i, polygon in enumerate(polygons):
            self._vertices[i, :len(polygon)] = polygon
        self.max_step = None if max_step is None else self._check_step(max_step)
        centres = np.array([_chebyshev_centre(self._rows, i) for i in range(n)])
        self._geometry = self._pack(np.zeros(2 * n))  # a finite action never falls back
        self._centre = self.project(np.concatenate([centres[:, 0], centres[:, 1]])).action
        self._geometry = self._pack(self._centre)
        self._reference: dict[bool, tuple[Any, Any, Any, Any]] = {}

    def _pack(self, centre: np.ndarray) -> tuple[Any, ...]:
        """The kernels' trailing arguments (see the kernel section of this module)."""
        step = np.zeros(self.dimension) if self.max_step is None else self.max_step
        work = np.zeros((2, self._counts.max() + 4, 2))
        return (step, self.max_step is not None, self._rows, self._row_norm, self._vertices,
                self._counts, centre, self.tol, work)

    def _check_step(self, max_step: float | np.ndarray) -> np.ndarray:
        step = np.broadcast_to(np.asarray(max_step, dtype=float), (self.dimension,)).copy()
        if not (np.all(np.isfinite(step)) and np.all(step > 0)):
            raise ValueError(f"rate bound per step must be positive and finite, got {max_step}")
        return step

    @classmethod
    def from_certificate(cls, certificate: GainCertificate, period: float = 0.01,
                         rate: float | None = None, tol: float = 1e-9) -> SafetyLayer:
        """Build the layer on a certificate's polytope.

        The set is ``certificate.polytope``, the certified subset of the box asked about: it is
        accepted when it is certified (``certificate.polytope_certified``), even if the whole
        box is not; otherwise the certificate is refused. The layer keeps actions inside the set;
        which gain *variations* are covered (frozen, switching, rate-bounded) is the
        certificate's ``gain_variation``.

        Parameters
        ----------
        certificate : GainCertificate
            Verdict and polytope, for example from
            :func:`~teleopkit.certification.certify_gains`.
        period : float
            Control period ``T_s`` in seconds (converts a rate into a per-step bound).
        rate : float, optional
            Largest gain rate ``rho`` (gain units per second). Defaults to the certificate's rate
            for ``gain_variation = "rate:R"`` and to no bound otherwise; it may tighten the
            certificate's rate, never loosen it.
        tol : float
            Tolerance of the active-constraint report (see :class:`SafetyLayer`).

        Returns
        -------
        SafetyLayer
            The layer on the certified polytope, rate-bounded if asked.

        Raises
        ------
        ValueError
            If the certificate does not certify its polytope, the polytope is empty, or the
            rate exceeds the certified one.
        """
        if not certificate.polytope_certified:
            raise ValueError(f"the {certificate.method} certificate does not certify its gain "
                             f"set ({certificate.violation or 'not certified'}); refusing to "
                             "build a safety layer on it")
        if not (math.isfinite(period) and period > 0):
            raise ValueError(f"control period must be positive, got {period}")
        variation = parse_gain_variation(certificate.gain_variation)
        certified_rate = variation.rate if variation.kind == "rate" else math.inf
        chosen = certified_rate if rate is None else float(rate)
        if chosen > certified_rate:
            raise ValueError(f"rate bound {chosen:g}/s exceeds the certified {certified_rate:g}/s")
        return cls(certificate.polytope, None if math.isinf(chosen) else chosen * period, tol)

    @property
    def dimension(self) -> int:
        """Dimension ``2 n`` of the action space."""
        return self.polytope.dimension

    @property
    def fallback_action(self) -> np.ndarray:
        """The fixed interior action used when no finite action is available (a copy)."""
        return self._centre.copy()

    def active_labels(self, active: np.ndarray) -> tuple[str, ...]:
        """Labels of the active rows of one sample.

        Parameters
        ----------
        active : ndarray of bool, shape (m,)
            :attr:`Projection.active` of one sample.

        Returns
        -------
        tuple of str
            The polytope's labels of the active rows.
        """
        return tuple(label for label, on in zip(self.polytope.labels, active, strict=True) if on)

    def _actions(self, values: np.ndarray, shape: tuple[int, ...],
                 name: str) -> np.ndarray:
        array = np.ascontiguousarray(values, dtype=np.float64)
        if array.shape != shape:
            raise ValueError(f"{name} must have shape {shape}, got {array.shape}")
        return array

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
        flags, distance = _project_one(raw, prev_array, prev is not None, out, active,
                                       rate_active, *self._geometry)
        return Projection(out, distance, active, rate_active, _FLAGS[flags])

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
        _project_many(raw, prev_array, prev is not None, out, active, rate_active, flags,
                      distance, *self._geometry)
        return Projection(out, distance, active, rate_active, flags)

    def _reference_problem(self, rate: bool) -> tuple[Any, Any, Any, Any]:
        """The cvxpy QP (built once per variant): problem, variable, raw and previous action."""
        if rate not in self._reference:
            import cvxpy as cp

            dim = self.dimension
            a = cp.Variable(dim)
            a_raw, a_prev = cp.Parameter(dim), cp.Parameter(dim)
            constraints = [self.polytope.G @ a <= self.polytope.h]
            if rate:
                constraints += [a <= a_prev + self.max_step, a >= a_prev - self.max_step]
            problem = cp.Problem(cp.Minimize(cp.sum_squares(a - a_raw)), constraints)
            self._reference[rate] = (problem, a, a_raw, a_prev)
        return self._reference[rate]

    def project_reference(self, raw: np.ndarray, prev: np.ndarray | None = None) -> np.ndarray:
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
        if not (_finite(raw) and _finite(centre)):
            raise ValueError("the reference projection needs finite actions")
        problem, a, a_raw, a_prev = self._reference_problem(rate)
        a_raw.value, a_prev.value = raw, centre
        problem.solve(solver=cp.CLARABEL, tol_gap_abs=1e-12, tol_gap_rel=1e-12,
                      tol_feas=1e-12, tol_ktratio=1e-10)
        if problem.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
            raise ValueError(f"reference projection failed: {problem.status}")
        g, h = self.polytope.G, self.polytope.h
        if rate:
            eye = np.eye(self.dimension)
            g = np.vstack([g, eye, -eye])
            h = np.concatenate([h, centre + self.max_step, self.max_step - centre])
        approx = np.asarray(a.value, dtype=float)
        exact = _kkt_polish(g, h, raw, approx)
        if exact is None and problem.status != cp.OPTIMAL:
            raise ValueError(f"reference projection failed: {problem.status}")
        return approx if exact is None else exact


def _kkt_polish(g: np.ndarray, h: np.ndarray, raw: np.ndarray, approx: np.ndarray,
                tol: float = 1e-4) -> np.ndarray | None:
    """Exact projection of ``raw`` onto ``{g a <= h}`` from an approximate one.

    Rows within distance ``tol`` of ``approx`` start as equalities; the row with the most
    negative multiplier is dropped until all are non-negative. The least-squares solution is
    returned if it is also feasible (then it satisfies the KKT conditions), else None.
    """
    norms = np.linalg.norm(g, axis=1)
    active = np.flatnonzero(g @ approx - h >= -tol * norms)
    while True:
        g_a = g[active]
        multipliers = np.linalg.lstsq(g_a @ g_a.T, g_a @ raw - h[active], rcond=None)[0]
        if active.size == 0 or multipliers.min() >= -1e-9:
            break
        active = np.delete(active, np.argmin(multipliers))
    exact = raw - g_a.T @ multipliers
    feasible = np.all(g @ exact - h <= 1e-10 * norms * (1.0 + np.abs(exact).max()))
    return exact if feasible else None
