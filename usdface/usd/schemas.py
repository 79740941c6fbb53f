"""usdface's codeless USD schemas: registration in this process.

The schema source is ``schemas/usdFace/schema.usda``; ``usdGenSchema`` (from usd-core, needs
jinja2) writes ``generatedSchema.usda`` and ``plugInfo.json`` beside it, and this module copies
them into the package (``usdface/resources/usdFace``) so wheels carry them.

``import usdface`` registers them (:func:`usdface.register_schemas`). Registration must happen before the first stage with
prims is opened in the process (USD builds its schema registry once); DCCs import their own pxr
first, so for them put :func:`plugin_path` on ``PXR_PLUGINPATH_NAME`` before the DCC starts.
"""
from __future__ import annotations

from pathlib import Path

from .. import API_SCHEMAS, SCHEMA_RESOURCES as _PACKAGE_RESOURCES  # noqa: F401  (named once, in the package)
from ..errors import SchemaRegistrationError

MULTIPLE_APPLY = {"FaceRegionAPI", "FaceDistanceMatrixAPI"}
_SOURCE_DIR = Path(__file__).resolve().parents[2] / "schemas" / "usdFace"
_GENERATED = ("generatedSchema.usda", "plugInfo.json")


def plugin_path() -> Path:
    """Folder holding usdface's plugInfo.json: the value to put on PXR_PLUGINPATH_NAME."""
    return _PACKAGE_RESOURCES


def register() -> bool:
    """Register usdface's schemas with USD in this process (``import usdface`` did); True when they
    are usable (see :func:`usdface.register_schemas`)."""
    from .. import register_schemas

    return register_schemas()


def require_registered() -> None:
    """Raise SchemaRegistrationError if the schemas are not usable in this process."""
    if not register():
        raise SchemaRegistrationError(
            "usdface schemas are not registered in this process; set PXR_PLUGINPATH_NAME="
            f"{plugin_path()} before starting Python, or import usdface before opening any stage"
        )
