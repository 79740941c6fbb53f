"""What the identity tests share: the sample meshes and takes, a fixture of layers written by the
processors, and helpers to read, strip and compose identities."""
from __future__ import annotations

import shutil

LAYOUTS = {"mh": "makehuman_hm08_face", "sty": "makehuman_hm08_face_stylized", "mp": "mediapipe_face_holes"}
OBJS = {"mh": "makehuman_hm08_face_cm.obj", "sty": "makehuman_hm08_face_stylized_cm.obj",
        "mp": "mediapipe_canonical_face_model_holes.obj"}


def identity_files(d, sa) -> dict:
    """Meshes (MakeHuman, stylized, MediaPipe), two takes (Jaw, Nose; 100 frames each), bindings,
    Euclidean analyses and one animation, written by the processors into ``d``."""
    from usdface import api
    from usdface.options import CaptureOptions

    f = {"dir": d}
    for key, obj in OBJS.items():
        f[key] = d / f"{key}.usdc"
        api.import_mesh(str(sa / "meshes" / obj), output=f[key])
    for take, trim in (("jaw", (300, 400)), ("nose", (100, 200))):
        f[take] = d / f"{take}.usdc"
        api.import_capture(str(sa / "capture" / f"{take.capitalize()}MoCap.ma"), CaptureOptions(trim=trim),
                           output=f[take])
    for key in ("mh", "mp"):
        f[f"bind_{key}"] = d / f"bind_{key}.usda"
        api.bind(f[key], f["jaw"], {"layout": str(sa / "layouts" / f"{LAYOUTS[key]}.layout.json")},
                 output=f[f"bind_{key}"])
        f[f"an_{key}"] = d / f"an_{key}.usdc"
        api.distances(f[key], f[f"bind_{key}"], {"method": "euclidean"}, output=f[f"an_{key}"])
    f["bind_mh_nose"] = d / "bind_mh_nose.usda"
    api.bind(f["mh"], f["nose"], {"layout": str(sa / "layouts" / "makehuman_hm08_face.layout.json")},
             output=f["bind_mh_nose"])
    f["anim"] = d / "anim.usdc"
    api.transfer(f["mh"], f["jaw"], f["bind_mh"], f["an_mh"], output=f["anim"])
    return f


def short(digest: str) -> str:
    """An identity as messages and `info` show it: its first 12 hex digits."""
    return digest[:12]


def recorded(path) -> dict:
    from usdface.usd.layers import layer_provenance

    return layer_provenance(path)["identity"]


def stripped(src, name):
    """A copy of ``src`` as usdface 0.2 wrote it: the same layer without its identity, beside it
    (its sublayers and references resolve)."""
    from pxr import Sdf

    dst = src.with_name(name)
    shutil.copy(src, dst)
    layer = Sdf.Layer.FindOrOpen(str(dst))
    data = dict(layer.customLayerData)
    prov = dict(data["usdface"])
    prov.pop("identity", None)
    prov.pop("revision", None)
    prov["usdfaceVersion"] = "0.2.0"
    data["usdface"] = prov
    layer.customLayerData = data
    layer.Save()
    return dst


def composed(path, sublayers, *, metadata=True):
    """A .usda sublayering ``sublayers`` (a user's own composition of usdface layers)."""
    head = 'defaultPrim = "Face"\n    metersPerUnit = 0.01\n    upAxis = "Y"\n    ' if metadata else ""
    subs = ", ".join(f"@./{p.name}@" for p in sublayers)
    path.write_text(f"#usda 1.0\n(\n    {head}subLayers = [{subs}]\n)\n")
    return path
