"""Campaign throughput on a local Dask cluster: 1 worker against 2 (or any list of counts).

Run: ``NUMBA_NUM_THREADS=1 python benchmarks/bench_campaign.py [--scenarios 10000]
[--workers 1,2] [--chunk 64] [--duration 40]``. Each worker count runs the same random campaign
of ``--scenarios`` episodes (the paper's teleoperator with 9 perturbed variants: joint stiffness
80/100/120 N m/rad times remote masses x0.8/1/1.2; delays drawn from the paper profile, constant,
sinusoidal and fast-switching; ``K_r`` in [2, 20], ``B_r`` in [30, 90]) from scratch on a fresh
LocalCluster of single-threaded worker processes, and prints one table: cluster start-up time,
campaign time (planning, simulation and writing of every chunk and of the final table), scenarios
per second, and the speed-up and parallel efficiency against the first worker count. The tables
of all runs are checked to be identical (apart from ``wall_time`` and ``chunk``). Results go to a
temporary directory that is deleted afterwards.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import pandas as pd

from teleopkit.robustness.campaign import local_cluster, run_campaign
from teleopkit.robustness.spec import CampaignSpec


def campaign_spec(scenarios: int, duration: float) -> CampaignSpec:
    """The benchmark's random campaign."""
    return CampaignSpec.from_dict({
        "mode": "random", "samples": scenarios, "seed": 2024, "duration": duration,
        "factors": {
            "joint_stiffness": [80.0, 100.0, 120.0],
            "remote_mass_scale": [0.8, 1.0, 1.2],
            "delay": ["paper", "constant:0.8", "sine:0.5:0.4:0.5", "switching:0:1:0.01"],
            "kr": {"uniform": [2.0, 20.0]},
            "br": {"uniform": [30.0, 90.0]},
        }})


def run_with(workers: int, spec: CampaignSpec, out: Path,
             chunk: int) -> tuple[dict[str, float], pd.DataFrame]:
    """Start a LocalCluster, run the campaign on it, and time both."""
    from distributed import Client

    start = time.perf_counter()
    with local_cluster(workers) as cluster, Client(cluster) as client:
        client.run(lambda: __import__("teleopkit.robustness.campaign"))  # import before timing
        ready = time.perf_counter()
        table = run_campaign(spec, out, client=client, chunk=chunk, resume=False)
        done = time.perf_counter()
    timing = {"workers": workers, "start-up, s": ready - start, "campaign, s": done - ready,
              "scenarios/s": len(table) / (done - ready)}
    return timing, table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", type=int, default=10_000, help="episodes per campaign")
    parser.add_argument("--workers", default="1,2", help="comma list of worker counts")
    parser.add_argument("--chunk", type=int, default=64, help="scenarios per Dask task")
    parser.add_argument("--duration", type=float, default=40.0, help="episode length, s")
    args = parser.parse_args()
    counts = [int(w) for w in args.workers.split(",")]
    spec = campaign_spec(args.scenarios, args.duration)
    print(f"{args.scenarios} scenarios of {args.duration:g} s, chunk {args.chunk}, "
          f"NUMBA_NUM_THREADS={os.environ.get('NUMBA_NUM_THREADS', 'unset')}, "
          f"{os.cpu_count()} cores")
    with tempfile.TemporaryDirectory() as tmp:
        runs = [run_with(w, spec, Path(tmp) / f"w{w}.parquet", args.chunk) for w in counts]
    tables = [table for _, table in runs]
    result = pd.DataFrame([timing for timing, _ in runs]).set_index("workers")
    base = result["scenarios/s"].iloc[0]
    result["speed-up"] = result["scenarios/s"] / base
    result["efficiency"] = result["speed-up"] / (result.index / result.index[0])
    print(result.round(3).to_string())
    same = all(t.drop(columns=["wall_time", "chunk"]).equals(
        tables[0].drop(columns=["wall_time", "chunk"])) for t in tables)
    diverged = int(tables[0]["diverged"].sum())
    print(f"identical rows across worker counts: {same}; diverged scenarios: {diverged}")


if __name__ == "__main__":
    main()
