"""Peak memory of ``teleopkit evaluate`` and ``teleopkit reproduce`` (32 held-out scenarios).

    python benchmarks/bench_memory.py [--search]

Each command runs in a fresh process; its peak resident set size is read from the operating
system (``resource.getrusage(RUSAGE_CHILDREN)``, the largest child so far, so the commands run
from the smallest expected peak up). Rows: the shipped covered tuner (its comparators stored
with it), the paper's tuner, ``reproduce``, and with ``--search`` a policy without stored
comparators (``evaluate`` then searches the best static gains, the semi-active law and the
open-loop schedule: about four minutes).
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from importlib import resources
from pathlib import Path

from teleopkit.rl.policy import PRETRAINED, PRETRAINED_COVERED, GainPolicy


def peak(args: list[str]) -> tuple[float, float]:
    """Peak memory in MB (the largest child process so far) and wall time of one command."""
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "teleopkit.cli", *args], check=True,
                   capture_output=True)
    return (resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024,
            time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--search", action="store_true",
                        help="also a policy whose comparators must be searched")
    args = parser.parse_args()
    data = resources.files("teleopkit") / "data"
    with tempfile.TemporaryDirectory() as tmp, resources.as_file(data) as folder:
        rows = [("evaluate, paper's tuner", ["evaluate", "--policy", str(folder / PRETRAINED)]),
                ("evaluate, covered tuner",
                 ["evaluate", "--policy", str(folder / PRETRAINED_COVERED)]),
                ("reproduce", ["reproduce"])]
        if args.search:
            bare = GainPolicy.pretrained(PRETRAINED_COVERED)
            del bare.metadata["comparators"]
            bare.save(Path(tmp) / "bare.npz")
            rows.append(("evaluate, comparators searched",
                         ["evaluate", "--policy", str(Path(tmp) / "bare.npz")]))
        print("| command | peak memory [MB] | wall time [s] |\n|---|---|---|")
        for name, command in rows:
            memory, wall = peak([*command, "--out", str(Path(tmp) / name.replace(" ", "_"))])
            print(f"| {name} | {memory:.0f} | {wall:.1f} |", flush=True)


if __name__ == "__main__":
    main()
