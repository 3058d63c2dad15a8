"""What a Dask worker process is set up with before it simulates campaign chunks.

Imported only where a Dask cluster runs a campaign (it needs ``dask[distributed]``).
"""

from __future__ import annotations

from typing import Any

from distributed import WorkerPlugin

__all__ = ["OneNumbaThread"]


class OneNumbaThread(WorkerPlugin):
    """Set numba to one thread in each worker process, once, when the worker starts.

    The workers of a campaign share the cores as processes (one single-threaded process per
    core), so a chunk's compiled integrator must not start threads of its own.
    ``NUMBA_NUM_THREADS`` is not set through Dask instead: its nanny would also set it in the
    client's process, where numba then refuses to compile once its threads run with another
    count.
    """

    name = "teleopkit-one-numba-thread"

    def setup(self, worker: Any) -> None:
        """Cap numba's threads of this worker process at one.

        Parameters
        ----------
        worker : distributed.Worker
            The worker starting (unused).
        """
        import numba

        numba.set_num_threads(1)
