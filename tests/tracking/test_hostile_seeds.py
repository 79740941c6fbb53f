"""Seed points that are not two numbers are refused (a string "12" read as (1, 2) before)."""
from __future__ import annotations

import pytest

from usdface.errors import InputError
from usdface.tracking.detect import check_seeds


@pytest.mark.parametrize("xy", ["12", [True, 3], [10**400, 3], [1, 2, 3], {"x": 1}])
def test_seed_that_is_not_two_numbers(xy):
    with pytest.raises(InputError, match=r"--seeds: marker 'Chin': expected \[x, y\] in pixels"):
        check_seeds({"Chin": xy}, (640, 480))


def test_good_seeds_pass():
    assert check_seeds({"Chin": [10, 20.5]}, (640, 480)) == {"Chin": (10.0, 20.5)}
