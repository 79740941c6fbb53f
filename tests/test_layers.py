"""The house rules of DESIGN.md §2, read from every import (function-level ones included).

Layers, from the top; an import may only point down (or stay in its layer)::

    front doors   usdface.console, usdface.cli, usdface.__main__, usdface.api
    pipeline      usdface.pipeline
    processors    usdface.processors        (one module per processor: they never import each other)
    registry      usdface.registry
    options       usdface.options
    usd           usdface.usd               (the only package that imports pxr)
    compute       capture mesh distance rbf skel blendshape tissue scan tracking evaluation preview
                  playblast media report
    io            usdface.io
    base          errors units fileutil temporaries progress numba_cache memory model revisions, and the package
                  root

Also: no cycle between usdface's packages; pxr only in usdface/usd/ (and the schema registration
in usdface/__init__.py); cv2 only in io/, tracking/, scan/ and preview/; compute packages own their
constants (they never import the options).

Run it as a script to list every violation of a tree: ``python tests/test_layers.py [ROOT]``.
"""
from __future__ import annotations

import ast
import shutil
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

LAYERS = (
    ("front doors", ("usdface.console", "usdface.cli", "usdface.__main__", "usdface.api")),
    ("pipeline", ("usdface.pipeline",)),
    ("processors", ("usdface.processors",)),
    ("registry", ("usdface.registry",)),
    ("options", ("usdface.options",)),
    ("usd", ("usdface.usd",)),
    ("compute", ("usdface.capture", "usdface.mesh", "usdface.distance", "usdface.rbf", "usdface.skel",
                 "usdface.blendshape", "usdface.tissue", "usdface.scan", "usdface.tracking", "usdface.evaluation",
                 "usdface.preview", "usdface.playblast", "usdface.media", "usdface.report")),
    ("io", ("usdface.io",)),
    ("base", ("usdface.errors", "usdface.units", "usdface.fileutil", "usdface.temporaries", "usdface.progress", "usdface.numba_cache",
              "usdface.memory", "usdface.model", "usdface.cache", "usdface.lazy", "usdface.inputfiles",
              "usdface.findings", "usdface.revisions", "usdface")),
)
#: third-party modules confined to some packages
CONFINED = {"pxr": ("usdface.usd", "usdface"), "cv2": ("usdface.io", "usdface.tracking", "usdface.scan",
                                                        "usdface.preview")}


def module_name(path: Path, root: Path) -> str:
    rel = path.relative_to(root).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def imports_of(path: Path, module: str) -> list[tuple[str, int]]:
    """(imported module, line) for every import in the file, at any depth (functions included).
    ``from .x import y`` yields ``pkg.x.y`` candidates resolved by :func:`resolve`."""
    tree = ast.parse(path.read_text(), str(path))
    is_pkg = path.name == "__init__.py"
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".")
                base = base if is_pkg else base[:-1]
                base = base[: len(base) - (node.level - 1)]
                prefix = ".".join(base + ([node.module] if node.module else []))
            else:
                prefix = node.module or ""
            found.append((prefix, node.lineno))
            found += [(f"{prefix}.{alias.name}", node.lineno) for alias in node.names]
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", None)) in (
                "import_module", "__import__") and node.args and isinstance(node.args[0], ast.Constant) \
                and isinstance(node.args[0].value, str) and node.args[0].value.startswith("usdface"):
            found.append((node.args[0].value, node.lineno))  # importlib with a literal name
    return found


def layer_of(module: str) -> int | None:
    best, rank = None, None
    for i, (_, prefixes) in enumerate(LAYERS):
        for p in prefixes:
            inside = module == p or (p != "usdface" and module.startswith(p + "."))  # the root: itself only
            if inside and (best is None or len(p) > len(best)):
                best, rank = p, i
    return rank


def package_of(module: str) -> str:
    parts = module.split(".")
    return ".".join(parts[:2]) if len(parts) > 1 else parts[0]


def scan(root: Path) -> dict:
    """Every import edge of the usdface package under ``root``: {module: [(target, line)]}."""
    pkg = root / "usdface"
    modules = {module_name(p, root): p for p in pkg.rglob("*.py")}
    edges = {}
    for mod, path in modules.items():
        out = []
        for target, line in imports_of(path, mod):
            if target.startswith("usdface"):
                # keep the longest prefix that is a module of the tree (names imported from a module)
                parts = target.split(".")
                while parts and ".".join(parts) not in modules:
                    parts.pop()
                if parts:
                    out.append((".".join(parts), line))
            else:
                out.append((target, line))
        edges[mod] = list(dict.fromkeys(out))
    return {"modules": modules, "edges": edges}


def violations(root: Path = ROOT) -> list[str]:
    """Every broken rule, one line each: file:line, what imports what, which rule."""
    found = scan(root)
    modules, edges = found["modules"], found["edges"]
    out = []

    def where(mod, line):
        return f"{modules[mod].relative_to(root)}:{line}"

    pkg_edges: dict = {}
    out += [f"{modules[m].relative_to(root)}: {m} belongs to no layer" for m in modules if layer_of(m) is None]
    for mod, targets in edges.items():
        src_layer = layer_of(mod)
        for target, line in targets:
            top = target.split(".")[0]
            if top in CONFINED:
                allowed = CONFINED[top]
                if not any(mod == a or mod.startswith(a + ".") for a in allowed if a != "usdface") and \
                        not ("usdface" in allowed and mod == "usdface"):
                    out.append(f"{where(mod, line)}: {mod} imports {top} (only {', '.join(allowed)} may)")
                continue
            if not target.startswith("usdface") or target == mod:
                continue
            dst_layer = layer_of(target)
            a, b = package_of(mod), package_of(target)
            if a != b and target != "usdface":
                pkg_edges.setdefault(a, {}).setdefault(b, (mod, target, line))
            if src_layer is None or dst_layer is None:
                continue  # reported once above
            if target == "usdface" and mod != "usdface":
                continue  # the package root (its version): base
            if dst_layer < src_layer:
                out.append(f"{where(mod, line)}: {mod} ({LAYERS[src_layer][0]}) imports {target} "
                           f"({LAYERS[dst_layer][0]}): an upward import")
            if mod.startswith("usdface.processors.") and target.startswith("usdface.processors.") and \
                    package_of(mod) == package_of(target) and mod.split(".")[2] != target.split(".")[2]:
                out.append(f"{where(mod, line)}: processor {mod} imports processor {target}: processors never "
                           "import each other (what they share lives in the layer below)")
            if LAYERS[src_layer][0] == "compute" and target.startswith("usdface.options"):
                out.append(f"{where(mod, line)}: {mod} imports {target}: compute packages own their constants")
    out += [f"package cycle: {c}" for c in cycles(pkg_edges)]
    return out


def cycles(graph: dict) -> list[str]:
    """Strongly connected components of more than one package, each with one edge that closes it."""
    index, low, stack, on, comps = {}, {}, [], set(), []
    counter = [0]

    def strong(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, {}):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                comps.append(sorted(comp))

    sys.setrecursionlimit(max(10000, sys.getrecursionlimit()))
    for v in list(graph):
        if v not in index:
            strong(v)
    out = []
    for comp in comps:
        ties = [f"{m} -> {t} (line {ln})" for a in comp for b, (m, t, ln) in graph.get(a, {}).items() if b in comp]
        out.append(" <-> ".join(comp) + ": " + "; ".join(ties))
    return out


def test_the_house_keeps_its_layers():
    found = violations(ROOT)
    assert not found, f"{len(found)} import rule(s) broken:\n" + "\n".join(found)


@pytest.mark.parametrize("planted, expected", [
    ("usdface/rbf/kernels.py", "imports pxr"),                                   # pxr outside usd/
    ("usdface/distance/euclidean.py", "an upward import"),                       # compute -> processors
    ("usdface/mesh/closest.py", "imports cv2"),                                  # cv2 outside its packages
])
def test_a_planted_violation_fails_the_check(tmp_path, planted, expected):
    copy = tmp_path / "tree"
    shutil.copytree(ROOT / "usdface", copy / "usdface", ignore=shutil.ignore_patterns("__pycache__", "*.nbi",
                                                                                      "*.nbc"))
    line = {"imports pxr": "from pxr import Usd", "an upward import": "from ..processors import bind",
            "imports cv2": "import cv2"}[expected]
    target = copy / planted
    target.write_text(target.read_text() + f"\n\ndef _planted():\n    {line}\n")
    found = violations(copy)
    assert any(expected in v and planted in v for v in found), found


def test_a_planted_cycle_fails_the_check(tmp_path):
    copy = tmp_path / "tree"
    shutil.copytree(ROOT / "usdface", copy / "usdface", ignore=shutil.ignore_patterns("__pycache__"))
    # io -> capture is allowed (down to... no: io is below compute); a function-level import from
    # the capture package into the io package and back makes a cycle
    (copy / "usdface" / "units.py").write_text((copy / "usdface" / "units.py").read_text()
                                               + "\n\ndef _planted():\n    from . import errors\n")
    (copy / "usdface" / "errors.py").write_text((copy / "usdface" / "errors.py").read_text()
                                                + "\n\ndef _planted():\n    from . import units\n")
    found = violations(copy)
    assert any(v.startswith("package cycle:") and "usdface.errors" in v and "usdface.units" in v for v in found), \
        found


if __name__ == "__main__":
    problems = violations(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT)
    print("\n".join(problems) or "no violations")
    print(f"{len(problems)} violation(s)")
