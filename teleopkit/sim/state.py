"""The simulator's state vector: one named layout for every reader.

A scenario's state is a flat vector of ``12 n`` values (``n`` joints per arm), the blocks in the
order of :data:`FIELDS`::

    [q_l, q_l', q_r, q_r', theta, theta', int e_track, int e_damp,
     int q_l'^2, iint q_l'^2, int theta'^2, iint theta'^2]

with ``e_track = theta - q_l(t - T_l)`` and ``e_damp = theta - q_r``. The last four blocks are
the velocity energies a Lyapunov–Krasovskii storage needs, integrated exactly along the run:
``I(t) = int_0^t v^2`` and its integral ``int_0^t I`` for ``v = q_l'`` and ``v = theta'`` (per
joint), from which the storage's double integrals follow at any sample time
(:mod:`teleopkit.certification.nuno.lyapunov`). The two delay channels carry
``(q_l, q_l')`` forward and ``(theta, theta')`` backward. :class:`StateLayout` names the blocks so
that the simulator, the environments, campaigns and falsification never count offsets by hand
(the compiled kernel, which needs constant offsets, is tested against the numpy integrator that
uses this layout).
"""

from __future__ import annotations

import builtins
from dataclasses import dataclass
from functools import cache, cached_property
from typing import Literal

import numpy as np

__all__ = ["FIELDS", "Field", "StateLayout"]

Field = Literal["ql", "dql", "qr", "dqr", "theta", "dtheta", "int_track", "int_damp",
                "int_dql2", "iint_dql2", "int_dtheta2", "iint_dtheta2"]

FIELDS: tuple[Field, ...] = ("ql", "dql", "qr", "dqr", "theta", "dtheta", "int_track",
                             "int_damp", "int_dql2", "iint_dql2", "int_dtheta2", "iint_dtheta2")
"""Names of the state blocks, in order: local, remote link and motor positions and velocities,
the integrated tracking and damping errors, then the single and double integrals of the squared
local and motor velocities."""

_CHANNELS: tuple[tuple[Field, Field], ...] = (("ql", "dql"), ("theta", "dtheta"))


@dataclass(frozen=True)
class StateLayout:
    """Where each block of :data:`FIELDS` sits in a state vector of ``12 n`` values.

    Parameters
    ----------
    n_joints : int
        Joints per arm.

    Examples
    --------
    >>> layout = StateLayout(2)
    >>> layout.slice("theta"), layout.size
    (slice(8, 10, None), 24)
    """

    n_joints: int

    def __post_init__(self) -> None:
        if isinstance(self.n_joints, bool) or int(self.n_joints) != self.n_joints \
                or self.n_joints < 1:
            raise ValueError(f"a state layout needs n_joints >= 1, got {self.n_joints!r}")

    @staticmethod
    def of(state: np.ndarray) -> StateLayout:
        """The layout of states whose last axis has ``12 n`` entries.

        Parameters
        ----------
        state : ndarray, shape (..., 12 n)
            States.

        Returns
        -------
        StateLayout
            The layout for ``n`` joints.
        """
        return _layout(np.shape(state)[-1])

    @property
    def size(self) -> int:
        """Length ``12 n`` of a state vector."""
        return len(FIELDS) * self.n_joints

    def slice(self, name: Field) -> builtins.slice:
        """The entries of block ``name``.

        Parameters
        ----------
        name : str
            A name of :data:`FIELDS`.

        Returns
        -------
        slice
            Its ``n`` entries.
        """
        try:
            return self._slices[name]
        except (KeyError, TypeError):
            raise ValueError(f"unknown state block {name!r}; known: {', '.join(FIELDS)}") from None

    @cached_property
    def _slices(self) -> dict[str, builtins.slice]:
        n = self.n_joints
        return {name: slice(k * n, (k + 1) * n) for k, name in enumerate(FIELDS)}

    def get(self, state: np.ndarray, name: Field) -> np.ndarray:
        """Block ``name`` of states of any leading shape.

        Parameters
        ----------
        state : ndarray, shape (..., 12 n)
            States.
        name : str
            A name of :data:`FIELDS`.

        Returns
        -------
        ndarray, shape (..., n)
            A view of the block.
        """
        return np.asarray(state)[..., self.slice(name)]

    @property
    def bounded(self) -> int:
        """How many leading entries a divergence check bounds: motion and integrated errors.

        The last four blocks (the velocity energies and their integrals) are bookkeeping for a
        storage function and grow on every run: ``iint v^2`` grows linearly in time once
        ``int v^2`` has settled (about 30 rad^2 s^-1 after a start far from rest gives 1000
        within 35 s), so a bound on them would end stable runs. They are checked for finiteness.
        """
        return 8 * self.n_joints

    def escaped(self, state: np.ndarray, bound: float) -> np.ndarray:
        """Which runs left the bound: an entry not finite, or a bounded entry beyond ``bound``.

        Parameters
        ----------
        state : ndarray, shape (..., B, 12 n)
            States (any leading axes, for example time).
        bound : float
            Largest admissible absolute value of the entries of :attr:`bounded`.

        Returns
        -------
        ndarray of bool, shape (B,)
            True for the runs that left it at some point.
        """
        state = np.asarray(state)
        beyond = ~(np.abs(state[..., :self.bounded]) <= bound)
        bad = np.any(beyond, axis=-1) | ~np.all(np.isfinite(state), axis=-1)
        return bad.reshape(-1, bad.shape[-1]).any(axis=0)

    @property
    def positions(self) -> np.ndarray:
        """Indices of every joint angle: local, remote link and motor positions (``3 n``)."""
        return np.r_[self.slice("ql"), self.slice("qr"), self.slice("theta")]

    def channel(self, state: np.ndarray, channel: int) -> tuple[np.ndarray, np.ndarray]:
        """The signal a delay channel carries: its position and velocity blocks.

        Parameters
        ----------
        state : ndarray, shape (..., 12 n)
            States.
        channel : {0, 1}
            0: forward (``q_l, q_l'``); 1: backward (``theta, theta'``).

        Returns
        -------
        position, velocity : ndarray, shape (..., n)
            Views of the two blocks.
        """
        position, velocity = _CHANNELS[channel]
        return self.get(state, position), self.get(state, velocity)

    def pack(self, batch: int = 1, **blocks: np.ndarray | tuple[float, ...]) -> np.ndarray:
        """States assembled from named blocks (the others zero).

        Parameters
        ----------
        batch : int
            Number of states.
        **blocks : array_like, shape (n,) or (batch, n)
            Values of named blocks, for example ``ql=(0.1, 0.2)``.

        Returns
        -------
        ndarray, shape (batch, 12 n)
            The states.
        """
        state = np.zeros((batch, self.size))
        for name, values in blocks.items():
            state[:, self.slice(name)] = values  # type: ignore[arg-type]
        return state


@cache
def _layout(size: int) -> StateLayout:
    """The (shared, immutable) layout of states of ``size`` entries."""
    if size % len(FIELDS):
        raise ValueError(f"a state has {len(FIELDS)} n entries, got {size}")
    return StateLayout(size // len(FIELDS))
