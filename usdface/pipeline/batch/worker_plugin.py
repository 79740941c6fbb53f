"""The Dask worker plugin of a batch (imported only where dask.distributed runs the shots)."""
from __future__ import annotations

import signal

from distributed.core import Status
from distributed.diagnostics.plugin import WorkerPlugin


class StopPlugin(WorkerPlugin):
    """usdface's stops in every worker of the batch's cluster, those joining later included:

    - SIGTERM/SIGHUP handlers (:func:`usdface.pipeline.stopping.install_worker_handlers`);
      ``ignore_interrupt`` for the command's own local cluster, whose workers leave Ctrl-C to it;
    - a worker that closes (its scheduler went away, its nanny restarts it, the cluster closes)
      first stops its running shots, which remove their partial work.
    """

    name = "usdface-stop-signals"
    idempotent = True  # a farm's scheduler keeps it from an earlier batch: not sent to its workers again

    def __init__(self, ignore_interrupt: bool = False):
        self.ignore_interrupt = ignore_interrupt

    def setup(self, worker) -> None:
        from ..stopping import install_worker_handlers

        install_worker_handlers(ignore_interrupt=self.ignore_interrupt)

    async def teardown(self, worker) -> None:
        if worker.status not in (Status.closing, Status.closing_gracefully, Status.closed):
            return  # the plugin is replaced, the worker goes on: its shots too
        from ..stopping import stop_shots

        await stop_shots(None, signal.SIGTERM)
