"""Pipelines: the processors that compose others (`run`, `solve`, `report`, `batch`), calling them
only through the registry (:func:`usdface.registry.call`), and the shot commit."""
