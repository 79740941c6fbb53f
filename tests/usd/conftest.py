"""Fixtures of the usd tests."""
from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def fx(tmp_path_factory, sample_assets):
    """Layers written by the processors for the identity tests (:func:`identity_helpers.identity_files`)."""
    from tests.usd.identity_helpers import identity_files

    return identity_files(tmp_path_factory.mktemp("identity"), sample_assets)
