"""usdface's codeless USD schemas: registration in this process.

The schema source is ``schemas/usdFace/schema.usda``; ``usdGenSchema`` (from usd-core, needs
jinja2) writes ``generatedSchema.usda`` and ``plugInfo.json`` beside it, and this module copies
them into the package (``usdface/resources/usdFace``) so wheels carry them.

``import usdface`` calls :func:`register`. Registration must happen before the first stage with
prims is opened in the process (USD builds its schema registry once); DCCs import their own pxr
first, so for them put :func:`plugin_path` on ``PXR_PLUGINPATH_NAME`` before the DCC starts.
"""
from __future__ import annotations

import warnings
from pathlib import Path

from ..errors import SchemaRegistrationError

#: the applied API schema type names usdface defines
#: TfType name -> the token used with ApplyAPI / apiSchemas
API_SCHEMAS = {
    "UsdFaceMarkerSetAPI": "FaceMarkerSetAPI",
    "UsdFaceMarkerBindingAPI": "FaceMarkerBindingAPI",
    "UsdFaceRegionAPI": "FaceRegionAPI",
    "UsdFaceDistanceMatrixAPI": "FaceDistanceMatrixAPI",
    "UsdFaceTransferAPI": "FaceTransferAPI",
    "UsdFaceMuscleAPI": "FaceMuscleAPI",
}
MULTIPLE_APPLY = {"FaceRegionAPI", "FaceDistanceMatrixAPI"}

_PACKAGE_RESOURCES = Path(__file__).resolve().parents[1] / "resources" / "usdFace"
_SOURCE_DIR = Path(__file__).resolve().parents[2] / "schemas" / "usdFace"
_GENERATED = ("generatedSchema.usda", "plugInfo.json")

_registered = False


def plugin_path() -> Path:
    """Folder holding usdface's plugInfo.json: the value to put on PXR_PLUGINPATH_NAME."""
    return _PACKAGE_RESOURCES


def register() -> bool:
    """Register usdface's schemas with USD in this process.

    Returns True when the schemas are usable. When the process already built its schema registry
    before usdface was imported (a DCC, or a script that opened a stage first) and the plugin
    was not on PXR_PLUGINPATH_NAME, warns with what to do and returns False.
    """
    global _registered
    if _registered:
        return True
    from pxr import Plug, Usd

    Plug.Registry().RegisterPlugins(str(_PACKAGE_RESOURCES))
    missing = [name for name in API_SCHEMAS if not _is_known(Usd, name)]
    if missing:
        warnings.warn(
            "usdface schemas were registered too late in this process (USD's schema registry was "
            f"already built), so {', '.join(missing)} cannot be applied. Import usdface before "
            "opening any stage, or set PXR_PLUGINPATH_NAME to the folder printed by "
            "`usdface plugin-path` before starting Python or the DCC.",
            RuntimeWarning,
            stacklevel=3,
        )
        return False
    _registered = True
    return True


def _is_known(Usd, type_name: str) -> bool:
    return Usd.SchemaRegistry().FindAppliedAPIPrimDefinition(API_SCHEMAS[type_name]) is not None


def require_registered() -> None:
    """Raise SchemaRegistrationError if the schemas are not usable in this process."""
    if not register():
        raise SchemaRegistrationError(
            "usdface schemas are not registered in this process; set PXR_PLUGINPATH_NAME="
            f"{plugin_path()} before starting Python, or import usdface before opening any stage"
        )
