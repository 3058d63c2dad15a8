"""What a Dask worker process is set up with before it simulates campaign chunks.

Imported only where a Dask cluster runs a campaign (it needs ``dask[distributed]``).
"""

from __future__ import annotations

import contextlib
import logging
import signal
from typing import Any

from distributed import WorkerPlugin

__all__ = ["WorkerSetup"]


class WorkerSetup(WorkerPlugin):
    """Set up each worker process once, when it starts: one numba thread, Ctrl-C left alone.

    The workers of a campaign share the cores as processes (one single-threaded process per
    core), so a chunk's compiled integrator must not start threads of its own.
    ``NUMBA_NUM_THREADS`` is not set through Dask instead: its nanny would also set it in the
    client's process, where numba then refuses to compile once its threads run with another
    count. A Ctrl-C in the terminal reaches every process of the group; the workers ignore it
    (the client's process stops the campaign and shuts the cluster down) instead of each
    printing a traceback, and the chunks cancelled by that shutdown are not reported as
    warnings (``distributed.worker.state_machine``; errors still are).
    """

    name = "teleopkit-worker-setup"

    def setup(self, worker: Any) -> None:
        """Cap numba's threads of this worker process at one; ignore SIGINT and cancellations.

        Parameters
        ----------
        worker : distributed.Worker
            The worker starting (unused).
        """
        import numba

        numba.set_num_threads(1)
        with contextlib.suppress(ValueError):  # only the main thread may set a handler
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        logging.getLogger("distributed.worker.state_machine").setLevel(logging.ERROR)
