"""Headless Chromium opens the meshcat page and the skeleton appears in its colour."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest

from tracker.sinks.meshcat_view import MeshcatView
from tracker.sinks.geometry import pose_joints_m, track_colour
from tracker import TrackedPose

CHROMIUM = "/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else shutil.which("chromium")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="needs Chromium (apt-get install chromium)")

TRACK = 6  # pink in the palette: unlike the blue sky, grey grid and red/green/blue axes


def _screenshot(url: str, out: Path, profile: Path, live: bool = False) -> np.ndarray:
    """Render ``url`` headless and return the screenshot as (H, W, 3) uint8 RGB. live: the page
    keeps receiving updates, so it never goes idle: shoot after a wall-clock delay instead of
    a virtual-time budget (which waits for idleness)."""
    wait = "--timeout=5000" if live else "--virtual-time-budget=8000"
    command = [
        CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
        "--disable-background-networking", "--no-first-run", f"--user-data-dir={profile}",
        "--window-size=800,600", wait, f"--screenshot={out}", url,
    ]
    result = subprocess.run(command, capture_output=True, text=True, timeout=180)
    assert out.is_file(), f"chromium wrote no screenshot (code {result.returncode}): " \
                          f"{result.stderr[-500:]}"
    return cv2.imread(str(out))[:, :, ::-1]


def _colour_pixels(image: np.ndarray, rgb: tuple[float, float, float]) -> int:
    """Pixels whose channel ratios match ``rgb`` (shading scales all channels alike)."""
    pixels = image.reshape(-1, 3).astype(np.float64)
    r, g, b = rgb
    red = pixels[:, 0]
    bright = red > 80
    ratio_g = pixels[:, 1] / np.maximum(red, 1)
    ratio_b = pixels[:, 2] / np.maximum(red, 1)
    close = (np.abs(ratio_g - g / r) < 0.15) & (np.abs(ratio_b - b / r) < 0.15)
    return int(np.count_nonzero(bright & close))


def test_chromium_shows_the_skeleton_in_its_track_colour(tmp_path):
    joints = pose_joints_m(np.r_[1.0, np.zeros(54)][None])[0] + [0.0, 0.95, 0.0]
    with MeshcatView(print_url=False) as view:
        empty = _screenshot(view.web_url, tmp_path / "empty.png", tmp_path / "profile1")
        view.write(TrackedPose(0, 0.0, TRACK, np.zeros(55), np.zeros(55), False, joints))
        drawn = _screenshot(view.web_url, tmp_path / "skeleton.png", tmp_path / "profile2")
    colour = track_colour(TRACK)
    assert _colour_pixels(empty, colour) < 20
    assert _colour_pixels(drawn, colour) > 300


def test_track_view_serves_the_live_skeleton_to_a_browser(tmp_path):
    """`track --view` on a rendered walk: while it plays, Chromium shows the skeleton of
    track 0 in its colour; when it ends, the viewer's port is closed."""
    import os
    import socket
    import sys

    from sequences.video import Actor, write_video
    from tests.test_track_cli import _walker

    video = tmp_path / "walk.mp4"          # 15 s: played in real time, outlasts the screenshot
    write_video(video, [Actor(_walker(450, step=0.1))], size=(240, 320), noise_sigma=1.0)
    root = Path(__file__).resolve().parents[1]
    proc = subprocess.Popen([sys.executable, "-m", "tracker.cli", str(video), "--view",
                             "--quiet", "--out", str(tmp_path / "v.mcap")],
                            env={**os.environ, "PYTHONPATH": str(root)},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert line.startswith("meshcat viewer: http://127.0.0.1:"), line
        url = line.split(": ", 1)[1].strip()
        drawn = _screenshot(url, tmp_path / "track.png", tmp_path / "profile", live=True)
        assert proc.poll() is None, "track ended before the screenshot: not played in real time"
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert _colour_pixels(drawn, track_colour(0)) > 300
    port = int(url.split(":")[2].split("/")[0])
    with socket.socket() as s:
        assert s.connect_ex(("127.0.0.1", port)) != 0      # server gone with the command
