"""Wall time of ``teleopkit certify --method lmi`` on two-joint boxes, before and after.

Each case runs the command line in a fresh process (imports included) with the cache off, then
once more with a cache to time a repeated question. With ``--before REV`` the same cases run on
a git worktree of that revision too, in the same session, so the ratio compares like with like.

Run: ``python benchmarks/bench_certify_cli.py [--before REV] [--cases small,paper]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
CASES = {
    "small": ["--kr", "5:10", "--br", "30:60"],
    "paper": ["--kr", "1:50", "--br", "1:150"],
}


def run(source: Path, args: list[str], env: dict[str, str]) -> tuple[float, dict]:
    """Seconds and the JSON certificate of one ``teleopkit certify`` process on ``source``."""
    command = [sys.executable, "-m", "teleopkit.cli", "certify", *args, "--method", "lmi",
               "--json"]
    start = time.perf_counter()
    # run from the checkout measured: ``python -m`` puts the working directory first on the path
    done = subprocess.run(command, capture_output=True, text=True, check=False, cwd=source,
                          env={**env, "PYTHONPATH": str(source)})
    elapsed = time.perf_counter() - start
    if done.returncode not in (0, 1):
        raise RuntimeError(f"{' '.join(command)} failed: {done.stderr.strip()}")
    return elapsed, json.loads(done.stdout)


def summary(certificate: dict) -> str:
    """Verdict, offered polytope, margin and margin limit of a certificate, in a few words."""
    details = certificate.get("details", {})
    verdict = "certified" if certificate["certified"] else "not certified"
    polytope = ("" if certificate["certified"] else
                f", cut s = {float(details.get('polytope_scale', 1.0)):g}"
                f"{' proven' if certificate.get('polytope_certified') else ''}")
    limit = (f", limit {float(details['margin_limit']):.4g} s" if "margin_limit" in details
             else "")
    return (f"{verdict}{polytope}, margin {float(certificate['delay_margin']):.4g} s"
            f"{limit}")


def measure(label: str, source: Path, cases: list[str], cache: bool) -> list[dict]:
    """One row per case: wall time, answer and (with ``cache``) the time of a repeat."""
    rows = []
    off = ["--no-cache"] if cache else []  # revisions before the cache have no such option
    with tempfile.TemporaryDirectory() as folder:
        env = {**os.environ, "TELEOPKIT_CACHE": folder}
        for case in cases:
            seconds, cert = run(source, [*CASES[case], *off], env)
            row = {"version": label, "case": " ".join(CASES[case]), "seconds": seconds,
                   "answer": summary(cert)}
            if cache:
                run(source, CASES[case], env)  # fills the cache
                row["repeat, cached s"] = run(source, CASES[case], env)[0]
            rows.append(row)
            print(row, flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", help="git revision to compare with (a temporary worktree)")
    parser.add_argument("--cases", default="small,paper", help="comma-separated: small, paper")
    args = parser.parse_args()
    cases = args.cases.split(",")
    rows = measure("this checkout", ROOT, cases, cache=True)
    if args.before:
        with tempfile.TemporaryDirectory() as folder:
            tree = Path(folder) / "before"
            subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree),
                            args.before], check=True, capture_output=True)
            try:
                rows += measure(args.before, tree, cases, cache=False)
            finally:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force",
                                str(tree)], check=False, capture_output=True)
    print(pd.DataFrame(rows).round(1).to_string(index=False))


if __name__ == "__main__":
    main()
