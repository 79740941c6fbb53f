"""write_png: atomic, permissions, errors naming the path."""
from __future__ import annotations

import os
import stat

import cv2
import numpy as np
import pytest

from usdface.errors import InputError, OptionError
from usdface.preview import write_png
import usdface.preview.render as render_module


def image(h=20, w=30, seed=0):
    return np.random.default_rng(seed).integers(0, 256, (h, w, 3), dtype=np.uint8)


def test_round_trip_and_mode(tmp_path):
    img = image()
    out = write_png(tmp_path / "a.png", img)
    assert out == tmp_path / "a.png"
    np.testing.assert_array_equal(cv2.imread(str(out), cv2.IMREAD_UNCHANGED), img)
    assert stat.S_IMODE(os.stat(out).st_mode) == 0o644
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png"]  # no temp file left


@pytest.mark.parametrize("img", [np.zeros((5, 7), np.uint8), np.zeros((5, 7, 4), np.uint8),
                                 np.full((5, 7, 3), 60000, np.uint16)])
def test_grey_alpha_and_16_bit(tmp_path, img):
    out = write_png(str(tmp_path / "b.png"), img)
    back = cv2.imread(str(out), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(back.reshape(img.shape), img)


def test_replaces_an_existing_file_atomically(tmp_path):
    path = tmp_path / "c.png"
    write_png(path, image(seed=1))
    ino = os.stat(path).st_ino
    new = image(seed=2)
    write_png(path, new)
    np.testing.assert_array_equal(cv2.imread(str(path)), new)
    assert os.stat(path).st_ino != ino  # a new file renamed over the old one, not rewritten in place
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.png"]


def test_failed_encode_leaves_the_old_file_and_no_temp(tmp_path, monkeypatch):
    path = tmp_path / "d.png"
    old = image(seed=3)
    write_png(path, old)
    monkeypatch.setattr(cv2, "imencode", lambda *a, **k: (False, None))
    with pytest.raises(InputError, match="d.png"):
        write_png(path, image(seed=4))
    np.testing.assert_array_equal(cv2.imread(str(path)), old)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.png"]


def test_a_full_disk_leaves_the_old_file_and_no_temp(tmp_path, monkeypatch):
    from usdface.errors import WriteError

    path = tmp_path / "e.png"
    old = image(seed=5)
    write_png(path, old)
    monkeypatch.setenv("USDFACE_TEST_FAULT", "ENOSPC:save")  # the atomic writer's fault hook
    with pytest.raises(WriteError, match="e.png.*disk full"):
        write_png(path, image(seed=6))
    np.testing.assert_array_equal(cv2.imread(str(path)), old)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e.png"]


def test_missing_folder_names_the_path(tmp_path):
    path = tmp_path / "nope" / "f.png"
    with pytest.raises(InputError) as err:
        write_png(path, image())
    assert str(path) in str(err.value) and "does not exist" in str(err.value)


def test_path_is_a_folder(tmp_path):
    (tmp_path / "g.png").mkdir()
    with pytest.raises(InputError, match="folder"):
        write_png(tmp_path / "g.png", image())


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write into read-only folders")
def test_read_only_folder(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        with pytest.raises(InputError, match="h.png"):
            write_png(ro / "h.png", image())
    finally:
        ro.chmod(0o755)


def test_bad_arguments(tmp_path):
    with pytest.raises(OptionError, match=r"\.png"):
        write_png(tmp_path / "i.jpg", image())
    with pytest.raises(OptionError, match="uint8 or uint16"):
        write_png(tmp_path / "j.png", image().astype(np.float32))
    with pytest.raises(OptionError, match="shape"):
        write_png(tmp_path / "k.png", np.zeros((4, 4, 2), np.uint8))
    assert list(tmp_path.iterdir()) == []


def test_module_uses_the_patched_cv2():
    assert render_module._cv2() is cv2


def test_unwritable_folder_names_the_path(tmp_path, monkeypatch):
    from usdface.errors import WriteError

    monkeypatch.setenv("USDFACE_TEST_FAULT", "EACCES:create")  # the atomic writer's fault hook
    with pytest.raises(WriteError, match=r"l\.png.*permission denied"):
        write_png(tmp_path / "l.png", image())
    assert list(tmp_path.iterdir()) == []
