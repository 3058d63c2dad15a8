"""Robustness campaigns: thousands of scenarios, one tidy table, on Dask.

A campaign is a :class:`CampaignSpec`: *factors* (delay profile, delay scale, operator reference
gain, remote gains, perturbed teleoperator parameters, seed) crossed as a full grid or sampled at
random, the episode settings and a divergence threshold. :func:`run_campaign` expands it into one
row per scenario (:meth:`CampaignSpec.expand`), cuts the rows into chunks, simulates each chunk on
a Dask cluster as batches of the :class:`~teleopkit.sim.simulator.Simulator` (one batch per distinct
teleoperator in the chunk, not one process per scenario), writes every finished chunk as its own
Parquet file and returns the assembled table: the factor columns plus RMS / IAE / maximum of the
tracking and damping errors, the peak position, a growth ratio, a ``diverged`` flag and the wall
time. A campaign that was interrupted resumes: only the chunks whose files are missing run again.

The parts: :mod:`~teleopkit.robustness.factors` (what may vary), :mod:`~teleopkit.robustness.spec`
(the spec format), :mod:`~teleopkit.robustness.chunks` (simulating a chunk),
:mod:`~teleopkit.robustness.store` (the chunk files) and this module (scheduling on Dask).
Divergence is the criterion of :mod:`teleopkit.sim.divergence`.
"""

from __future__ import annotations

import contextlib
import logging
import os
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from teleopkit.delays.profiles import TraceDelay
from teleopkit.files import atomic_write, run_lock
from teleopkit.robustness.chunks import (
    ChunkTask,
    check_row_delays,
    check_steps,
    plan_chunks,
    simulate_chunk,
)
from teleopkit.robustness.factors import factor_dtypes
from teleopkit.robustness.spec import CampaignSpec
from teleopkit.robustness.store import ChunkStore

if TYPE_CHECKING:
    from distributed import Client

__all__ = ["CampaignInterrupted", "local_cluster", "run_campaign"]


def _tasks(spec: CampaignSpec, scenarios: pd.DataFrame, chunks: Sequence[np.ndarray],
           todo: Iterable[int]) -> list[ChunkTask]:
    indexed = scenarios.set_index("scenario", drop=False)
    policies = spec.policies()
    tasks = []
    for k in todo:
        rows = indexed.loc[chunks[k]].reset_index(drop=True)
        used = {c: policies[c] for c in rows["controller"].unique() if c in policies}
        tasks.append(ChunkTask(k, rows, spec.duration, spec.dt, spec.control_period,
                               spec.divergence_radius, used, spec.setup))
    return tasks


def _run_synchronous(tasks: Sequence[ChunkTask], traces: Mapping[str, TraceDelay],
                     done: Callable[[pd.DataFrame], None]) -> None:
    """Run the chunks one after the other in this process (no Dask needed)."""
    for task in tasks:
        done(simulate_chunk(task, traces))


class CampaignInterrupted(RuntimeError):
    """The cluster lost a chunk for good (its workers kept dying); resume to finish."""


def _run_distributed(tasks: Sequence[ChunkTask], traces: Mapping[str, TraceDelay],
                     client: Client, done: Callable[[pd.DataFrame], None]) -> None:
    from distributed import KilledWorker, as_completed

    from teleopkit.robustness.dask_workers import WorkerSetup

    client.register_plugin(WorkerSetup())
    shared = client.scatter(dict(traces), broadcast=True) if traces else {}  # sent once
    futures = [client.submit(simulate_chunk, task, shared, pure=False) for task in tasks]
    try:
        for future in as_completed(futures):
            done(future.result())
    except KilledWorker as error:
        raise CampaignInterrupted(
            f"campaign stopped: {error}; the finished chunks are kept, run again with "
            "resume=True (teleopkit campaign --resume) to finish it") from None
    finally:
        client.cancel(futures)


def _usable_cores() -> int:
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def local_cluster(workers: int | None = None) -> Any:
    """A Dask LocalCluster of single-threaded worker processes on this machine.

    What :func:`run_campaign` starts when no client is given; start one yourself to run several
    campaigns on the same workers (``Client(local_cluster())``).

    Parameters
    ----------
    workers : int, optional
        Worker processes; the number of usable cores by default.

    Returns
    -------
    distributed.LocalCluster
        Processes with one thread each and no dashboard (with Dask's one-thread defaults for
        OpenMP, MKL and OpenBLAS); every worker runs numba on one thread
        (:class:`~teleopkit.robustness.dask_workers.WorkerSetup`, set once when a campaign
        starts on it).
    """
    from distributed import LocalCluster

    count = workers if workers is not None else _usable_cores()
    return LocalCluster(n_workers=count, threads_per_worker=1, processes=True,
                        dashboard_address=None)


def _execute(tasks: Sequence[ChunkTask], traces: Mapping[str, TraceDelay],
             client: Client | str | None, workers: int | None,
             done: Callable[[pd.DataFrame], None]) -> None:
    """Run the tasks on the chosen scheduler, handing each finished chunk to ``done``."""
    if client == "synchronous":
        _run_synchronous(tasks, traces, done)
        return
    try:
        from distributed import Client
    except ModuleNotFoundError:
        raise ModuleNotFoundError("campaigns on a cluster need dask[distributed]: pip install "
                                  "'teleopkit[campaign]' (or use --scheduler synchronous)"
                                  ) from None
    if client is None:
        with local_cluster(workers) as cluster, Client(cluster) as local, _quiet_on_interrupt():
            _run_distributed(tasks, traces, local, done)
    elif isinstance(client, str):
        with Client(client) as remote, _quiet_on_interrupt():
            _run_distributed(tasks, traces, remote, done)
    else:
        with _quiet_on_interrupt():
            _run_distributed(tasks, traces, client, done)


@contextlib.contextmanager
def _quiet_on_interrupt() -> Iterator[None]:
    """On Ctrl-C, silence Dask's logs and warnings while the cluster shuts down.

    Entered inside the cluster's and the client's blocks, so that it acts before they close.
    """
    try:
        yield
    except KeyboardInterrupt:
        for name in ("distributed", "tornado", "asyncio"):
            logging.getLogger(name).setLevel(logging.CRITICAL)
        warnings.simplefilter("ignore")
        raise


def _progress(total: int, enabled: bool) -> Any:
    from tqdm import tqdm

    return tqdm(total=total, unit="scenario", disable=not enabled, leave=False)


def _load_spec(spec: CampaignSpec | Mapping[str, Any] | str | Path) -> CampaignSpec:
    if isinstance(spec, CampaignSpec):
        return spec
    if isinstance(spec, Mapping):
        return CampaignSpec.from_dict(spec)
    return CampaignSpec.from_file(spec)


def _check_output(out: str | Path) -> Path:
    out = Path(out)
    if out.suffix.lower() not in (".parquet", ".csv"):
        raise ValueError(f"campaign output {out} must end in .parquet or .csv")
    if out.is_dir():
        raise ValueError(f"campaign output {out} is a directory")
    return out


def _write_table(table: pd.DataFrame, out: Path) -> None:
    if out.suffix.lower() == ".csv":
        atomic_write(out, lambda tmp: table.to_csv(tmp, index=False))
    else:
        atomic_write(out, lambda tmp: table.to_parquet(tmp, index=False))


def run_campaign(spec: CampaignSpec | Mapping[str, Any] | str | Path, out: str | Path,
                 client: Client | str | None = None, chunk: int = 64, resume: bool = True,
                 workers: int | None = None, progress: bool = False) -> pd.DataFrame:
    """Run a campaign on Dask and return (and save) one row per scenario.

    Parameters
    ----------
    spec : CampaignSpec, mapping, str or Path
        The campaign, its plain data, or a YAML / JSON / TOML file.
    out : str or Path
        Result table, ``.parquet`` or ``.csv``. Finished chunks are kept as Parquet files in the
        directory ``<out>.chunks`` (with a manifest of the spec), so that a rerun resumes.
    client : distributed.Client, str or None
        ``None``: a LocalCluster of ``workers`` single-threaded processes on this machine, made
        and closed here; a scheduler address (``"tcp://host:8786"``): that cluster (the workers
        need teleopkit installed); a ``distributed.Client``: used as it is; ``"synchronous"``:
        Dask's synchronous scheduler in this process (debugging, tests).
    chunk : int
        Scenarios per task (simulated as batches of the simulator).
    resume : bool
        Keep the chunk files of an earlier run of the same spec and chunk size and run only the
        missing chunks; with ``False`` start afresh (deleting earlier chunk files).
    workers : int, optional
        Worker processes of the default LocalCluster; the number of usable cores by default.
    progress : bool
        Show a progress bar (standard error).

    Returns
    -------
    pandas.DataFrame
        One row per scenario, sorted by ``scenario``: ``scenario``, ``chunk``, the factor columns
        of :data:`FACTORS`, ``G_1, G_2`` (operator reference gains), ``delay_bound`` and
        :data:`METRIC_COLUMNS`.

    Raises
    ------
    ValueError
        A bad spec, output path or chunk size, a plant or gain the step cannot integrate stably
        (:func:`~teleopkit.robustness.chunks.check_steps`), a row whose delays reach the run's
        length (:func:`~teleopkit.robustness.chunks.check_row_delays`), or chunk files of
        another campaign in the way.
    CampaignInterrupted
        The cluster gave up on a chunk (see Notes); the finished chunks are kept.

    Notes
    -----
    If a Dask worker process dies mid-campaign, Dask reruns the chunks it held on the other (or
    restarted) workers and the table is unchanged; only a chunk whose workers die more than
    ``distributed.scheduler.allowed-failures`` times (3 by default) stops the run with
    :class:`CampaignInterrupted`, and a rerun with ``resume=True`` then runs only the chunks
    missing from ``<out>.chunks``.
    """
    spec = _load_spec(spec)
    out = _check_output(out)
    scenarios = spec.expand()
    check_steps(scenarios, spec.dt, spec.control_period, spec.setup.params)
    check_row_delays(scenarios, spec.duration, spec.setup, spec.traces())
    chunks = plan_chunks(scenarios, chunk)
    store = ChunkStore(out)
    with run_lock(out.with_name(out.name + ".lock"), str(out)), store.kept_if_used():
        store.prepare({"fingerprint": spec.fingerprint(), "chunk": int(chunk),
                       "scenarios": len(scenarios), "spec": spec.to_dict()}, resume)
        tables = {k: store.load(k, ids) for k, ids in enumerate(chunks)} if resume else {}
        todo = [k for k in range(len(chunks)) if tables.get(k) is None]
        with _progress(len(scenarios), progress) as bar:
            bar.update(len(scenarios) - sum(len(chunks[k]) for k in todo))

            def done(table: pd.DataFrame) -> None:
                k = int(table["chunk"].iloc[0])
                store.save(k, table)
                tables[k] = table
                bar.update(len(table))

            if todo:
                _execute(_tasks(spec, scenarios, chunks, todo), spec.traces(), client,
                         workers, done)
        table = _assemble([tables[k] for k in range(len(chunks))], len(scenarios))
        _write_table(table, out)
    return table


def _assemble(parts: Sequence[pd.DataFrame | None], size: int) -> pd.DataFrame:
    """Concatenate the chunks; check one row per scenario."""
    table = pd.concat(parts, ignore_index=True).sort_values("scenario", ignore_index=True)
    table = table.astype(factor_dtypes())
    if not np.array_equal(table["scenario"].to_numpy(), np.arange(size)):
        raise RuntimeError("campaign table is incomplete or has duplicate scenarios")
    return table
