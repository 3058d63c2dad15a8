"""Backend-neutral assembly of block matrices for LMIs.

The same assembly code serves the cvxpy problem (decision variables are cvxpy
expressions, delay bounds are cvxpy parameters) and the numpy re-check of a stored
certificate (everything is a float array). Only ``+``, ``*``, ``@`` and ``.T`` are
used on the operands, so both backends work unchanged; :meth:`BlockMatrix.assemble`
picks ``cvxpy.bmat`` or ``numpy.block`` at the end.

A *form* is a dictionary ``{block name: coefficient}`` and denotes the linear map
``xi -> sum_k coefficient_k @ xi_k`` on the augmented vector ``xi``; a coefficient is
a scalar (number or scalar parameter) or a matrix.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import cvxpy as cp
import numpy as np

__all__ = ["BlockMatrix", "Form", "MatrixInequality", "bmat", "diag", "form_matrix", "hadamard",
           "is_symbolic"]

Form = Mapping[str, Any]


def is_symbolic(value: Any) -> bool:
    """Tell whether ``value`` is a cvxpy expression (rather than a number or an array).

    Parameters
    ----------
    value : Any
        Operand.

    Returns
    -------
    bool
        ``True`` for cvxpy expressions.
    """
    return isinstance(value, cp.Expression)


def bmat(rows: list[list[Any]]) -> Any:
    """Assemble a block matrix with ``cvxpy.bmat`` if any block is symbolic, else ``numpy.block``.

    Parameters
    ----------
    rows : list of list
        Blocks, row by row (arrays or cvxpy expressions of compatible shapes).

    Returns
    -------
    numpy.ndarray or cvxpy.Expression
        The assembled matrix.
    """
    if any(is_symbolic(b) for row in rows for b in row):
        return cp.bmat(rows)
    return np.block(rows)


def diag(vector: Any) -> Any:
    """The diagonal matrix of a vector (``cvxpy.diag`` for an expression, else ``numpy.diag``).

    Parameters
    ----------
    vector : array or cvxpy expression, shape (r,)
        The diagonal.

    Returns
    -------
    numpy.ndarray or cvxpy.Expression
        The ``(r, r)`` matrix.
    """
    return cp.diag(vector) if is_symbolic(vector) else np.diag(vector)


def hadamard(a: Any, b: Any) -> Any:
    """The entrywise product (``cvxpy.multiply`` if either operand is symbolic).

    Parameters
    ----------
    a, b : array or cvxpy expression
        Operands of the same shape.

    Returns
    -------
    numpy.ndarray or cvxpy.Expression
        ``a * b`` entry by entry.
    """
    return cp.multiply(a, b) if is_symbolic(a) or is_symbolic(b) else a * b


def _is_scalar(coef: Any) -> bool:
    return bool(np.ndim(coef) == 0) if not is_symbolic(coef) else coef.shape == ()


def _left(coef: Any, mat: Any) -> Any:
    """Return ``coef.T @ mat`` (``coef * mat`` for a scalar)."""
    return coef * mat if _is_scalar(coef) else coef.T @ mat


def _right(mat: Any, coef: Any) -> Any:
    """Return ``mat @ coef`` (``mat * coef`` for a scalar)."""
    return mat * coef if _is_scalar(coef) else mat @ coef


def form_matrix(form: Form, sizes: Mapping[str, int], rows: int) -> np.ndarray:
    """The numeric matrix of a form over the blocks ``sizes`` (absent blocks are zero).

    Parameters
    ----------
    form : Form
        Numeric form; a scalar coefficient stands for that multiple of the identity.
    sizes : Mapping[str, int]
        Ordered block names and their dimensions.
    rows : int
        Number of rows of the form's image.

    Returns
    -------
    numpy.ndarray, shape (rows, sum(sizes))
        The matrix ``L`` with ``L xi = sum_k coefficient_k xi_k``.
    """
    parts = []
    for name, size in sizes.items():
        coef = form.get(name, 0.0)
        parts.append(coef * np.eye(rows, size) if np.ndim(coef) == 0 else np.asarray(coef))
    return np.hstack(parts)


class BlockMatrix:
    """Symmetric matrix over named blocks of the augmented vector, built term by term.

    Parameters
    ----------
    sizes : Mapping[str, int]
        Ordered block names and their dimensions.
    """

    def __init__(self, sizes: Mapping[str, int]) -> None:
        self.sizes = dict(sizes)
        self._terms: dict[tuple[str, str], list[Any]] = {}

    def _add_block(self, row: str, col: str, value: Any) -> None:
        if row not in self.sizes or col not in self.sizes:
            raise KeyError(f"unknown block {row!r} or {col!r}")
        self._terms.setdefault((row, col), []).append(value)

    def add_quad(self, form: Form, mat: Any) -> None:
        """Add ``L^T mat L`` for the form ``L`` and a symmetric ``mat``.

        Parameters
        ----------
        form : Form
            The left and right form ``L``.
        mat : array or cvxpy expression
            Symmetric middle matrix.
        """
        for ka, ca in form.items():
            left = _left(ca, mat)
            for kb, cb in form.items():
                self._add_block(ka, kb, _right(left, cb))

    def add_he(self, left: Form, mat: Any, right: Form) -> None:
        """Add ``L^T mat R + R^T mat^T L`` (twice the symmetric part of ``L^T mat R``).

        Parameters
        ----------
        left : Form
            Left form ``L``.
        mat : array or cvxpy expression
            Middle matrix (any shape compatible with the forms).
        right : Form
            Right form ``R``.
        """
        for ka, ca in left.items():
            lm = _left(ca, mat)
            for kb, cb in right.items():
                term = _right(lm, cb)
                self._add_block(ka, kb, term)
                self._add_block(kb, ka, term.T)

    def assemble(self) -> Any:
        """Return the full matrix (``numpy.ndarray`` or cvxpy expression).

        Returns
        -------
        numpy.ndarray or cvxpy.Expression
            The assembled symmetric matrix.
        """
        names = list(self.sizes)
        return bmat([[self._block(r, c) for c in names] for r in names])

    def _block(self, row: str, col: str) -> Any:
        terms = self._terms.get((row, col))
        if not terms:
            return np.zeros((self.sizes[row], self.sizes[col]))
        total = terms[0]
        for t in terms[1:]:
            total = total + t
        return total


@dataclass(frozen=True)
class MatrixInequality:
    """A named condition ``matrix >= 0`` (positive semidefinite, strictly with a margin).

    Parameters
    ----------
    name : str
        Label (used for residuals and error messages).
    matrix : Any
        Symmetric matrix: numpy array or cvxpy expression.
    normalise : bool
        Whether the trace of this matrix enters the scale normalisation of the problem
        (true for positivity conditions of the functional, false for derivative conditions).
    """

    name: str
    matrix: Any
    normalise: bool = False
