"""Browser viewers, driven by a real headless Chromium (Debian's ``chromium`` and
``chromium-driver``, installed by ``make test``): the page loads, moving a slider changes
the 3-D scene (screenshots before/after differ where the robot is drawn), the server binds
to 127.0.0.1 and stops within a bounded time."""

from __future__ import annotations

import io
import shutil
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from PIL import Image

from geosyn.experiments.config.loader import load_config
from geosyn.experiments.viewer import Viewer, ViewerUnavailable, explore_robot, view_run

CHROMIUM, CHROMEDRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--enable-unsafe-swiftshader",  # WebGL in software (SwiftShader) without a GPU
    "--window-size=800,600",
)


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    """A headless Chromium driven by selenium, with a fresh profile (one per module). The
    viewers run with ``fast=True``: without a GPU, shadows and the environment map make
    the first WebGL frame take ~10 s, ~0.1 s without."""
    if shutil.which(CHROMIUM) is None or shutil.which(CHROMEDRIVER) is None:
        pytest.fail(
            "chromium and chromium-driver are needed (make test installs them: "
            "apt-get install chromium chromium-driver)"
        )
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for flag in (*FLAGS, f"--user-data-dir={tmp_path_factory.mktemp('profile')}"):
        opts.add_argument(flag)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
    driver.set_page_load_timeout(60)
    try:
        yield driver
    finally:
        driver.quit()


def _screenshot(driver) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(driver.get_screenshot_as_png())).convert("RGB"))


def _sliders(driver, timeout: float = 60.0) -> list:
    """The page's sliders in page order, once the GUI has arrived over the websocket."""
    from selenium.webdriver.common.by import By

    end = time.monotonic() + timeout
    while time.monotonic() < end:
        found = driver.find_elements(By.CSS_SELECTOR, "[role=slider]")
        labels = driver.find_elements(By.XPATH, "//*[contains(text(), 'time [s]')]")
        if found and labels:
            break
        time.sleep(0.5)
    else:
        raise AssertionError("the viewer's GUI did not appear within the timeout")
    time.sleep(1.0)  # the scene arrives with the GUI; give the renderer a frame or two
    return found


def _changed_screenshot(driver, before: np.ndarray, timeout: float = 30.0) -> np.ndarray:
    """The first screenshot whose scene region differs from ``before`` (or the last one)."""
    end = time.monotonic() + timeout
    while True:
        time.sleep(0.5)
        after = _screenshot(driver)
        if _changed_fraction(before, after) > 0.002 or time.monotonic() > end:
            return after


def _changed_fraction(before: np.ndarray, after: np.ndarray) -> float:
    """Fraction of the scene region's pixels that changed by more than 30 levels."""
    return float((np.abs(_scene_region(before) - _scene_region(after)).max(axis=2) > 30).mean())


def _scene_region(img: np.ndarray) -> np.ndarray:
    """Where the robot is drawn: left of the GUI panel, below the notification area."""
    h, w = img.shape[:2]
    return img[int(0.3 * h) :, : int(0.62 * w)].astype(np.int16)


def _close_bounded(viewer: Viewer, timeout: float = 15.0) -> None:
    """Stop the server from another thread and require it to finish within ``timeout``."""
    done = threading.Thread(target=viewer.close, daemon=True)
    done.start()
    done.join(timeout)
    assert not done.is_alive(), f"the viewer did not stop within {timeout} s"


def _press(driver, slider, key, times: int) -> None:
    from selenium.webdriver.common.action_chains import ActionChains

    ActionChains(driver).move_to_element(slider).click().perform()
    for _ in range(times):
        slider.send_keys(key)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """The acceptance run: ``ur5_tracking`` (kind tracking: UR5, box obstacle, push, QP)
    with ``--video``, shortened to 0.8 s (the push acts at 0.5-0.6 s) and small frames."""
    from geosyn.experiments.run.runner import run_experiment

    overrides = [
        "simulation.duration=0.8",
        "outputs.fps=10",
        "outputs.width=160",
        "outputs.height=120",
    ]
    cfg, _ = load_config("ur5_tracking", overrides)
    out = tmp_path_factory.mktemp("runs") / "ur5"
    outcome = run_experiment(cfg, out, video=True, progress=False, quiet=True)
    return outcome.path


@pytest.mark.slow
def test_the_acceptance_run_has_its_video(run_dir):
    """``--video`` on a tracking run writes a GIF and says so in the saved config and
    run.json: one frame per 0.1 s from 0 to the end of the 0.8 s run, i.e. 9 frames."""
    import json

    import yaml

    with Image.open(run_dir / "video_qp.gif") as gif:
        assert gif.n_frames == 9
        assert gif.size == (160, 120)
    assert yaml.safe_load((run_dir / "config.yaml").read_text())["outputs"]["video"] is True
    record = json.loads((run_dir / "run.json").read_text())["video"]
    assert record["files"] == ["video_qp.gif"] and record["error"] is None
    assert record["frames"] == 9


def _start_cli(*args: str) -> tuple[subprocess.Popen, str]:
    """``geosyn ARGS`` in a subprocess; returns it and the URL it serves (within 120 s)."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "geosyn", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    lines: list[str] = []

    def read() -> None:
        for line in proc.stdout:  # type: ignore[union-attr]
            lines.append(line)

    threading.Thread(target=read, daemon=True).start()
    end = time.monotonic() + 120.0
    while time.monotonic() < end and proc.poll() is None:
        url = next((ln.split()[1] for ln in lines if ln.startswith("viewer: ")), None)
        if url:
            return proc, url
        time.sleep(0.2)
    proc.kill()
    raise AssertionError("geosyn did not serve a viewer:\n" + "".join(lines))


def _stop_cli(proc: subprocess.Popen, timeout: float = 15.0) -> int:
    """SIGTERM, then require the process to end within ``timeout``; returns its code."""
    proc.terminate()
    try:
        return proc.wait(timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise AssertionError(f"the viewer did not stop within {timeout} s") from None


@pytest.mark.slow
def test_view_scrub_changes_the_scene(run_dir, browser):
    """``geosyn view RUN_DIR`` on the acceptance run serves on 127.0.0.1; scrubbing time to
    the end moves the robot; SIGTERM stops the server."""
    from selenium.webdriver.common.keys import Keys

    proc, url = _start_cli("view", str(run_dir), "--port", "0", "--fast")
    try:
        assert url.startswith("http://127.0.0.1:")
        browser.get(url)
        sliders = _sliders(browser)
        before = _screenshot(browser)
        time_slider = sliders[0]
        assert float(time_slider.get_attribute("aria-valuenow")) == 0.0
        _press(browser, time_slider, Keys.END, 1)  # scrub to the end of the run
        after = _changed_screenshot(browser, before)
        assert float(time_slider.get_attribute("aria-valuenow")) == pytest.approx(0.8, abs=0.02)
    finally:
        code = _stop_cli(proc)
    assert code == 143  # SIGTERM: SystemExit(128 + 15) after the server was closed
    assert _scene_region(before).std() > 5.0  # something is drawn, not a blank page
    changed = _changed_fraction(before, after)
    assert changed > 0.002, f"only {changed:.4%} of the scene pixels changed"


@pytest.mark.slow
def test_explore_weight_slider_changes_the_scene(browser):
    """`geosyn explore`: moving a weight slider recomputes the combination; the robot moves."""
    from selenium.webdriver.common.keys import Keys

    viewer = explore_robot("planar3", k=2, port=0, fast=True)
    try:
        browser.get(viewer.url)
        sliders = _sliders(browser)
        before = _screenshot(browser)
        weight = sliders[0]
        assert float(weight.get_attribute("aria-valuenow")) == 1.0
        _press(browser, weight, Keys.ARROW_RIGHT, 10)  # 1.0 -> 1.5
        after = _changed_screenshot(browser, before)
        assert float(weight.get_attribute("aria-valuenow")) == pytest.approx(1.5)
    finally:
        _close_bounded(viewer)
    changed = _changed_fraction(before, after)
    assert changed > 0.002, f"only {changed:.4%} of the scene pixels changed"


def test_view_rejects_a_directory_without_a_run(tmp_path):
    from geosyn.experiments.errors import ExperimentError

    with pytest.raises(ExperimentError, match="no config.yaml"):
        view_run(tmp_path, port=0)


def test_port_in_use_is_one_clear_error(run_dir):
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        with pytest.raises(ViewerUnavailable, match=f"port {port}"):
            view_run(run_dir, port=port)
