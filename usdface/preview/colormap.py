"""Colour maps for scalar-per-vertex previews, and the fixed region palette.

The sequential maps (``viridis``, ``magma``) are rebuilt here from 9 control colours each (the
well-known 9-step palettes of the matplotlib maps of the same names, by van der Walt and Smith, CC0).
Between control points the colours are interpolated in CIE L*a*b*, so lightness L* is piecewise
linear in the scalar and strictly increasing: equal steps of the scalar read as equal steps of
lightness, and the maps stay readable in greyscale. ``coolwarm`` (after Moreland 2009) is a
diverging map for signed values (blue < 0 < red), interpolated the same way through a light grey.

All colours in this module are RGB; :func:`apply_colormap` returns floats in [0, 1].
No cv2 here: pure numpy.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..errors import OptionError, list_names
from .choices import COLORS  # noqa: F401 (the colours offered)


#: control colours, sRGB hex, evenly spaced from the low end to the high end
_CONTROL = {
    "viridis": ("#440154", "#472d7b", "#3b528b", "#2c728e", "#21908c",
                "#27ad81", "#5dc863", "#aadc32", "#fde725"),
    "magma": ("#000004", "#1d1147", "#51127c", "#822681", "#b63679",
              "#e65164", "#fb8861", "#fec287", "#fcfdbf"),
    "coolwarm": ("#3b4cc0", "#8db0fe", "#dddddd", "#f49a7b", "#b40426"),
}
#: maps whose lightness increases from low to high (a diverging map does not)
SEQUENTIAL = ("viridis", "magma")
#: every map :func:`colormap_lut` knows
COLORMAPS = tuple(_CONTROL)
#: colour (RGB 0..1) of vertices whose scalar is NaN
NAN_COLOR = (0.55, 0.55, 0.55)

# --- CIE L*a*b* (D65) <-> sRGB, enough for building the lookup tables -----------------------------
_M_RGB2XYZ = np.array([[0.4124564, 0.3575761, 0.1804375],
                       [0.2126729, 0.7151522, 0.0721750],
                       [0.0193339, 0.1191920, 0.9503041]])
_M_XYZ2RGB = np.linalg.inv(_M_RGB2XYZ)
_WHITE = _M_RGB2XYZ @ np.ones(3)


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _linear_to_srgb(c: np.ndarray) -> np.ndarray:
    c = np.clip(c, 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)


def srgb_to_lab(rgb: np.ndarray) -> np.ndarray:
    """(..., 3) sRGB in [0, 1] -> (..., 3) CIE L*a*b* (D65), L* in [0, 100]."""
    xyz = _srgb_to_linear(rgb) @ _M_RGB2XYZ.T / _WHITE
    d = 6 / 29
    f = np.where(xyz > d ** 3, np.cbrt(xyz), xyz / (3 * d * d) + 4 / 29)
    return np.stack([116 * f[..., 1] - 16, 500 * (f[..., 0] - f[..., 1]), 200 * (f[..., 1] - f[..., 2])], axis=-1)


def lab_to_srgb(lab: np.ndarray) -> np.ndarray:
    """(..., 3) CIE L*a*b* (D65) -> (..., 3) sRGB in [0, 1] (out-of-gamut values clipped)."""
    lab = np.asarray(lab, dtype=np.float64)
    fy = (lab[..., 0] + 16) / 116
    f = np.stack([fy + lab[..., 1] / 500, fy, fy - lab[..., 2] / 200], axis=-1)
    d = 6 / 29
    xyz = np.where(f > d, f ** 3, 3 * d * d * (f - 4 / 29)) * _WHITE
    return _linear_to_srgb(xyz @ _M_XYZ2RGB.T)


def _hex(h: str) -> tuple[float, float, float]:
    return tuple(int(h[i:i + 2], 16) / 255.0 for i in (1, 3, 5))


@lru_cache(maxsize=None)
def _lut(name: str, n: int) -> np.ndarray:
    ctrl = srgb_to_lab(np.array([_hex(h) for h in _CONTROL[name]]))
    pos = np.linspace(0.0, 1.0, len(ctrl))
    t = np.linspace(0.0, 1.0, n)
    lab = np.stack([np.interp(t, pos, ctrl[:, k]) for k in range(3)], axis=-1)
    lut = lab_to_srgb(lab)
    lut.setflags(write=False)
    return lut


def colormap_lut(name: str = "viridis", n: int = 256) -> np.ndarray:
    """Lookup table of a colour map.

    Parameters
    ----------
    name : str
        One of :data:`COLORMAPS` (``viridis``, ``magma``: sequential; ``coolwarm``: diverging).
    n : int
        Number of entries (>= 2).

    Returns
    -------
    ndarray, shape (n, 3), float64
        RGB in [0, 1], entry 0 the low end, entry n-1 the high end. Read-only.
    """
    if name not in _CONTROL:
        raise OptionError(f"unknown colormap {name!r}; expected one of {list_names(COLORMAPS)}")
    if int(n) < 2:
        raise OptionError(f"colormap size must be >= 2; got {n}")
    return _lut(name, int(n))


def scalar_range(scalars: np.ndarray, *, colormap: str = "viridis") -> tuple[float, float]:
    """Default display range of ``scalars``: (min, max) of the finite values; symmetric
    (-max|s|, +max|s|) for the diverging ``coolwarm`` map; (0, 1) when nothing is finite."""
    s = np.asarray(scalars, dtype=np.float64)
    s = s[np.isfinite(s)]
    if s.size == 0:
        return 0.0, 1.0
    if colormap not in SEQUENTIAL:
        m = float(np.abs(s).max())
        return (-m, m) if m > 0 else (-1.0, 1.0)
    return float(s.min()), float(s.max())


def apply_colormap(scalars: np.ndarray, *, vrange: tuple[float, float] | None = None,
                   colormap: str = "viridis", n: int = 256) -> np.ndarray:
    """Colours of scalar values.

    Parameters
    ----------
    scalars : ndarray, shape (N,)
        Values; NaN or infinite values get :data:`NAN_COLOR`.
    vrange : (lo, hi), optional
        Values mapped to the low and high ends (clipped beyond); default :func:`scalar_range`.
    colormap : str
        A name from :data:`COLORMAPS`.

    Returns
    -------
    ndarray, shape (N, 3), float64
        RGB in [0, 1]. ``lo`` maps exactly to the first table entry, ``hi`` to the last.
    """
    lut = colormap_lut(colormap, n)
    s = np.asarray(scalars, dtype=np.float64).ravel()
    lo, hi = scalar_range(s, colormap=colormap) if vrange is None else (float(vrange[0]), float(vrange[1]))
    if not (np.isfinite(lo) and np.isfinite(hi)) or hi < lo:
        raise OptionError(f"scalar range must be finite with lo <= hi; got ({lo}, {hi})")
    span = hi - lo if hi > lo else 1.0
    finite = np.isfinite(s)
    t = np.clip((np.where(finite, s, lo) - lo) / span, 0.0, 1.0)
    out = lut[np.rint(t * (n - 1)).astype(np.int64)]
    out[~finite] = NAN_COLOR
    return out


# --- regions ------------------------------------------------------------------------------------
#: RGB 0..255 by region role
ROLE_COLORS = {
    "mouth": [(226, 84, 72), (240, 120, 100)],
    "eye": [(62, 128, 240), (44, 178, 232), (110, 110, 245)],
    "outerBorder": [(84, 84, 84)],  # dark: the clay surface is light grey
}
#: colours for regions that are neither mouth, eye nor border, in order of appearance
OTHER_COLORS = [(240, 168, 48), (92, 190, 104), (186, 110, 214), (58, 196, 190), (232, 118, 168),
                (176, 156, 86), (150, 210, 60), (255, 214, 120), (120, 90, 200), (200, 200, 90)]
#: RGB 0..1 of vertices outside every region, and the default surface colour ("clay")
CLAY = (0.80, 0.76, 0.71)


def region_role(name: str, role: str | None = None) -> str:
    """The palette role of a region: its declared role, or guessed from its name
    (``*mouth*``/``*lip*`` -> mouth, ``*eye*`` -> eye, ``*border*``/``*outer*`` -> outerBorder)."""
    if role in ROLE_COLORS:
        return role
    low = name.lower()
    if "mouth" in low or "lip" in low:
        return "mouth"
    if "eye" in low:
        return "eye"
    if "border" in low or "outer" in low:
        return "outerBorder"
    return role or "other"


def region_palette(names, roles=None) -> dict[str, tuple[int, int, int]]:
    """Fixed, deterministic colour (RGB 0..255) for each region name, in the given order:
    mouth red-ish, eyes blue-ish, outer border grey, every other region a distinct colour."""
    roles = list(roles) if roles is not None else [None] * len(names)
    used = {k: 0 for k in ROLE_COLORS}
    other = 0
    out = {}
    for name, role in zip(names, roles):
        r = region_role(name, role)
        if r in ROLE_COLORS:
            cols = ROLE_COLORS[r]
            out[name] = cols[used[r] % len(cols)]
            used[r] += 1
        else:
            out[name] = OTHER_COLORS[other % len(OTHER_COLORS)]
            other += 1
    return out
