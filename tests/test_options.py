"""One options object for the command line, batch manifests and the Python API."""
from __future__ import annotations

import pytest

from usdface.cli import build_parser
from usdface.console.arguments import options_from_args
from usdface.errors import OptionError
from usdface.options import CaptureOptions, RunOptions, TransferOptions, option_fields


def _run_options(*argv):
    args = build_parser().parse_args(["run", "--mesh", "m.obj", "--capture", "c.ma", "-o", "out", *argv])
    return options_from_args(RunOptions, args)


def test_defaults_are_the_dataclass_defaults():
    assert _run_options() == RunOptions()
    o = RunOptions()
    assert o.method == "hybrid" and o.stabilize == "auto" and o.output_kind == ("points",) and o.head_motion
    # import-capture does not stabilise unless asked; run does
    assert CaptureOptions().stabilize is None


def test_command_line_manifest_and_api_mean_the_same():
    cli = _run_options("--method", "euclidean", "--trim", "0", "300", "--pin-border", "all", "--stabilize",
                       "ForeHead_M,NoseTop,Leye_Inside", "--no-head-motion", "--output-kind", "both",
                       "--regularization", "0.01", "--polynomial", "--max-influences", "4")
    manifest = RunOptions.from_mapping({"method": "euclidean", "trim": [0, 300], "pin_border": "all",
                                        "stabilize": ["ForeHead_M", "NoseTop", "Leye_Inside"],
                                        "head_motion": False, "output_kind": "points,skel", "regularization": 0.01,
                                        "polynomial": True, "max_influences": 4})
    api = RunOptions(method="euclidean", trim=(0, 300), pin_border="all",
                     stabilize=("ForeHead_M", "NoseTop", "Leye_Inside"), head_motion=False,
                     output_kind=("points", "skel"), regularization=0.01, polynomial=True, max_influences=4)
    assert cli == manifest == api
    assert api.record() == cli.record()


def test_no_stabilize_and_output_kind_aliases():
    assert _run_options("--no-stabilize").stabilize is None
    assert RunOptions(stabilize=False).stabilize is None
    assert _run_options("--output-kind", "skel,points").output_kind == ("points", "skel")
    assert RunOptions(output_kind="all").output_kind == ("points", "skel", "blendshapes")


@pytest.mark.parametrize("kwargs, message", [
    ({"max_influences": 0}, r"--max-influences 0: expected an integer >= 1"),
    ({"max_influences": -3}, r"--max-influences -3: expected an integer >= 1"),
    ({"method": "manhattan"}, r"--method manhattan: expected one of euclidean, geodesic, hybrid"),
    ({"trim": (10, 5)}, r"--trim 10 5: expected 0 <= START < END"),
    ({"output_kind": "points,mesh"}, r"--output-kind mesh"),
    ({"stabilize": "A,B"}, r"at least 3 marker names"),
    ({"resample": 0}, r"--resample 0: expected a number > 0"),
    ({"threshold": 1.5}, r"--threshold 1.5: expected a number in \[0, 1\]"),
    ({"rbf": "paper", "polynomial": True}, r"--polynomial and --regularization apply to --rbf interpolate only"),
    ({"layout": "l.json", "auto": True}, r"--layout and --auto"),
])
def test_bad_values_name_the_flag(kwargs, message):
    with pytest.raises(OptionError, match=message):
        RunOptions(**kwargs)


def test_unknown_manifest_key_suggests_the_closest():
    with pytest.raises(OptionError, match=r"unknown option 'pinborder' \(did you mean 'pin_border'\?\)"):
        RunOptions.from_mapping({"pinborder": "all"})


def test_bad_value_on_the_command_line_exits_2(capsys):
    from usdface.cli import main

    assert main(["run", "--mesh", "m.obj", "--capture", "c.ma", "--layout", "l.json", "-o", "out",
                 "--max-influences", "0"]) == 2
    assert "--max-influences 0: expected an integer >= 1" in capsys.readouterr().err


def test_every_option_has_a_flag_and_help():
    flags = set()
    for f in option_fields(RunOptions):
        assert f.metadata["flag"].startswith("--") and f.metadata["help"]
        assert f.metadata["flag"] not in flags
        flags.add(f.metadata["flag"])


def test_group_takes_a_group_out():
    o = RunOptions(kernel="inverse_multiquadric", stiffness=2.5)
    t = o.group(TransferOptions)
    # the transfer reads the matrix of run's distance method (TransferOptions.method, since 0.3)
    assert t == TransferOptions(kernel="inverse_multiquadric", stiffness=2.5, method="hybrid")
    assert TransferOptions.from_other(o) == t
