"""Which kernel works with which distance: the policy table, the polynomial default, the messages."""
from __future__ import annotations

import itertools

import pytest

from usdface.errors import OptionError
from usdface.rbf import KERNELS
from usdface.rbf.soundness import check_kernel_method, resolve_polynomial, sound_kernels

METHODS = ("euclidean", "geodesic", "hybrid")
ACCEPTED = {  # (kernel, method, polynomial) of interpolate mode that the pipeline runs
    (k, m, p)
    for m in METHODS
    for k in ("gaussian", "inverse_multiquadric")
    for p in (False, True)
} | {("multiquadric", "euclidean", False), ("multiquadric", "euclidean", True),
     ("thin_plate_spline", "euclidean", True)}


@pytest.mark.parametrize("kernel,method,polynomial", list(itertools.product(KERNELS, METHODS, (False, True))))
def test_every_combination_is_accepted_or_refused_in_one_line(kernel, method, polynomial):
    if (kernel, method, polynomial) in ACCEPTED:
        assert check_kernel_method(kernel, method, polynomial=polynomial) == kernel
        return
    with pytest.raises(OptionError) as err:
        check_kernel_method(kernel, method, polynomial=polynomial)
    msg = str(err.value)
    assert err.value.exit_code == 2 and "\n" not in msg
    assert msg.startswith(f"--kernel {kernel} with --method {method}")
    assert msg.endswith(", ".join(sound_kernels(method, polynomial=polynomial)))


def test_refusal_messages():
    with pytest.raises(OptionError) as err:
        check_kernel_method("tps", "geodesic", polynomial=True)
    assert str(err.value) == (
        "--kernel thin_plate_spline with --method geodesic: no well-posed variant (its guarantees hold for "
        "Euclidean distances only; on geodesic distances it amplifies marker motion 17x or more, 3-65x the error of a "
        "Gaussian); kernels that work with --method geodesic: gaussian, inverse_multiquadric")
    with pytest.raises(OptionError) as err:
        check_kernel_method("multiquadric", "hybrid", polynomial=True, method_source="shot/analysis.usdc")
    assert "--method hybrid (the distances of shot/analysis.usdc)" in str(err.value)
    assert str(err.value).endswith("kernels that work with --method hybrid (the distances of shot/analysis.usdc): "
                                   "gaussian, inverse_multiquadric")
    with pytest.raises(OptionError) as err:
        check_kernel_method("cubic", "euclidean", polynomial=True)
    assert str(err.value) == (
        "--kernel cubic with --method euclidean: no usable variant with any --method (scale-free with its polynomial, "
        "it amplifies marker motion about 9x at any width, 1.5x the error of a Gaussian); kernels that work with "
        "--method euclidean: gaussian, inverse_multiquadric, multiquadric, thin_plate_spline")
    # the cubic works with no method: its geodesic/hybrid refusal must not send the user to Euclidean
    for method in ("geodesic", "hybrid"):
        with pytest.raises(OptionError) as err:
            check_kernel_method("cubic", method, polynomial=True)
        assert str(err.value) == (
            f"--kernel cubic with --method {method}: no usable variant with any --method (on {method} distances it "
            "amplifies marker motion 17x or more, 3-65x the error of a Gaussian; on Euclidean ones, scale-free with its "
            f"polynomial, about 9x at any width); kernels that work with --method {method}: gaussian, "
            "inverse_multiquadric")
    with pytest.raises(OptionError) as err:
        check_kernel_method("thin_plate_spline", "euclidean", polynomial=False)
    assert str(err.value) == (
        "--kernel thin_plate_spline with --method euclidean and --no-polynomial: thin_plate_spline is conditionally "
        "positive definite of order 2 and needs its linear polynomial term (drop --no-polynomial); kernels that work "
        "with --method euclidean without it: gaussian, inverse_multiquadric, multiquadric")


def test_paper_mode_takes_the_decaying_kernels_on_every_distance():
    for method in METHODS:
        assert sound_kernels(method, mode="paper") == ("gaussian", "inverse_multiquadric")
        check_kernel_method("gaussian", method, polynomial=False, mode="paper")
        with pytest.raises(OptionError, match=r"^--kernel multiquadric with --rbf paper \(--method " + method
                           + r"\): Eqs\. 1-5 solve nothing and need a kernel that decays with distance; "
                           r"kernels that work with --method \w+ in paper mode: gaussian, inverse_multiquadric$"):
            check_kernel_method("mq", method, polynomial=False, mode="paper")


def test_bad_names():
    with pytest.raises(OptionError, match="--method 'graph': expected one of euclidean, geodesic, hybrid"):
        check_kernel_method("gaussian", "graph", polynomial=False)
    with pytest.raises(OptionError, match="unknown kernel 'wendland'"):
        check_kernel_method("wendland", "euclidean", polynomial=False)
    with pytest.raises(OptionError, match="--rbf 'exact'"):
        sound_kernels("euclidean", mode="exact")


def test_polynomial_default_is_what_the_kernel_needs():
    assert [resolve_polynomial(k) for k in KERNELS] == [False, True, False, True, True]
    assert resolve_polynomial("gaussian", True) is True
    assert resolve_polynomial("cubic", False) is False
    for bad in ("yes", 1, None):
        with pytest.raises(OptionError, match="polynomial: expected 'auto', True or False"):
            resolve_polynomial("gaussian", bad)
