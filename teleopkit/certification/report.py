"""Human-readable text for certificates (the default output of ``teleopkit certify``)."""

from __future__ import annotations

from collections.abc import Sequence

from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.nuno.guarantee import Start
from teleopkit.model.params import InitialState, PlanarArm, TeleoperatorParams
from teleopkit.model.records import plant_record
from teleopkit.setup.reading import listed

__all__ = ["CLASSES_PAGE", "certificate_table"]

CLASSES_PAGE = ('what each gain class covers, and what the safety layer enforces: the '
                '"What is certified" page of the teleopkit documentation')
"""The closing line of :func:`certificate_table`."""


def _range(pair: tuple[float, float]) -> str:
    return f"[{pair[0]:g}, {pair[1]:g}]"


def _polygon(cert: GainCertificate, joint: int) -> str:
    vertices = cert.polytope.joint_vertices(joint)
    if vertices.size == 0:
        return "empty"
    return " ".join(f"({k:.4g}, {b:.4g})" for k, b in vertices)


def certificate_table(results: Sequence[GainCertificate], footer: bool = True,
                      start: InitialState | Start | None = None) -> str:
    """Format one or more certificates of the same question as aligned text.

    Parameters
    ----------
    results : sequence of GainCertificate
        Certificates (for example one per method).
    footer : bool
        End with where the gain classes are explained.
    start : InitialState, StartSpec or StartMix, optional
        The start a scheduled class's guarantee is stated from
        (:meth:`~teleopkit.certification.gain_certificate.GainCertificate.guarantee`; the
        paper's by default, and none is stated for another number of joints).

    Returns
    -------
    str
        A block of text: the question once, then verdict, margin, admissible set, violation and
        assumptions per certificate, and where the gain classes are explained.
    """
    first = results[0]
    box = first.box
    lines = [
        f"delay bounds      T_l* = {first.delay_bounds[0]:g} s, T_r* = {first.delay_bounds[1]:g} s",
        *(f"gain box joint {i + 1}  K_r in {_range(box.kr[i])}, B_r in {_range(box.br[i])}"
          for i in range(box.n_joints)),
    ]
    for cert in results:
        verdict = "CERTIFIED" if cert.certified else "NOT CERTIFIED"
        lines += ["", f"[{cert.method}] {verdict} for {cert.gain_variation} gains",
                  f"  covers          {cert.variation.describe()}",
                  f"  delay margin    {cert.delay_margin:.4g} s (largest common T* for the box)"
                  if "partial" not in cert.details else
                  "  delay margin    not searched (the set is proven at the delay bounds above)"]
        if "margin_limit" in cert.details:
            limit, vertex = cert.details["margin_limit"], cert.details["margin_limit_vertex"]
            lines.append(f"  margin limit    {limit:.4g} s (certified at the gain vertex {vertex} "
                         "alone)")
        label = "admissible" if cert.polytope_certified else "uncertified"
        lines += [f"  {f'{label} j{i + 1}':<16}{_polygon(cert, i)}" for i in range(box.n_joints)]
        allowed = cert.scheduled_set
        if allowed is not None:
            shape = allowed.shape
            lines.append("  common shape    " + ", ".join(
                f"K_r{i + 1} = {s / shape[0]:g} K_r1" for i, s in enumerate(shape) if i))
        guarantee = (cert.guarantee(start) if start is not None or box.n_joints == 2
                     else None)
        if guarantee is not None:
            lines.append(f"  guarantees      {guarantee.describe()}")
        if cert.violation:
            lines.append(f"  violation       {cert.violation}")
        if "partial" in cert.details:
            lines.append(f"  partial         {cert.details['partial']}")
        lines += [f"  assumes         {text}" for text in cert.assumptions]
    return "\n".join([*lines, "", CLASSES_PAGE] if footer else lines)


def plant_text(params: TeleoperatorParams) -> str:
    """The plant a certificate answers for, in one line (arms, joints, gains, fingerprint).

    Parameters
    ----------
    params : TeleoperatorParams
        The teleoperator.

    Returns
    -------
    str
        For example ``local arm l [0.38, 0.38] m, m [0.5, 0.35] kg; remote arm ...;
        S_r [100, 100], J_r [0.3, 0.3]; K_l [25, 25], B_l [10, 10]; K_s 10, K_d 2
        (fingerprint ...)``.
    """
    def arm(name: str, value: PlanarArm) -> str:
        extra = "" if value.com is None else f", com {listed(value.com)} m"
        extra += "" if value.inertia is None else f", I {listed(value.inertia)} kg m^2"
        return f"{name} arm l {listed(value.lengths)} m, m {listed(value.masses)} kg{extra}"

    record = plant_record(params)
    return (f"{arm('local', params.local_arm)}; {arm('remote', params.remote_arm)}; "
            f"S_r {listed(params.joints.stiffness)}, J_r {listed(params.joints.rotor_inertia)}; "
            f"K_l {listed(params.local_gains.stiffness)}, B_l "
            f"{listed(params.local_gains.damping)}; K_s {params.operator.stiffness:g}, "
            f"K_d {params.operator.damping:g} (plant fingerprint {record['fingerprint']})")
