"""Batch at scale: shot manifests, a content-addressed cache, resumable runs on dask.distributed.

>>> from usdface.batch import load_manifest, run_batch        # doctest: +SKIP
>>> summary = run_batch(load_manifest("shots.toml"), workers=2, resume=True)   # doctest: +SKIP
"""
from .cache import ContentCache, content_key
from .manifest import Manifest, Shot, load_manifest
from .runner import execute_shot, run_batch, shot_is_current

__all__ = ["ContentCache", "content_key", "Manifest", "Shot", "load_manifest", "run_batch", "execute_shot",
           "shot_is_current"]
