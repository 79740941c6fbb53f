"""How the package is built, measured from its source: a before/after table for a redesign.

    python benchmarks/house_metrics.py --before 9e2e68a          # a git revision against this tree

Per tree: lines of code per layer (the layers of ``tests/test_layers.py``), modules over 600
lines, functions over 100 and over 120 lines and over 10 parameters (numba kernels excepted;
``*args``/``**kwargs`` count as one each), package cycles and upward imports (every import,
function-level ones included, read with ``ast``), and the commands the Python API covers.
"""
from __future__ import annotations

import argparse
import ast
import importlib.util
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]


def _rules():
    spec = importlib.util.spec_from_file_location("layer_rules", HERE / "tests" / "test_layers.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _is_numba(node, wrapped: set) -> bool:
    return node.name in wrapped or any("jit" in ast.unparse(d) for d in node.decorator_list)


def _jit_wrapped(tree) -> set:
    """Names of functions compiled by a call rather than a decorator (``njit(...)(_kernel_py)``,
    which keeps the plain Python function for when numba is missing): kernels too."""
    return {arg.id for node in ast.walk(tree) if isinstance(node, ast.Call) and isinstance(node.func, ast.Call)
            and "jit" in ast.unparse(node.func.func) for arg in node.args if isinstance(arg, ast.Name)}


def functions(root: Path):
    """(path, name, lines, parameters) of every function outside numba kernels."""
    for path in sorted((root / "usdface").rglob("*.py")):
        tree = ast.parse(path.read_text())
        wrapped = _jit_wrapped(tree)
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not _is_numba(node, wrapped):
                a = node.args
                names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs if x.arg not in ("self", "cls")]
                n = len(names) + bool(a.vararg) + bool(a.kwarg)
                yield path.relative_to(root), node.name, node.end_lineno - node.lineno + 1, n


def api_coverage(root: Path) -> tuple[int, int]:
    """(commands with a usdface.api function of the same name, leaf commands), asked of the tree
    in a fresh interpreter."""
    code = (
        "import argparse, json, importlib\n"
        f"from usdface.{'console' if (root / 'usdface' / 'console').is_dir() else 'cli'} import build_parser\n"
        "import usdface.api as api\n"
        "leaves = []\n"
        "def walk(p, w):\n"
        "    subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]\n"
        "    if not subs:\n        leaves.append(' '.join(w)); return\n"
        "    for n, s in subs[0].choices.items():\n        walk(s, w + [n])\n"
        "walk(build_parser(), [])\n"
        "names = [l.replace('-', '_').replace(' ', '_') for l in leaves]\n"
        "print(json.dumps([sum(callable(getattr(api, n, None)) for n in names), len(names)]))\n")
    env = dict(__import__("os").environ, PYTHONPATH=str(root))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, cwd=root)
    if out.returncode != 0:
        raise RuntimeError(f"API coverage of {root}: {out.stderr.strip()[-500:]}")
    return tuple(json.loads(out.stdout))


def repeated_code(root: Path) -> str:
    """Pairs of places in the package sharing six or more lines (identical, or alike but for names
    and values), as counted by the `duplicates` tool when it is installed."""
    import shutil

    if shutil.which("duplicates") is None:
        return "n/a (duplicates not installed)"
    out = subprocess.run(["duplicates", "--repo", str(root / "usdface"), "--seconds", "180"], capture_output=True,
                         text=True).stdout.splitlines()
    first = out[0] if out else ""
    found = re.match(r"(\d+) pairs of places \((\d+) files read\)(?:.*\((\d+) by shape alone, (\d+) of those "
                     r"marked boilerplate\))?", first)
    if not found:
        return "0" if first.startswith("no duplicates") else f"n/a ({first[:60]})"
    pairs, files, _, boiler = found.groups()
    kept = int(pairs) - int(boiler or 0)
    return f"{kept} ({pairs} with boilerplate; {files} files)"


def measure(root: Path) -> dict:
    rules = _rules()
    found = rules.scan(root)
    modules = found["modules"]
    per_layer: dict = {}
    for mod, path in modules.items():
        layer = rules.layer_of(mod)
        name = "outside the layers" if layer is None else rules.LAYERS[layer][0]
        per_layer[name] = per_layer.get(name, 0) + len(path.read_text().splitlines())
    violations = rules.violations(root)
    fns = list(functions(root))
    big = sorted((len(p.read_text().splitlines()), str(p.relative_to(root))) for p in modules.values())
    return {
        "lines per layer": per_layer,
        "modules over 600 lines": [f"{path} ({n})" for n, path in big if n > 600],
        "functions over 100 lines": sum(1 for f in fns if f[2] > 100),
        "functions over 120 lines": [f"{f[0]}:{f[1]} ({f[2]})" for f in fns if f[2] > 120],
        "functions over 10 parameters": [f"{f[0]}:{f[1]} ({f[3]})" for f in fns if f[3] > 10],
        "package cycles": [v for v in violations if v.startswith("package cycle")],
        "upward imports": sum("upward import" in v for v in violations),
        "processors importing processors": sum("processors never import" in v for v in violations),
        "pxr or cv2 outside their packages": sum(" imports pxr" in v or " imports cv2" in v for v in violations),
        "API coverage (commands)": "{}/{}".format(*api_coverage(root)),
        "pairs of repeated code (6+ lines)": repeated_code(root),
    }


def checkout(rev: str, where: Path) -> Path:
    archive = subprocess.run(["git", "-C", str(HERE), "archive", rev], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(where)], input=archive, check=True)
    return where


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", required=True, help="git revision to compare with")
    ap.add_argument("--json", action="store_true", help="print the measurements as JSON")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        before = measure(checkout(args.before, Path(tmp)))
        after = measure(HERE)
    if args.json:
        print(json.dumps({"before": before, "after": after}, indent=1))
        return 0

    def show(v):
        if isinstance(v, list):
            return str(len(v))
        if isinstance(v, dict):
            return ", ".join(f"{k} {n}" for k, n in sorted(v.items(), key=lambda kv: -kv[1]))
        return str(v)

    print(f"| measure | {args.before} | this tree |\n|---|---|---|")
    for key in after:
        print(f"| {key} | {show(before[key])} | {show(after[key])} |")
    for key in ("modules over 600 lines", "functions over 120 lines", "functions over 10 parameters",
                "package cycles"):
        if after[key]:
            print(f"\n{key} (this tree):\n  " + "\n  ".join(after[key]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
