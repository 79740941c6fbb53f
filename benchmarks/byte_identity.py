"""Byte identity of the user's outputs between two versions of usdface.

Runs the same commands with two trees of usdface (a git revision, checked out into a temporary
folder with ``git archive``, and this working tree by default) on the same inputs, writing to the
same output paths (so paths inside the files agree), and compares every file written, byte for
byte. Where bytes differ, only the fields listed in ``ALLOWED`` may differ: JSON files are compared
without them, USD layers as text (``Sdf.Layer.ExportToString``) without them; anything else is a
difference::

    python benchmarks/byte_identity.py --before 9e2e68a            # 0.2.0 against this tree
    python benchmarks/byte_identity.py --before 9e2e68a --jobs main solve
    python benchmarks/byte_identity.py --before c5721ae --identity  # layer identities added since

``--identity`` also allows what the layer identities (issue 20) change on purpose, listed in
``IDENTITY_ALLOWED``: everything else must still agree byte for byte.

Jobs (the README's commands): ``main`` (the main job), ``all`` (``run --output-kind all``),
``batch`` (the batch example, serial), ``solve`` (``solve --csv --livelink``), ``playblast`` (of
the main job's shot, one render worker: 0.2.0's threaded render was not reproducible); on request also ``tissue`` (``muscles``, ``simulate``, ``fit-muscles``
on the sample face and jaw take) and ``evaluate`` (the quality table). Exit 0 when every file
agrees.
"""
from __future__ import annotations

import argparse
import difflib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]

#: fields allowed to differ, and why. Keys are matched anywhere in a JSON document (a summary) and
#: in the provenance JSON that USD layers carry in customLayerData.
ALLOWED = {
    "seconds, *Seconds": "wall time of a step or run (seconds, computeSeconds, solveSeconds...)",
    "started": "the batch's start time",
    "host": "the Dask worker's address",
    "scheduler": "the Dask scheduler's address",
    "dashboard": "the Dask dashboard's address",
    "usdfaceVersion": "the version number (only if it was bumped)",
    "steps (batch summary)": "a batch shot record's {step: wall seconds}",
}


#: with --identity: what layer identities change on purpose, and why
IDENTITY_ALLOWED = {
    "customLayerData usdface.identity": "the identities a layer records (new)",
    "sha256 of a USD input, and a shot record's file sha256 and provenance id": "the input layers gained their "
    "identity, so their bytes differ",
    "the provenance of a simulate/fit-muscles shot stage": "new: version, processor and identity (it had none)",
    "the capture cache key, and the cache entry's record of its layer": "the key gained the identity version, so "
    "entries whose layer has no identity are not reused (entries are compared under the new key)",
}


def _identity_stripped(text: str) -> str:
    """USD text without what :data:`IDENTITY_ALLOWED` lists."""
    text = _without_block(text, "dictionary identity = {")
    # hashes of .usd* inputs (provenance inputs, shot records), quotes escaped or not
    text = re.sub(r'(\\?"file\\?": \\?"[^"\\]*\.usd[ac]?\\?", \\?"sha256\\?": )\\?"[0-9a-f]{64}\\?"',
                  r"\1<layer sha256>", text)
    text = re.sub(r'(\\?"[^"\\]*\.usd[ac]?\\?": \{\\?"id\\?": )\\?"[0-9a-f]+\\?", (\\?"sha256\\?": )\\?"[0-9a-f]{64}\\?"',
                  r"\1<id>, \2<layer sha256>", text)
    return re.sub(r'\n    customLayerData = \{\n        dictionary usdface = \{\n            string processor = '
                  r'"(?:simulate|fit-muscles)"\n            string usdfaceVersion = "[^"]*"\n        \}\n    \}', "", text)


def _without_block(text: str, opener: str) -> str:
    """``text`` without each ``opener`` ... matching ``}`` block (and its line)."""
    while (start := text.find(opener)) >= 0:
        depth, i = 0, start + len(opener) - 1
        while i < len(text):
            depth += {"{": 1, "}": -1}.get(text[i], 0)
            if depth == 0:
                break
            i += 1
        line_start = text.rfind("\n", 0, start)
        text = text[:line_start] + text[i + 1:]
    return text


def jobs(sa: Path, out: Path) -> dict[str, list[list[str]]]:
    """{job: [usdface argv, ...]}: the README's commands on the sample assets ``sa``, into ``out``."""
    mesh = str(sa / "meshes" / "makehuman_hm08_face_cm.obj")
    layout = str(sa / "layouts" / "makehuman_hm08_face.layout.json")
    jaw = str(sa / "capture" / "JawMoCap.ma")
    shapes = str(sa / "meshes" / "makehuman_hm08_face_units_cm.npz")
    return {
        "main": [["run", "--mesh", mesh, "--capture", jaw, "--layout", layout, "-o", str(out / "jaw")]],
        "all": [["run", "--mesh", mesh, "--capture", jaw, "--layout", layout, "--shapes", shapes,
                 "--output-kind", "all", "-o", str(out / "jaw_all")]],
        "batch": [["batch", str(sa / "batch" / "example.toml"), "--workers", "0"]],
        "solve": [["solve", "--mesh", mesh, "--shapes", shapes, "--capture", jaw, "--layout", layout,
                   "-o", str(out / "curves.usdc"), "--csv", str(out / "curves.csv"),
                   "--livelink", str(out / "curves_livelink.csv")]],
        "playblast": [["run", "--mesh", mesh, "--capture", jaw, "--layout", layout, "-o", str(out / "pb")],
                      # one render worker: 0.2.0's threaded render raced (two runs of 9e2e68a differ in 250
                      # of 1590 frames); this tree's threads give its 1-worker movie byte for byte
                      # (tests/media: the movie does not depend on the workers)
                      ["playblast", str(out / "pb" / "shot.usda"), "-o", str(out / "jaw.mp4"), "--size", "960x540",
                       "--workers", "1"]],
        "tissue": [["import-mesh", mesh, "-o", str(out / "face.usdc")],
                   ["import-capture", jaw, "-o", str(out / "jaw.usdc")],
                   ["bind", "--mesh", str(out / "face.usdc"), "--capture", str(out / "jaw.usdc"), "--layout", layout,
                    "-o", str(out / "binding.usda")],
                   ["muscles", "--mesh", str(out / "face.usdc"), "--layout", layout, "--force", "zygomaticMajor=20000",
                    "--tissue", "k_deep=25", "-o", str(out / "rig.usda")],
                   ["muscles", "--mesh", mesh, "-o", str(out / "rig_obj.usda")],
                   ["simulate", "--mesh", str(out / "face.usdc"), "--rig", str(out / "rig.usda"), "--expression", "joy",
                    "--ramp", "2", "--hold", "1", "-o", str(out / "joy.usdc")],
                   ["simulate", "--mesh", mesh, "--rig", str(out / "rig_obj.usda"), "--expression", "surprise",
                    "--integrator", "symplectic", "--ramp", "1", "--hold", "0", "-o", str(out / "surprise.usdc")],
                   ["fit-muscles", "--mesh", str(out / "face.usdc"), "--rig", str(out / "rig.usda"), "--capture",
                    str(out / "jaw.usdc"), "--binding", str(out / "binding.usda"), "--frames", "200", "260", "--step",
                    "20", "--refine", "1", "--report", str(out / "fit.json"), "-o", str(out / "fit.usdc")]],
        "evaluate": [["evaluate", "--mesh", mesh, "--shapes", shapes, "--layout", layout, "--only", "jawOpen",
                      "eyeBlink*", "--methods", "euclidean", "hybrid", "--pins", "upper", "-o", str(out / "quality.md")]],
    }


def checkout(rev: str, where: Path) -> Path:
    """The tree of git revision ``rev`` in ``where`` (no .git)."""
    where.mkdir(parents=True, exist_ok=True)
    archive = subprocess.run(["git", "-C", str(HERE), "archive", rev], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(where)], input=archive, check=True)
    return where


def run_tree(tree: Path, job: str, work: Path) -> tuple[float, list[str]]:
    """Run ``job`` with ``tree``'s usdface; outputs land in work/run (sample assets copied to
    work/sa, so the batch writes beside its manifest as the README's does). Returns (seconds,
    stderr lines of failures)."""
    sa = work / "sa"
    if sa.exists():
        shutil.rmtree(sa)
    shutil.copytree(HERE / "sample_assets", sa)
    out = work / "run"
    out.mkdir(parents=True)
    env = dict(os.environ, PYTHONPATH=str(tree), PYTHONHASHSEED="0")
    errors = []
    loaded = subprocess.run([sys.executable, "-c", "import usdface; print(usdface.__file__)"], env=env, cwd=tree,
                            capture_output=True, text=True).stdout.strip()
    if not Path(loaded).resolve().is_relative_to(Path(tree).resolve()):
        raise SystemExit(f"the tree {tree} did not load its own usdface ({loaded})")
    t0 = time.perf_counter()
    for argv in jobs(sa, out)[job]:
        # cwd=tree: `python -m` puts the working folder first on sys.path, before PYTHONPATH
        proc = subprocess.run([sys.executable, "-m", "usdface", *argv, "-q"], env=env, capture_output=True,
                              text=True, cwd=tree)
        if proc.returncode != 0:
            errors.append(f"{' '.join(argv[:1])} exited {proc.returncode}: {proc.stderr.strip()[-400:]}")
    return time.perf_counter() - t0, errors


def _is_timing(key: str) -> bool:
    return key == "seconds" or key.endswith("Seconds")


def _is_timing_table(key, value) -> bool:
    """A batch shot record's ``steps``: {step: wall seconds}."""
    return key == "steps" and isinstance(value, dict) and all(isinstance(v, (int, float)) or v is None
                                                                for v in value.values())


def _drop(doc, allowed):
    if isinstance(doc, dict):
        return {k: _drop(v, allowed) for k, v in doc.items()
                if k not in allowed and not _is_timing(k) and not _is_timing_table(k, v)}
    if isinstance(doc, list):
        return [_drop(v, allowed) for v in doc]
    return doc


def _json_text(text: str) -> str | None:
    try:
        return json.dumps(_drop(json.loads(text), ALLOWED), sort_keys=True, indent=1)
    except ValueError:
        return None


_PROV = re.compile(r'("?(?:provenance|usdface:provenance)"?\s*=\s*)(".*?(?<!\\)")', re.S)


def _usd_text(path: Path, *, identity: bool = False) -> str:
    from pxr import Sdf

    text = Sdf.Layer.OpenAsAnonymous(str(path)).ExportToString()
    # provenance is JSON inside a string: compare it without the allowed fields
    for key in [k for k in ALLOWED if " " not in k] + [r"\w*Seconds", "seconds"]:
        text = re.sub(rf'(\\"{key}\\": )(\\"[^\\]*\\"|[0-9.eE+-]+)', r"\1<allowed>", text)
    return _identity_stripped(text) if identity else text


def _capture_keys(before: Path, after: Path) -> dict[str, str]:
    """{capture cache key before: after} from the shot summaries found at the same paths (the key
    gained the identity version: IDENTITY_ALLOWED)."""
    def key(path: Path):
        try:
            return json.loads(path.read_text())["steps"]["import-capture"]["cache"]["key"]
        except (OSError, ValueError, KeyError, TypeError):
            return None

    keys = {}
    for summary in before.rglob("summary.json"):
        old, new = key(summary), key(after / summary.relative_to(before))
        if old and new:
            keys[old] = new
    return keys


def _renamed(name: Path, keys: dict) -> Path:
    text = str(name)
    for old, new in keys.items():
        text = text.replace(f"{old[:2]}/{old}", f"{new[:2]}/{new}").replace(f"capture-{old}", f"capture-{new}")
    return Path(text)


def _json_identity(text: str, keys: dict) -> str:
    """JSON text with the capture cache keys of before mapped to after's, and a cache entry's
    record of its .usd* files (sha256, size) masked."""
    for old, new in keys.items():
        text = text.replace(old, new)
    return re.sub(r'("[^"]*\.usd[ac]?": \{\s*"sha256": )"[0-9a-f]{64}",(\s*"size": )\d+', r'\1"<layer>",\g<2>0', text)


def compare(before: Path, after: Path, *, identity: bool = False) -> tuple[list[str], list[str]]:
    """(differences, files compared) between two output folders."""
    keys = _capture_keys(before, after) if identity else {}
    originals = {_renamed(p.relative_to(before), keys): p for p in before.rglob("*") if p.is_file()}
    names_b = set(originals)
    names_a = {p.relative_to(after) for p in after.rglob("*") if p.is_file()}
    diffs = [f"only before: {n}" for n in sorted(names_b - names_a)] + \
            [f"only after: {n}" for n in sorted(names_a - names_b)]
    for name in sorted(names_b & names_a):
        b, a = originals[name].read_bytes(), (after / name).read_bytes()
        if a == b:
            continue
        if name.suffix == ".json":
            tb, ta = _json_text(b.decode()), _json_text(a.decode())
            if identity and tb is not None and ta is not None:
                tb, ta = _json_identity(tb, keys), _json_identity(ta, keys)
        elif name.suffix in (".usda", ".usdc", ".usd"):
            tb, ta = _usd_text(originals[name], identity=identity), _usd_text(after / name, identity=identity)
        else:
            tb = ta = None
        if tb is not None and tb == ta:
            continue
        detail = ""
        if tb is not None and ta is not None:
            lines = list(difflib.unified_diff(tb.splitlines(), ta.splitlines(), lineterm="", n=0))[2:8]
            detail = " | ".join(line.strip()[:160] for line in lines)
        diffs.append(f"differs: {name} {detail}")
    return diffs, sorted(str(n) for n in names_b & names_a)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", required=True, help="git revision of the starting point (e.g. 9e2e68a)")
    ap.add_argument("--after", default=None, help="git revision to compare (default: this working tree)")
    ap.add_argument("--jobs", nargs="+", default=["main", "all", "batch", "solve", "playblast"],
                    choices=["main", "all", "batch", "solve", "playblast", "tissue", "evaluate"])
    ap.add_argument("--keep", help="keep the outputs in this folder")
    ap.add_argument("--identity", action="store_true", help="also allow what layer identities change on purpose "
                    "(IDENTITY_ALLOWED)")
    args = ap.parse_args(argv)
    root = Path(args.keep or tempfile.mkdtemp(prefix="usdface-byteid-"))
    trees = {"before": checkout(args.before, root / "tree-before")}
    trees["after"] = checkout(args.after, root / "tree-after") if args.after else HERE
    print(f"before: {args.before}  after: {args.after or 'working tree ' + str(HERE)}")
    print("fields allowed to differ: " + "; ".join(f"{k} ({v})" for k, v in ALLOWED.items()))
    if args.identity:
        print("and, with --identity: " + "; ".join(f"{k} ({v})" for k, v in IDENTITY_ALLOWED.items()))
    failed = False
    for job in args.jobs:
        work = root / "work"
        results = {}
        for side in ("before", "after"):
            if work.exists():
                shutil.rmtree(work)
            seconds, errors = run_tree(trees[side], job, work)
            if errors:
                print(f"{job}: {side} failed: {'; '.join(errors)}")
                failed = True
            dest = root / side / job
            if dest.exists():
                shutil.rmtree(dest)
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.move(str(work / "run"), dest)
            if (work / "sa" / "batch" / "out").exists():  # the batch writes beside its manifest
                shutil.move(str(work / "sa" / "batch" / "out"), dest / "batch-out")
            results[side] = seconds
        diffs, files = compare(root / "before" / job, root / "after" / job, identity=args.identity)
        failed |= bool(diffs)
        print(f"{job}: {len(files)} files, {'identical' if not diffs else f'{len(diffs)} difference(s)'} "
              f"(before {results['before']:.1f} s, after {results['after']:.1f} s)")
        for d in diffs:
            print(f"  {d}")
    if not args.keep:
        shutil.rmtree(root, ignore_errors=True)
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
