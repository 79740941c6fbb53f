"""The census-transform Hamming cost works on numpy 1.26 (no np.bitwise_count) as on numpy 2."""
import numpy as np

from usdface.scan import graphcut


def test_popcount_without_numpy2(monkeypatch):
    rng = np.random.default_rng(0)
    for dtype in (np.uint8, np.uint32, np.uint64):
        a = rng.integers(0, np.iinfo(dtype).max, size=(7, 5), dtype=dtype, endpoint=True)
        expected = np.vectorize(lambda v: bin(int(v)).count("1"))(a)
        monkeypatch.delattr(np, "bitwise_count", raising=False)
        np.testing.assert_array_equal(graphcut.popcount(a), expected)
        monkeypatch.undo()
