"""The closed form of Nuño et al. (method ``"nuno"``), on the nonlinear teleoperator.

:mod:`~teleopkit.certification.nuno.condition` is the per-joint condition
``4 B_l B_r >= (T_l* + T_r*)^2 K_l K_r`` for constant gains: its half-planes, the admissible
polytope of a box, the delay margins and the frozen-gain certificate.
:mod:`~teleopkit.certification.nuno.lyapunov` is the Lyapunov–Krasovskii storage behind the
scheduled classes and its value along a run; :mod:`~teleopkit.certification.nuno.scheduled`
turns it into the certificates of ``scheduled:L`` and ``tank``.
"""

__all__: list[str] = []  # the modules are the API; nothing is re-exported
