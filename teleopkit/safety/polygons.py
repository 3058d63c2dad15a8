"""The certified set as one convex polygon per joint: its geometry and compiled projection.

A gain polytope ``{a : G a <= h}`` whose rows each involve one joint is a product of polygons
in the planes ``(K_r^i, B_r^i)``, and so is its intersection with a rate box around the previous
action. The Euclidean projection then splits into ``n`` exact 2-D projections: a point inside the
polygon stays; otherwise the nearest point of the polygon's edges is the projection. With a rate
bound the polygon is first clipped by the box (Sutherland–Hodgman). The kernel (numba) does not
allocate.

Geometry packed once by :class:`~teleopkit.safety.layer.SafetyLayer` (its ``_geometry``, the
kernels' trailing arguments): the per-step rate bound ``step`` (2 n,) and whether it applies,
rows (m, 4) = [joint, g_K, g_B, h] in the joint's plane (joint -1 for an all-zero row),
row_norm (m,), vertices (n, k_max, 2) in order around each polygon, counts (n,), the fallback
``centre`` (2 n,), the report tolerance, and work (2, k_max + 4, 2), scratch for clipping.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from teleopkit.certification.gain_sets import GainPolytope

__all__ = [
    "chebyshev_centre",
    "check_bounded",
    "finite",
    "joint_rows",
    "project_many",
    "project_one",
]

# The kernel never allocates, so it runs without numba's reference counting (``_nrt=False``):
# atomic reference-count updates were a third of its time.
_OPTIONS: dict[str, Any] = {"cache": True, "nogil": True, "error_model": "numpy", "_nrt": False}
_jit = njit(**_OPTIONS)
_inline = njit(forceinline=True, **_OPTIONS)



@_inline
def finite(x: np.ndarray) -> bool:
    """Whether every entry of the 1-D array ``x`` is finite (compiled, no allocation)."""
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
    """Nearest point to ``(x, y)`` on the edges of polygon ``polygons[p, :k]``.

    Candidates are compared by the sign of ``|c - x|^2 - |b - x|^2 = (c - b) . (c + b - 2 x)``,
    not by their squared distances: two candidates a micro-unit apart, far from ``x``, have
    squared distances that agree to every digit, and comparing those picked either.
    """
    bx, by = polygons[p, 0, 0], polygons[p, 0, 1]
    for e in range(k):
        f = (e + 1) % k
        ax, ay = polygons[p, e, 0], polygons[p, e, 1]
        dx, dy = polygons[p, f, 0] - ax, polygons[p, f, 1] - ay
        length2 = dx * dx + dy * dy
        t = 0.0
        if length2 > 0.0:
            t = min(1.0, max(0.0, ((x - ax) * dx + (y - ay) * dy) / length2))
        px, py = ax + t * dx, ay + t * dy
        if (px - bx) * (px + bx - 2.0 * x) + (py - by) * (py + by - 2.0 * y) < 0.0:
            bx, by = px, py
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
def project_one(raw: np.ndarray, prev: np.ndarray, has_prev: bool, out: np.ndarray,
                 active: np.ndarray, rate_active: np.ndarray, step: np.ndarray, has_rate: bool,
                 rows: np.ndarray, row_norm: np.ndarray, vertices: np.ndarray,
                 counts: np.ndarray, centre: np.ndarray, tol: float,
                 work: np.ndarray) -> tuple[int, float]:
    """Project one action into ``out``; fill the reports; return (flags, distance)."""
    n = raw.size // 2
    prev_ok = has_prev and finite(prev)
    rate = has_rate and prev_ok
    flags = 2 if has_rate and has_prev and not prev_ok else 0
    raw_ok = finite(raw)
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
def project_many(raw: np.ndarray, prev: np.ndarray, has_prev: bool, out: np.ndarray,
                  active: np.ndarray, rate_active: np.ndarray, flags: np.ndarray,
                  distance: np.ndarray, step: np.ndarray, has_rate: bool, rows: np.ndarray,
                  row_norm: np.ndarray, vertices: np.ndarray, counts: np.ndarray,
                  centre: np.ndarray, tol: float, work: np.ndarray) -> None:
    """:func:`project_one` on every row of a batch (the arguments with a leading batch axis)."""
    for b in range(raw.shape[0]):
        flags[b], distance[b] = project_one(raw[b], prev[b], has_prev, out[b], active[b],
                                             rate_active[b], step, has_rate, rows, row_norm,
                                             vertices, counts, centre, tol, work)


def joint_rows(polytope: GainPolytope) -> np.ndarray:
    """Rows ``[joint, g_K, g_B, h]`` (joint -1 for all-zero rows); checks the product structure.

    Parameters
    ----------
    polytope : GainPolytope
        The set; no row may involve two joints.

    Returns
    -------
    ndarray, shape (m, 4)
        Each row in its joint's plane.

    Raises
    ------
    ValueError
        If a row couples joints or reads ``0 <= negative``.
    """
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


def check_bounded(rows: np.ndarray, joint: int) -> None:
    """Raise unless the outward normals of the joint's polygon leave no angular gap >= pi.

    Parameters
    ----------
    rows : ndarray, shape (m, 4)
        Output of :func:`joint_rows`.
    joint : int
        Joint index, from 0.

    Raises
    ------
    ValueError
        If the joint's admissible gains are unbounded.
    """
    normals = rows[rows[:, 0] == joint, 1:3]
    angles = np.sort(np.arctan2(normals[:, 1], normals[:, 0]))
    gaps = np.diff(np.concatenate([angles, angles[:1] + 2 * np.pi]))
    if angles.size < 3 or gaps.max() >= np.pi - 1e-12:
        raise ValueError(f"joint {joint + 1}'s admissible gains are unbounded; bound K_r and B_r")


def chebyshev_centre(rows: np.ndarray, joint: int) -> np.ndarray:
    """Centre ``(K, B)`` of the largest disc inside the joint's polygon (a linear program).

    Parameters
    ----------
    rows : ndarray, shape (m, 4)
        Output of :func:`joint_rows`.
    joint : int
        Joint index, from 0.

    Returns
    -------
    ndarray, shape (2,)
        The centre.
    """
    from scipy.optimize import linprog  # deferred: importing it costs 0.7 s at ``import teleopkit``

    mine = rows[rows[:, 0] == joint]
    norms = np.hypot(mine[:, 1], mine[:, 2])
    result = linprog(c=[0.0, 0.0, -1.0], A_ub=np.column_stack([mine[:, 1:3], norms]),
                     b_ub=mine[:, 3], bounds=[(None, None), (None, None), (0.0, None)],
                     method="highs")
    if not result.success:
        raise ValueError(f"no interior point for joint {joint + 1}: {result.message}")
    return np.asarray(result.x[:2])
