"""Headless Chromium opens the meshcat page and the skeleton appears in its colour."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest

from tracker.meshcat_view import MeshcatView
from tracker.skeleton_geometry import pose_joints_m, track_colour

CHROMIUM = "/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else shutil.which("chromium")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="needs Chromium (apt-get install chromium)")

TRACK = 6  # pink in the palette: unlike the blue sky, grey grid and red/green/blue axes


def _screenshot(url: str, out: Path, profile: Path) -> np.ndarray:
    """Render ``url`` headless and return the screenshot as (H, W, 3) uint8 RGB."""
    command = [
        CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
        "--disable-background-networking", "--no-first-run", f"--user-data-dir={profile}",
        "--window-size=800,600", "--virtual-time-budget=8000", f"--screenshot={out}", url,
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
        view.write(0, 0.0, TRACK, np.zeros(55), np.zeros(55), False, joints)
        drawn = _screenshot(view.web_url, tmp_path / "skeleton.png", tmp_path / "profile2")
    colour = track_colour(TRACK)
    assert _colour_pixels(empty, colour) < 20
    assert _colour_pixels(drawn, colour) > 300
