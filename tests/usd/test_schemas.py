"""usdface's schemas: generated files up to date, registered on import, applicable everywhere."""
import subprocess
import sys

import pytest

import usdface  # noqa: F401  (registers the schemas)
from usdface.usd import schemagen
from usdface.usd.schemas import API_SCHEMAS, MULTIPLE_APPLY, plugin_path


def test_generated_files_match_schema_source():
    pytest.importorskip("jinja2")
    assert schemagen.validate() == []


def test_plugin_path_holds_plug_info():
    assert (plugin_path() / "plugInfo.json").is_file()
    assert (plugin_path() / "generatedSchema.usda").is_file()


def test_every_schema_applies_on_a_fresh_stage():
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.CreateInMemory()
    points = UsdGeom.Points.Define(stage, "/P").GetPrim()
    mesh = UsdGeom.Mesh.Define(stage, "/M").GetPrim()
    curves = UsdGeom.BasisCurves.Define(stage, "/C").GetPrim()
    for type_name, token in API_SCHEMAS.items():
        prim = {"FaceMarkerSetAPI": points, "FaceMuscleAPI": curves}.get(token, mesh)
        if token in MULTIPLE_APPLY:
            assert prim.ApplyAPI(token, "inst"), token
            assert prim.HasAPI(token, "inst")
        else:
            assert prim.ApplyAPI(token), token
            assert prim.HasAPI(token)
    assert mesh.GetAttribute("usdface:region:inst:role").Get() == "other"
    assert points.GetAttribute("usdface:markerSet:dimensions").Get() == 3


def test_api_schemas_refuse_wrong_prim_types():
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.CreateInMemory()
    xform = UsdGeom.Xform.Define(stage, "/X").GetPrim()
    assert not xform.CanApplyAPI("FaceMarkerSetAPI")
    assert not xform.CanApplyAPI("FaceMarkerBindingAPI")


def test_registration_too_late_warns_clearly():
    code = (
        "import warnings\n"
        "from pxr import Usd, UsdGeom\n"
        "s = Usd.Stage.CreateInMemory(); UsdGeom.Mesh.Define(s, '/M')\n"
        "Usd.SchemaRegistry().FindAppliedAPIPrimDefinition('SkelBindingAPI')  # registry built now\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    warnings.simplefilter('always')\n"
        "    import usdface\n"
        "print([str(x.message) for x in w])\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert "registered too late" in out and "usdface plugin-path" in out and "PXR_PLUGINPATH_NAME" in out


def test_pxr_plugin_path_env_registers_without_import(tmp_path):
    code = ("from pxr import Usd\n"
            "print(Usd.SchemaRegistry().FindAppliedAPIPrimDefinition('FaceMarkerBindingAPI') is not None)\n")
    env = {**__import__("os").environ, "PXR_PLUGINPATH_NAME": str(plugin_path())}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True,
                         cwd=tmp_path).stdout
    assert out.strip() == "True"
