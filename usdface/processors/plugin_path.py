"""`usdface plugin-path`: the folder to put on PXR_PLUGINPATH_NAME for DCCs."""
from __future__ import annotations

from ..options import NoOptions
from ..registry import Result
from ..usd.schemas import plugin_path as folder


def plugin_path(*, options: NoOptions) -> Result:
    """The folder holding usdface's plugInfo.json."""
    path = str(folder())
    return Result(summary={"path": path}, text=[path])
