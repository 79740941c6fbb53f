"""Nothing changes for command-line users: every command's arguments (flags, destination,
choices, effective default, nargs, const, required, kind) equal usdface 0.2.0's, taken from the
0.2.0 tree by ``benchmarks/cli_surface.py`` into ``tests/data/cli_surface_0.2.0.json``. Order,
grouping and help wording may change."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_NO_POLYNOMIAL = ("issue 19: the linear polynomial is added by default to exactly the kernels that need it "
                  "(--polynomial's default is 'auto'); --no-polynomial turns it off")
_POSE_REFIT = "issue 19: rounds of pose refit (head stabilisation and rest pose corrected by the rig), 0 = usdface 0.2"
#: arguments added since 0.2.0, on purpose: {(command, flags): why}; nothing else may change
ADDED: dict = {
    ("batch", "--report-only"): "issue 20: rebuild a finished batch's HTML report from its summary without running "
                                "or checking any shot (--report re-ran the shots unless --resume)",
    **{(command, "--no-polynomial"): _NO_POLYNOMIAL for command in ("run", "skel", "transfer")},
    **{(command, "--pose-refit"): _POSE_REFIT for command in ("run", "solve")},
}
#: arguments changed since 0.2.0, on purpose: {(command, flags): why}; each must differ from 0.2.0
CHANGED: dict = {
    **{(command, "--polynomial"): "issue 19: default 'auto' (a store_const True) instead of False: thin-plate "
                                  "splines need the polynomial, the multiquadric gets it"
       for command in ("run", "skel", "transfer")},
    ("distances", "--backend"): "issue 19: fast marching is the default geodesic back-end (held out it transfers at "
                                "least as well as edge paths at the default width)",
    ("run", "--backend"): "issue 19: default None = the RBF mode's: fmm, graph (the paper's edge paths) with --rbf paper",
    ("evaluate", "--backend"): "issue 19: fmm offered; default None = the pipeline's back-end for each row's mode",
}


def _surface_module():
    spec = importlib.util.spec_from_file_location("cli_surface", ROOT / "benchmarks" / "cli_surface.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_command_parses_as_in_0_2_0():
    from usdface.console import build_parser

    before = json.loads((ROOT / "tests" / "data" / "cli_surface_0.2.0.json").read_text())
    now = _surface_module().surface(build_parser())
    assert sorted(now) == sorted(before), "commands added or removed"
    problems = []
    for command, records in before.items():
        old = {(tuple(r["flags"]), r["dest"]): r for r in records}
        new = {(tuple(r["flags"]), r["dest"]): r for r in now[command]}
        for key in sorted(set(old) | set(new)):
            if key not in old and (command, " ".join(key[0])) in ADDED:
                continue
            if (command, " ".join(key[0])) in CHANGED:
                if old.get(key) == new.get(key) or key not in new:
                    problems.append(f"{command} {' '.join(key[0])}: listed as changed, but it is {new.get(key)}")
                continue
            if old.get(key) != new.get(key):
                problems.append(f"{command} {' '.join(key[0]) or key[1]}: 0.2.0 {old.get(key)} now {new.get(key)}")
    assert not problems, "\n".join(problems)


def test_the_comparison_sees_a_changed_default(monkeypatch):
    """The check can fail: a default moved in the options dataclass shows up."""
    import dataclasses

    from usdface.console import build_parser
    from usdface.options import DistanceOptions

    surface = _surface_module()
    before = surface.surface(build_parser())
    field = next(f for f in dataclasses.fields(DistanceOptions) if f.name == "sigma")
    monkeypatch.setattr(field, "default", 3.0)
    after = surface.surface(build_parser())
    old = next(r for r in before["distances"] if r["dest"] == "sigma")
    new = next(r for r in after["distances"] if r["dest"] == "sigma")
    assert (old["default"], new["default"]) == (2.0, 3.0)
