"""usdface: facial-animation stage processors for OpenUSD pipelines.

Importing usdface registers its USD schemas (see :mod:`usdface.usd.schemas`).
"""
__version__ = "0.2.0"

from .errors import UsdFaceError  # noqa: E402


def _register_schemas() -> None:
    from .usd.schemas import register

    register()


_register_schemas()

__all__ = ["UsdFaceError", "__version__"]
