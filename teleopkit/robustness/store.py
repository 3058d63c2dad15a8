"""Where a campaign keeps its finished chunks: one Parquet file each, and a manifest."""

from __future__ import annotations

import contextlib
import json
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from teleopkit.files import atomic_write

__all__ = ["ChunkStore"]


class ChunkStore:
    """Chunk files ``chunk-000000.parquet`` and a manifest in ``<out>.chunks/``.

    Parameters
    ----------
    out : Path
        The campaign's result table; the chunks live next to it.
    """

    def __init__(self, out: Path) -> None:
        self.dir = out.with_name(out.name + ".chunks")

    def path(self, chunk: int) -> Path:
        """The file of chunk ``chunk``.

        Parameters
        ----------
        chunk : int
            Chunk id.

        Returns
        -------
        Path
            ``<out>.chunks/chunk-NNNNNN.parquet``.
        """
        return self.dir / f"chunk-{chunk:06d}.parquet"

    @contextlib.contextmanager
    def kept_if_used(self) -> Iterator[None]:
        """Remove the directory again if the block fails before any chunk is kept in it.

        Yields
        ------
        None
            While the block runs.
        """
        existed = self.dir.exists()
        try:
            yield
        except BaseException:
            if not existed and not self.has_chunks():
                shutil.rmtree(self.dir, ignore_errors=True)
            raise

    def has_chunks(self) -> bool:
        """Whether finished chunks of an earlier run are kept here."""
        return any(self.dir.glob("chunk-*.parquet"))

    def prepare(self, manifest: dict[str, Any], resume: bool) -> None:
        """Create the directory; check (resume) or reset (no resume) what is there.

        Parameters
        ----------
        manifest : dict
            What identifies the campaign (spec fingerprint, chunk size, ...).
        resume : bool
            Keep chunks of the same manifest; otherwise delete every chunk file.
        """
        self.dir.mkdir(parents=True, exist_ok=True)
        path = self.dir / "manifest.json"
        if resume and path.exists():
            try:
                old = json.loads(path.read_text())
            except (OSError, ValueError):
                old = None
            if old != json.loads(json.dumps(manifest)):
                raise ValueError(f"{self.dir} holds chunks of another campaign or chunk size; "
                                 "use another output or delete it")
            return
        for stale in self.dir.glob("chunk-*.parquet"):
            stale.unlink()
        atomic_write(path, lambda tmp: tmp.write_text(json.dumps(manifest, indent=2)))

    def load(self, chunk: int, ids: np.ndarray) -> pd.DataFrame | None:
        """The chunk's table if its file exists, is readable and holds exactly ``ids``.

        Parameters
        ----------
        chunk : int
            Chunk id.
        ids : ndarray
            The scenario ids the chunk must hold.

        Returns
        -------
        pandas.DataFrame or None
            The table, or None when it must run (again).
        """
        path = self.path(chunk)
        if not path.exists():
            return None
        try:
            table = pd.read_parquet(path)
        except ImportError:
            raise
        except Exception:  # a damaged file (pyarrow raises its own error classes): run again
            return None
        if "scenario" not in table or not np.array_equal(table["scenario"].to_numpy(), ids):
            return None
        return table

    def save(self, chunk: int, table: pd.DataFrame) -> None:
        """Write a finished chunk atomically.

        Parameters
        ----------
        chunk : int
            Chunk id.
        table : pandas.DataFrame
            Its result rows.
        """
        atomic_write(self.path(chunk), lambda tmp: table.to_parquet(tmp, index=False))
