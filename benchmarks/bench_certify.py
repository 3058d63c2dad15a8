"""Timing of the certify LMIs: solve time against state dimension and number of vertices,
bisection with DPP re-solves against rebuilding the cvxpy problem at every step, the
teleoperator's remote gains as enumerated vertices against full-block multipliers, and two-joint
cells posed on the kernel of the kinematic rows against the full descriptor relation.

Run: ``python benchmarks/bench_certify.py [--quick]``.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import time
from unittest import mock

import numpy as np
import pandas as pd

from certify import AffineUncertainty, Certificate, LinearDelaySystem, PolytopicDelaySystem
from certify.bisection import _bisect, _initial_guess
from certify.methods import get_method
from certify.solve import LMIProblem
from certify.system import as_polytope
from teleopkit.certification.gain_sets import GainBox, GainPolytope
from teleopkit.certification.lmi.systems import gain_set_system, lmi_certificate
from teleopkit.model.linearize import rest_systems
from teleopkit.model.params import TeleoperatorParams, paper_setup

RANK = 2
"""Rank of each delay matrix (a teleoperator transmits positions only: rank 2 for 2 joints)."""


def random_polytope(seed: int, n: int, m: int, vertices: int) -> PolytopicDelaySystem:
    """Random polytope, stable at zero delay, whose delays act through fixed outputs
    ``y_i = C_i x`` of rank ``RANK`` (only the gains ``B_i`` and ``A0`` vary over vertices)."""
    rng = np.random.default_rng(seed)
    r = min(RANK, n)
    outputs = [rng.normal(size=(r, n)) / np.sqrt(n) for _ in range(m)]
    while True:
        a0 = rng.normal(size=(n, n)) / np.sqrt(n) - 1.5 * np.eye(n)
        gains = [0.5 * rng.normal(size=(n, r)) for _ in range(m)]
        verts = [
            LinearDelaySystem(
                a0 + 0.05 * rng.normal(size=(n, n)),
                [
                    (b + 0.1 * rng.normal(size=(n, r))) @ c
                    for b, c in zip(gains, outputs, strict=True)
                ],
            )
            for _ in range(vertices)
        ]
        if all(np.linalg.eigvals(v.A0 + sum(v.A)).real.max() < -0.2 for v in verts):
            return PolytopicDelaySystem(tuple(verts))


def time_solve(system: PolytopicDelaySystem, method: str, h: float) -> dict[str, float]:
    t0 = time.perf_counter()
    problem = LMIProblem(system, get_method(method), None)
    t1 = time.perf_counter()
    problem.solve([h] * system.m)
    t2 = time.perf_counter()
    cert = problem.solve([h] * system.m)
    t3 = time.perf_counter()
    return {
        "build_s": t1 - t0,
        "first_solve_s": t2 - t1,
        "resolve_s": t3 - t2,
        "certified": cert.certified,
    }


def solve_table(dims: list[int], vertex_counts: list[int], methods: list[str]) -> pd.DataFrame:
    rows = []
    for method in methods:
        for n in dims:
            for k in vertex_counts:
                sys = random_polytope(n * 100 + k, n, 2, k)
                rows.append(
                    {"method": method, "n": n, "vertices": k, **time_solve(sys, method, 0.1)}
                )
                print("  done:", rows[-1], flush=True)
    return pd.DataFrame(rows)


class RebuildEveryStep:
    """Same interface as LMIProblem, but builds (and compiles) a fresh problem per solve."""

    def __init__(self, system: PolytopicDelaySystem, method: str) -> None:
        self.system, self.method = system, get_method(method)

    def solve(self, h: np.ndarray) -> Certificate:
        return LMIProblem(self.system, self.method, None).solve(h)


def bisection_table(dims: list[int], methods: list[str]) -> pd.DataFrame:
    rows = []
    for method in methods:
        for n in dims:
            sys = as_polytope(random_polytope(7 + n, n, 2, 1).vertices[0])
            w = np.ones(sys.m)
            guess = _initial_guess(sys)
            out = {"method": method, "n": n}
            for label, problem in (
                ("dpp", LMIProblem(sys, get_method(method), None)),
                ("rebuild", RebuildEveryStep(sys, method)),
            ):
                t0 = time.perf_counter()
                cert = _bisect(problem, w, guess, 1e3, 1e-3)
                out[f"{label}_s"] = time.perf_counter() - t0
                out[f"{label}_h"] = cert.margin
            out["speedup"] = out["rebuild_s"] / out["dpp_s"]
            rows.append(out)
    return pd.DataFrame(rows)


def first_joint(params: TeleoperatorParams) -> TeleoperatorParams:
    """The teleoperator's first joint alone (every per-joint tuple cut to its first entry)."""
    def cut(part: object) -> object:
        return dataclasses.replace(part, **{k: v[:1] for k, v in vars(part).items()
                                           if isinstance(v, tuple)})
    return dataclasses.replace(params, **{f.name: cut(getattr(params, f.name))
                                          for f in dataclasses.fields(params)
                                          if dataclasses.is_dataclass(getattr(params, f.name))})


def with_rates(system: PolytopicDelaySystem, rate: float) -> PolytopicDelaySystem:
    """The same polytope with every uncertain parameter's rate bounded by ``rate``."""
    unc = system.uncertainty
    assert unc is not None
    return PolytopicDelaySystem(system.vertices, system.variation,
                                AffineUncertainty(unc.directions, unc.points, unc.names, rate))


def gain_cases(quick: bool) -> list[tuple[str, PolytopicDelaySystem, PolytopicDelaySystem]]:
    """(case, enumerated gain vertices, multiplier form) with one configuration each."""
    cases = [("1 joint", first_joint(paper_setup()), GainBox.uniform((5.0, 10.0), (30.0, 60.0), 1))]
    if not quick:
        cases.append(("2 joints", paper_setup(), GainBox.uniform((5.0, 10.0), (30.0, 60.0), 2)))
    out = []
    for name, params, box in cases:
        polytope = GainPolytope.from_box(box)
        multiplier = gain_set_system(params, polytope, "switching")
        one = PolytopicDelaySystem(multiplier.vertices[:1], "frozen", multiplier.uncertainty)
        enumerated = PolytopicDelaySystem(
            tuple(rest_systems(params, action)[0] for action in polytope.vertices()), "switching")
        out.append((name, enumerated, one))
    return out


def gain_table(quick: bool) -> pd.DataFrame:
    rows = []
    for name, enumerated, multiplier in gain_cases(quick):
        forms = [("vertices", enumerated), ("multiplier", multiplier)]
        if name == "1 joint":  # two joints widen Delta from 4 to 52: over 30 minutes a solve
            forms.append(("multiplier, rate 10/s", with_rates(multiplier, 10.0)))
        for form, system in forms:
            timing = time_solve(system, "rcc", 1.0)
            rows.append({"case": name, "form": form, "LMIs": len(system.vertices), **timing})
            print("  done:", rows[-1], flush=True)
    return pd.DataFrame(rows)


KERNEL_CELLS = (((5, 10), (30, 60), 1.3), ((5, 10), (30, 60), 1.5), ((1, 13.25), (1, 38.25), 0.5),
                ((25, 50), (75, 150), 0.3), ((1, 25), (1, 75), 0.2))
"""Two-joint cells of the paper's gain box (``K_r``, ``B_r`` of both joints, delay bound): cells
of the covers, certified and not."""


def kernel_table() -> pd.DataFrame:
    """Verdict and time of frozen-gain cells, on the kernel of ``q' = v`` and on the full relation.

    The full relation is what the LMIs were without eliminating any row: every row multiplied
    by the Finsler slack.
    """
    rows = []
    for kr, br, h in KERNEL_CELLS:
        polytope = GainPolytope.from_box(GainBox.uniform(kr, br, n_joints=2))
        row: dict[str, object] = {"K_r": kr, "B_r": br, "h": h}
        for form, rows_of in (("kernel", contextlib.nullcontext()),
                              ("full relation", mock.patch("certify.system_data.eliminable_rows",
                                                           lambda *args: ()))):
            with rows_of:
                start = time.perf_counter()
                cert = lmi_certificate(paper_setup(), polytope, h, h)
            row[f"{form} s"] = time.perf_counter() - start
            row[f"{form} certified"] = cert.certified
        rows.append(row)
        print("  done:", row, flush=True)
    return pd.DataFrame(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="small sizes only")
    args = parser.parse_args()
    dims = [2, 4, 6] if args.quick else [2, 4, 8, 12]
    vertex_counts = [1, 2, 4] if args.quick else [1, 4, 16]
    pd.set_option("display.width", 120)
    pd.set_option("display.float_format", "{:.3f}".format)
    print(f"LMI solve time (two fast-varying delays of rank {RANK}, h = 0.1)")
    print(solve_table(dims, vertex_counts, ["rcc", "io"]).to_string(index=False))
    print("\nBisection (rtol 1e-3): DPP re-solve vs rebuilding the problem each step")
    print(bisection_table(dims[:3], ["rcc", "io"]).to_string(index=False))
    print("\nRemote gains switching in K_r in [5, 10], B_r in [30, 60] per joint, one "
          "configuration, h = 1 s: vertices against multipliers (switching, or with a\n"
          "rate-bounded storage)")
    print(gain_table(args.quick).to_string(index=False))
    print("\nTwo-joint cells of the paper's box (frozen gains, RCC, one process): on the kernel of "
          "the\nkinematic rows q' = v against the full descriptor relation")
    print(kernel_table().to_string(index=False))


if __name__ == "__main__":
    main()
