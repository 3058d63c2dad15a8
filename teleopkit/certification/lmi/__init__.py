"""Lyapunov–Krasovskii LMIs on the linearisation at rest (method ``"lmi"``).

From the bottom up: :mod:`~teleopkit.certification.lmi.systems` writes the teleoperator as the
linear delay systems of :mod:`certify`; :mod:`~teleopkit.certification.lmi.workers` solves
independent LMIs on the local cores; :mod:`~teleopkit.certification.lmi.cells` remembers solved
cells; :mod:`~teleopkit.certification.lmi.cover` covers large sets of gains with cells;
:mod:`~teleopkit.certification.lmi.proof` packs a cover as a proof that can be re-checked; and
:mod:`~teleopkit.certification.lmi.verdict` turns them into a gain certificate (and verifies
one).
"""

__all__: list[str] = []  # the modules are the API; nothing is re-exported
