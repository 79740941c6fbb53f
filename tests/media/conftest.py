"""Shots made once per session from the sample assets (through the real CLI) for playblast and
report tests, and a headless Chromium for the tests that open reports as a person would."""
from __future__ import annotations

import json
import os
import shutil
import tempfile

import numpy as np
import pytest



@pytest.fixture(scope="session")
def shots(tmp_path_factory, sample_assets, cli):
    """The README's main job (hybrid, points and skeleton), a Euclidean run of its first 240 frames,
    and a take with gaps filled by --fill-gaps (trimmed to 300 frames)."""
    from usdface.usd.capture_layer import read_capture_layer, write_capture_layer

    d = tmp_path_factory.mktemp("media_shots")
    mesh = sample_assets / "meshes" / "makehuman_hm08_face_cm.obj"
    layout = sample_assets / "layouts" / "makehuman_hm08_face.layout.json"
    take = sample_assets / "capture" / "JawMoCap.ma"
    out = {"dir": d, "hybrid": d / "jaw", "euclidean": d / "jaw_euc", "gaps": d / "jaw_gaps"}
    assert cli("run", "--mesh", mesh, "--capture", take, "--layout", layout, "--output-kind", "both",
                   "-o", out["hybrid"], "-q") == 0
    assert cli("run", "--mesh", mesh, "--capture", take, "--layout", layout, "--method", "euclidean",
                   "--trim", 0, 240, "-o", out["euclidean"], "-q") == 0
    raw = d / "raw.usdc"
    assert cli("import-capture", take, "-o", raw, "--trim", 0, 300, "-q") == 0
    cap = read_capture_layer(raw)
    pos = cap.positions.copy()
    pos[100:106, cap.index("Chin")] = np.nan          # filled (6 <= 8)
    pos[150:153, cap.index("Mouth_DownL")] = np.nan   # filled
    pos[200:230, cap.index("NoseTop")] = np.nan       # too long: stays invalid
    gappy = d / "gappy.usdc"
    write_capture_layer(gappy, cap.replace(positions=pos), prov={"processor": "test"})
    assert cli("run", "--mesh", mesh, "--capture", gappy, "--layout", layout, "--fill-gaps", 8,
                   "-o", out["gaps"], "-q") == 0
    return out


@pytest.fixture(scope="session")
def video_shot(tmp_path_factory, sample_assets, cli):
    """The painted-dots clip tracked, lifted and transferred, trimmed to source frames 10..59."""
    d = tmp_path_factory.mktemp("media_video")
    out = d / "video"
    v = sample_assets / "video"
    assert cli("run", "--mesh", sample_assets / "meshes" / "makehuman_hm08_face_cm.obj", "--capture",
                   v / "animface_dots.mp4", "--seeds", v / "animface_dots.seeds.json", "--layout",
                   sample_assets / "layouts" / "makehuman_hm08_face.layout.json", "--trim", 10, 60, "-o", out,
                   "-q") == 0
    return {"dir": out, "shot": out / "shot.usda", "video": v / "animface_dots.mp4"}


# -- a real browser ---------------------------------------------------------------------------------

CHROMIUM = ("/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome")
CHROMEDRIVER = ("/usr/bin/chromedriver", "/usr/lib/chromium/chromedriver")


def _missing_browser(reason: str):
    """On CI a missing browser fails the run; elsewhere the browser tests skip."""
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"headless browser tests cannot run on CI: {reason} (.ci/run installs chromium and "
                    "chromium-driver with apt-get)")
    pytest.skip(reason)


@pytest.fixture(scope="session")
def browser():
    """A headless Chromium driven by selenium (Debian's chromium + chromium-driver)."""
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        _missing_browser("selenium is not installed (pip install '.[test]')")
    binary = next((p for p in CHROMIUM if os.path.exists(p)), None) or shutil.which("chromium")
    driver_path = next((p for p in CHROMEDRIVER if os.path.exists(p)), None) or shutil.which("chromedriver")
    if not binary or not driver_path:
        _missing_browser("chromium or chromedriver not found (apt-get install chromium chromium-driver)")
    profile = tempfile.mkdtemp(prefix="usdface-chromium-")
    opts = webdriver.ChromeOptions()
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-dev-shm-usage", f"--user-data-dir={profile}", "--window-size=1400,1000",
                 "--autoplay-policy=no-user-gesture-required"):
        opts.add_argument(flag)
    opts.binary_location = binary
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL", "performance": "ALL"})
    try:
        drv = webdriver.Chrome(service=Service(driver_path), options=opts)
    except Exception as exc:  # noqa: BLE001 - any start-up failure means no browser
        shutil.rmtree(profile, ignore_errors=True)
        _missing_browser(f"chromium could not start: {str(exc).splitlines()[0]}")
    drv.set_page_load_timeout(120)
    yield drv
    drv.quit()
    shutil.rmtree(profile, ignore_errors=True)


@pytest.fixture(scope="session")
def page_opener():
    """open_page(driver, path) -> {"state", "console", "requests"}."""
    return open_page


def open_page(drv, path, *, settle: float = 1.0) -> dict:
    """Open ``path`` (file://), wait until the plots are drawn; return console messages and
    every request the page made."""
    import time

    drv.get("about:blank")
    drv.get_log("browser")
    drv.get_log("performance")
    drv.get(path.resolve().as_uri())
    deadline = time.time() + 60
    while time.time() < deadline:
        state = drv.execute_script("return window.usdfaceReport || null")
        if state is not None:
            break
        time.sleep(0.2)
    time.sleep(settle)
    requests = []
    for entry in drv.get_log("performance"):
        msg = json.loads(entry["message"])["message"]
        if msg.get("method") == "Network.requestWillBeSent":
            requests.append(msg["params"]["request"]["url"])
    return {"state": state, "console": drv.get_log("browser"), "requests": requests}
