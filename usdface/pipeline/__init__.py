"""Pipelines: commands that compose processors (`run`, `solve`, `report`, `batch`). They call
processors through :func:`usdface.registry.call`, never their internals, and may use the layers
below (usd, compute, io)."""
