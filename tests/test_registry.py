"""The registry: a processor declared once appears in the command line, the Python API, the batch
manifest's steps and the README's command table; other packages add theirs through an entry
point; the README's table is the registry's."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import pytest

from usdface import api, registry
from usdface.console import main
from usdface.options import Options, option
from usdface.registry import Input, Output, Processor, Result

ROOT = Path(__file__).resolve().parents[1]
SA = ROOT / "sample_assets"


@dataclass(frozen=True)
class GreetOptions(Options):
    """A toy processor's options."""

    greeting: str = option("hello", flag="--greeting", help="what to write", group="greeting")


def greet(file, *, options: GreetOptions, output=None) -> Result:
    """A toy processor: writes a greeting naming its input (beside it when no output is given)."""
    out = Path(output) if output is not None else Path(file).with_suffix(".greeting.txt")
    out.write_text(f"{options.greeting} {Path(file).name}\n")
    return Result(files={"output": str(out)}, summary={"greeting": options.greeting, "output": str(out)},
                  text=[f"wrote {out}"])


GREET = Processor("greet", "write a greeting naming a file (a studio's own processor)",
                  "Write one line naming FILE: a toy processor registered by a test.", function=greet,
                  options=GreetOptions, inputs=(Input("file", "any file", kind="file", metavar="FILE"),),
                  outputs=(Output("output", "the text file to write", kind="file", required=False,
                                  metavar="GREETING.txt"),),
                  batch_step=True)


@pytest.fixture
def toy():
    registry.register(GREET)
    yield GREET
    registry.unregister(GREET.name)


def test_a_registered_processor_is_a_command_an_api_function_a_batch_step_and_a_readme_row(toy, tmp_path, capsys):
    # the command line
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0 and "greet" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main(["greet", "--help"])
    assert "--greeting" in capsys.readouterr().out
    src = tmp_path / "face.obj"
    src.write_text("# a file\n")
    assert main(["greet", str(src), "-o", str(tmp_path / "g.txt"), "--greeting", "hey", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["greeting"] == "hey"
    assert (tmp_path / "g.txt").read_text() == "hey face.obj\n"
    # the Python API
    assert "greet" in api.commands() and "greet" in dir(api)
    result = api.greet(str(src), {"greeting": "hi"}, output=str(tmp_path / "h.txt"))
    assert result.files["output"] == str(tmp_path / "h.txt") and (tmp_path / "h.txt").read_text() == "hi face.obj\n"
    with pytest.raises(api.OptionError, match="unknown option 'greting'"):
        api.greet(str(src), {"greting": "hi"})
    # the batch manifest's steps
    from usdface.pipeline.batch.manifest import load_manifest, shot_steps

    assert "greet" in shot_steps()
    manifest = tmp_path / "shots.toml"
    manifest.write_text(textwrap.dedent(f"""
        [defaults]
        method = "euclidean"
        trim = [0, 20]
        output = "out/{{capture}}"
        processors = ["run", "greet"]
        [[shots]]
        mesh = "{SA / 'meshes' / 'makehuman_hm08_face_cm.obj'}"
        capture = "{SA / 'capture' / 'JawMoCap.ma'}"
        layout = "{SA / 'layouts' / 'makehuman_hm08_face.layout.json'}"
    """))
    assert load_manifest(manifest).shots[0].processors == ("run", "greet")
    assert main(["batch", str(manifest), "--workers", "0", "--no-cache", "-q"]) == 0
    assert (tmp_path / "out" / "JawMoCap" / "shot.greeting.txt").read_text() == "hello shot.usda\n"
    # the README's table
    assert "| `usdface greet FILE [-o GREETING.txt] [options]` | write a greeting naming a file" in \
        registry.command_table()


def count_vertices(mesh, *, options: GreetOptions, output) -> Result:
    """A toy deliverable: a layer recording the face's vertex count (written where `run` says)."""
    from pxr import Sdf, Usd, UsdGeom

    stage = Usd.Stage.Open(str(mesh))
    face = next(p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh))
    n = len(UsdGeom.Mesh(face).GetPointsAttr().Get())
    layer = Sdf.Layer.CreateAnonymous("count.usda")
    out = Usd.Stage.Open(layer)
    out.OverridePrim(face.GetPath()).CreateAttribute("toy:vertexCount", Sdf.ValueTypeNames.Int).Set(n)
    layer.Export(str(output))
    return Result(layers={"output": str(output)}, summary={"vertices": n}, text=[f"wrote {output}"])


def test_a_registered_deliverable_joins_run(tmp_path):
    """A new kind of `run` deliverable is one declaration in the studio's own file: its processor
    with a Deliverable. `run --output-kind points,vertexcount` then writes its layer and its own
    shot stage, which composes it over the face."""
    from pxr import Usd

    from usdface.options.run import DELIVERABLES, Deliverable

    toy = Processor("vertexcount", "record the face's vertex count (a studio's deliverable)",
                    "A toy deliverable registered by a test.", function=count_vertices, options=GreetOptions,
                    inputs=(Input("mesh", "the face mesh layer", kind="usd"),),
                    outputs=(Output("output", "the layer to write", kind="usd"),),
                    deliverable=Deliverable("vertexcount", "vertexcount.usda", "shot_vertexcount.usda",
                                            step="vertexcount"))
    registry.register(toy)
    try:
        out = tmp_path / "shot"
        code = main(["run", "--mesh", str(SA / "meshes" / "makehuman_hm08_face_cm.obj"),
                     "--capture", str(SA / "capture" / "JawMoCap.ma"),
                     "--layout", str(SA / "layouts" / "makehuman_hm08_face.layout.json"), "--trim", "0", "20",
                     "--output-kind", "points,vertexcount", "-o", str(out), "-q"])
        assert code == 0
        shot = Usd.Stage.Open(str(out / "shot_vertexcount.usda"))
        counts = [p.GetAttribute("toy:vertexCount").Get() for p in shot.Traverse()
                  if p.HasAttribute("toy:vertexCount")]
        assert counts == [2020]
        assert main(["check", str(out / "shot_vertexcount.usda"), "-q"]) == 0
    finally:
        registry.unregister("vertexcount")
    assert "vertexcount" not in DELIVERABLES


def test_an_unknown_batch_step_names_the_registered_ones(toy, tmp_path):
    from usdface.errors import UsdFaceError
    from usdface.pipeline.batch.manifest import load_manifest

    manifest = tmp_path / "shots.toml"
    manifest.write_text(textwrap.dedent(f"""
        [[shots]]
        mesh = "{SA / 'meshes' / 'makehuman_hm08_face_cm.obj'}"
        capture = "{SA / 'capture' / 'JawMoCap.ma'}"
        layout = "{SA / 'layouts' / 'makehuman_hm08_face.layout.json'}"
        output = "out"
        processors = ["run", "greed"]
    """))
    with pytest.raises(UsdFaceError, match=r"expected a list of track, run, check, greet including 'run'"):
        load_manifest(manifest)


def test_a_processor_declared_twice_is_refused(toy):
    from usdface.errors import UsdFaceError

    with pytest.raises(UsdFaceError, match="'greet' .* declared twice"):
        registry.register(GREET)


def test_another_package_adds_a_processor_through_an_entry_point(tmp_path):
    """A studio package installed beside usdface (a dist-info with an entry point in the group
    usdface.processors) appears in the command line, the API and the batch steps."""
    pkg = tmp_path / "studio_face"
    pkg.mkdir()
    (pkg / "__init__.py").write_text(textwrap.dedent('''
        from dataclasses import dataclass
        from pathlib import Path

        from usdface.options import Options, option
        from usdface.registry import Input, Processor, Result


        @dataclass(frozen=True)
        class StampOptions(Options):
            word: str = option("ok", flag="--word", help="the word", group="stamp")


        def stamp(file, *, options):
            return Result(summary={"file": Path(file).name, "word": options.word}, text=[options.word])


        STAMP = Processor("stamp", "print a word about a file", "A studio's processor.",
                          function="studio_face:stamp", options=StampOptions,
                          inputs=(Input("file", "a file", kind="file"),), batch_step=True)
    '''))
    dist = tmp_path / "studio_face-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: studio-face\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[usdface.processors]\nstamp = studio_face:STAMP\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), str(ROOT)]))
    code = ("import json, sys\n"
            "from usdface import api, registry\n"
            "from usdface.console import main\n"
            "from usdface.pipeline.batch.manifest import shot_steps\n"
            "r = api.stamp(sys.argv[1], {'word': 'api'})\n"
            "print(json.dumps({'api': r.summary, 'steps': list(shot_steps()), 'table': 'usdface stamp' in "
            "registry.command_table()}))\n"
            "sys.exit(main(['stamp', sys.argv[1], '--word', 'cli']))\n")
    proc = subprocess.run([sys.executable, "-c", code, str(SA / "README.md")], env=env, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    first, second = proc.stdout.strip().splitlines()
    data = json.loads(first)
    assert data == {"api": {"file": "README.md", "word": "api"}, "steps": ["track", "run", "check", "stamp"],
                    "table": True}
    assert second == "cli"


def test_a_broken_plug_in_is_a_warning_not_a_crash(tmp_path):
    dist = tmp_path / "broken_face-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-face\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[usdface.processors]\nbroken = no_such_module:THING\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), str(ROOT)]))
    proc = subprocess.run([sys.executable, "-m", "usdface", "plugin-path"], env=env, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0
    assert "processor plug-in broken (no_such_module:THING) not loaded: ModuleNotFoundError" in proc.stderr


def test_the_readme_command_table_is_the_registrys():
    readme = (ROOT / "README.md").read_text()
    start, end = "<!-- commands: generated from usdface.registry -->\n", "<!-- end of commands -->"
    assert start in readme and end in readme, "the README's command table lost its markers"
    table = readme.split(start, 1)[1].split(end, 1)[0]
    assert table == registry.command_table(), ("the README's command table differs from the registry's; "
                                               "paste the output of `python -m usdface.registry`")


def test_every_leaf_command_has_an_api_function_of_the_same_name():
    """'-' becomes '_', a sub-command is joined with '_' (landmarks train -> landmarks_train)."""
    import argparse

    from usdface.console import build_parser

    leaves = []

    def walk(parser, words):
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if not subs:
            leaves.append(" ".join(words))
            return
        for name, sub in subs[0].choices.items():
            walk(sub, words + [name])

    walk(build_parser(), [])
    expected = {w.replace("-", "_").replace(" ", "_") for w in leaves}
    assert expected == set(api.commands())
    assert set(api.__all__) == expected | set(api.OTHER_EXPORTS)
    assert {"landmarks_train", "plugin_path", "shapes_transfer", "fit_muscles"} <= expected
    for name in expected:
        assert callable(getattr(api, name))


def test_every_command_prints_its_help():
    """Every command's --help renders: declared help is plain text, so a '%' in it ("8-15% long",
    fmm's help once) is not taken for an argparse format (which made `run --help` a traceback)."""
    import argparse

    from usdface.console import build_parser

    def leaves(parser, words=()):
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if not subs:
            yield words, parser
        for sub in subs:
            for name, child in sub.choices.items():
                yield from leaves(child, words + (name,))

    found = list(leaves(build_parser()))
    assert len(found) >= 26
    for words, parser in found:
        text = parser.format_help()
        assert text.startswith("usage: ") and "%%" not in text, words
