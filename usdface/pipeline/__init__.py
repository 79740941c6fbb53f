"""Pipelines: commands that compose processors (called through :func:`usdface.registry.call`) and
the layers below them."""
