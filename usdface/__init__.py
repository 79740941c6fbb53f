"""usdface: facial-animation stage processors for OpenUSD pipelines.

Importing usdface registers its USD schemas (:func:`register_schemas`; the schema source and its
generated files: :mod:`usdface.usd.schemas`). The command line is :mod:`usdface.console`, the
Python API :mod:`usdface.api`, the processors' declarations :mod:`usdface.registry`.
"""
__version__ = "0.3.0"

import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

from .errors import UsdFaceError  # noqa: E402

#: the folder holding usdface's plugInfo.json and generatedSchema.usda (package data)
SCHEMA_RESOURCES = Path(__file__).resolve().parent / "resources" / "usdFace"
#: the applied API schema type names usdface defines: TfType name -> the token used with ApplyAPI
API_SCHEMAS = {
    "UsdFaceMarkerSetAPI": "FaceMarkerSetAPI",
    "UsdFaceMarkerBindingAPI": "FaceMarkerBindingAPI",
    "UsdFaceRegionAPI": "FaceRegionAPI",
    "UsdFaceDistanceMatrixAPI": "FaceDistanceMatrixAPI",
    "UsdFaceTransferAPI": "FaceTransferAPI",
    "UsdFaceMuscleAPI": "FaceMuscleAPI",
}
_registered = False


def register_schemas() -> bool:
    """Register usdface's schemas with USD in this process.

    Returns True when the schemas are usable. When the process already built its schema registry
    before usdface was imported (a DCC, or a script that opened a stage first) and the plugin
    was not on PXR_PLUGINPATH_NAME, warns with what to do and returns False. This is the one place
    outside :mod:`usdface.usd` that imports pxr: registration must come before any stage opens.
    """
    global _registered
    if _registered:
        return True
    from pxr import Plug, Usd

    Plug.Registry().RegisterPlugins(str(SCHEMA_RESOURCES))
    missing = [name for name, token in API_SCHEMAS.items()
               if Usd.SchemaRegistry().FindAppliedAPIPrimDefinition(token) is None]
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


register_schemas()

__all__ = ["UsdFaceError", "__version__", "register_schemas"]
