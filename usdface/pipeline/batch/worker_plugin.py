"""The Dask worker plugin of a batch (imported only where dask.distributed runs the shots)."""
from __future__ import annotations

from distributed.diagnostics.plugin import WorkerPlugin


class StopPlugin(WorkerPlugin):
    """usdface's SIGTERM/SIGHUP handlers (:func:`usdface.pipeline.stopping.install_worker_handlers`)
    in every worker of the batch's cluster, those joining later included; ``ignore_interrupt``
    for the command's own local cluster, whose workers leave Ctrl-C to the command."""

    name = "usdface-stop-signals"

    def __init__(self, ignore_interrupt: bool = False):
        self.ignore_interrupt = ignore_interrupt

    def setup(self, worker) -> None:
        from ..stopping import install_worker_handlers

        install_worker_handlers(ignore_interrupt=self.ignore_interrupt)
