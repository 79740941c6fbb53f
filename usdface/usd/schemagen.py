"""Developer tool: regenerate and validate usdface's generated schema files.

    python -m usdface.usd.schemagen --generate   # after editing schemas/usdFace/schema.usda (needs jinja2)
    python -m usdface.usd.schemagen --validate   # CI: exit 1 if the generated files are out of date
"""
from __future__ import annotations

import argparse
import filecmp
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from ..errors import SchemaRegistrationError
from .schemas import plugin_path

_PACKAGE_RESOURCES = plugin_path()
_SOURCE_DIR = Path(__file__).resolve().parents[2] / "schemas" / "usdFace"
_GENERATED = ("generatedSchema.usda", "plugInfo.json")



def _run_usdgenschema(out_dir: Path, *, validate: bool) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "pxr.Usd.usdGenSchema", "-q"]
    if validate:
        cmd.append("--validate")
    cmd += [str(_SOURCE_DIR / "schema.usda"), str(out_dir)]
    return subprocess.run(cmd, capture_output=True, text=True)


def _fix_plug_info(path: Path) -> None:
    text = path.read_text()
    for placeholder, value in (("@PLUG_INFO_LIBRARY_PATH@", ""), ("@PLUG_INFO_RESOURCE_PATH@", "."),
                               ("@PLUG_INFO_ROOT@", ".")):
        text = text.replace(placeholder, value)
    path.write_text(text)


def generate() -> None:
    """Regenerate generatedSchema.usda and plugInfo.json from schema.usda (needs jinja2)."""
    result = _run_usdgenschema(_SOURCE_DIR, validate=False)
    if result.returncode:
        raise SchemaRegistrationError(f"usdGenSchema failed:\n{result.stdout}{result.stderr}")
    _fix_plug_info(_SOURCE_DIR / "plugInfo.json")
    json.loads(_strip_comments(_SOURCE_DIR / "plugInfo.json"))  # fail here, not at import, if broken
    _PACKAGE_RESOURCES.mkdir(parents=True, exist_ok=True)
    for name in _GENERATED:
        shutil.copyfile(_SOURCE_DIR / name, _PACKAGE_RESOURCES / name)


def _strip_comments(path: Path) -> str:
    return "\n".join(line for line in path.read_text().splitlines() if not line.lstrip().startswith("#"))


def validate() -> list[str]:
    """Problems with the generated files: out of date with schema.usda, or package copies differ."""
    problems = []
    with tempfile.TemporaryDirectory() as tmp:
        result = _run_usdgenschema(Path(tmp), validate=False)
        if result.returncode:
            return [f"usdGenSchema failed:\n{result.stdout}{result.stderr}"]
        _fix_plug_info(Path(tmp) / "plugInfo.json")
        for name in _GENERATED:
            fresh, committed = Path(tmp) / name, _SOURCE_DIR / name
            if not committed.exists() or not filecmp.cmp(fresh, committed, shallow=False):
                problems.append(f"{committed} is out of date with schema.usda; run `python -m usdface.usd.schemagen --generate`")
    for name in _GENERATED:
        src, pkg = _SOURCE_DIR / name, _PACKAGE_RESOURCES / name
        if not pkg.exists() or (src.exists() and not filecmp.cmp(src, pkg, shallow=False)):
            problems.append(f"{pkg} differs from {src}; run `python -m usdface.usd.schemagen --generate`")
    return problems


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m usdface.usd.schemagen", description=__doc__.splitlines()[0])
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--generate", action="store_true", help="regenerate the generated files from schema.usda")
    group.add_argument("--validate", action="store_true", help="exit 1 if the generated files are out of date")
    args = parser.parse_args(argv)
    if args.generate:
        generate()
        print(f"generated {', '.join(_GENERATED)} in {_SOURCE_DIR} and {_PACKAGE_RESOURCES}")
        return 0
    problems = validate()
    for p in problems:
        print(p, file=sys.stderr)
    if not problems:
        print("usdface schemas: generated files are up to date")
    return 1 if problems else 0


if __name__ == "__main__":
    raise SystemExit(main())
