"""Cells already decided for one question, reused by the covers of nested gain sets.

:func:`~teleopkit.certification.lmi.verdict.certify_lmi` covers several sets for the same delay
bounds: the whole box, then members of a family of polytopes cut from it, nested in one another.
Their covers split the same bounding box the same way, so the same boxes come up again,
clipping nested sets. Two facts make many of those cells free:

* an LMI solution for gains switching inside a cell holds on every subset of the cell: the
  conditions are affine in the gains and checked at the cell's vertices, and the vertices of a
  subset are convex combinations of them. A cell inside a certified one is certified by
  re-checking the old solution at its own vertices (in numpy, no solve); if the re-check fails,
  the cell is solved as usual;
* a cell that contains one the solver could not certify is not solved: a solution for it would
  be one for the smaller cell. It is split at once (which only ever costs cells, never soundness).

Single gain vertices checked alone are remembered as well.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from certify import Certificate
from teleopkit.certification.gain_sets import GainPolytope
from teleopkit.certification.lmi.systems import DelayQuestion, gain_set_system

__all__ = ["CellMemo"]

Box = tuple[np.ndarray, np.ndarray]


def _key(array: np.ndarray) -> bytes:
    return np.ascontiguousarray(array, dtype=float).tobytes()


def _inside(inner: GainPolytope, outer: GainPolytope) -> bool:
    """Whether every vertex of ``inner`` lies in ``outer`` (so ``inner`` is a subset)."""
    corners = inner.vertices()
    return corners.size > 0 and bool(outer.contains(corners).all())


@dataclass
class CellMemo:
    """Verdicts of one question (plant, delay bounds, lower bounds, LMI method) by box and vertex.

    Parameters
    ----------
    question : DelayQuestion
        What every verdict answers.
    """

    question: DelayQuestion
    _certified: dict[bytes, list[tuple[GainPolytope, Certificate]]] = field(
        default_factory=dict, init=False, repr=False)
    _failed: dict[bytes, list[tuple[GainPolytope, Certificate]]] = field(
        default_factory=dict, init=False, repr=False)
    _vertices: dict[bytes, tuple[np.ndarray, Certificate]] = field(
        default_factory=dict, init=False, repr=False)

    def recall(self, box: Box, cell: GainPolytope) -> Certificate | None:
        """The verdict on a cell that follows from earlier ones, if one does.

        Parameters
        ----------
        box : tuple of ndarray
            The box ``(lower, upper)`` the cell is clipped to.
        cell : GainPolytope
            The cell (gains switching inside it).

        Returns
        -------
        certify.Certificate or None
            A re-checked certificate of the cell (certified), the certificate that failed on a
            cell inside it (not certified), or ``None``: the cell must be solved.
        """
        key = _key(np.concatenate(box))
        for region, cert in self._certified.get(key, ()):
            if _inside(cell, region):
                system = gain_set_system(self.question.params, cell, "switching")
                reused = dataclasses.replace(cert, system=system)
                if reused.verify():
                    return reused
        for region, cert in self._failed.get(key, ()):
            if _inside(region, cell):
                return cert
        return None

    def record(self, box: Box, cell: GainPolytope, cert: Certificate) -> None:
        """Remember the solver's verdict on a cell.

        Parameters
        ----------
        box : tuple of ndarray
            The box ``(lower, upper)`` the cell is clipped to.
        cell : GainPolytope
            The cell.
        cert : certify.Certificate
            Its certificate (certified or not).
        """
        verdicts = self._certified if cert.certified else self._failed
        verdicts.setdefault(_key(np.concatenate(box)), []).append((cell, cert))

    def vertex(self, action: np.ndarray) -> Certificate | None:
        """The certificate of one gain vertex checked alone, if it was.

        Parameters
        ----------
        action : ndarray, shape (2 n,)
            Remote gains ``[K_r..., B_r...]``.

        Returns
        -------
        certify.Certificate or None
            Its certificate, or ``None`` if it was not checked.
        """
        known = self._vertices.get(_key(action))
        return None if known is None else known[1]

    def record_vertex(self, action: np.ndarray, cert: Certificate) -> None:
        """Remember the certificate of one gain vertex checked alone.

        Parameters
        ----------
        action : ndarray, shape (2 n,)
            Remote gains.
        cert : certify.Certificate
            Its certificate.
        """
        self._vertices[_key(action)] = (np.array(action, dtype=float), cert)

    def failed_vertex(self, polytope: GainPolytope) -> tuple[np.ndarray, Certificate] | None:
        """A gain vertex inside ``polytope`` checked alone and not certified, if there is one.

        No LMI certifies a set of switching gains containing such a point: its conditions
        restricted to the point would certify the point alone.

        Parameters
        ----------
        polytope : GainPolytope
            The gain set.

        Returns
        -------
        tuple of (ndarray, certify.Certificate) or None
            The gains and their failed certificate, or ``None``.
        """
        for action, cert in self._vertices.values():
            if not cert.certified and polytope.contains(action[None, :]).all():
                return action, cert
        return None
