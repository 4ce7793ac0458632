"""Headless Chromium opens the meshcat page: the bodies show both side colours, the video
screen shows beside them, all along a live `track --view` run.

Set VIEW_SCREENSHOTS=FOLDER to keep the three screenshots of the live run (docs/ has two)."""
from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from tests.chromium import CHROMIUM, Chromium
from tracker import TrackedPose
from tracker.outputs.geometry import SIDE_HUE_TURN_DEG, body_colours, pose_joints_m
from tracker.outputs.meshcat_view import BEZEL_COLOUR, MeshcatView

pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="needs Chromium (apt-get install chromium)")

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sequences" / "data" / "sample_spiral_walk.mp4"   # 361 frames, 12 s
TRACK = 1  # blue: its side colours (violet, cyan) are unlike the grey ground and light sky


def _hue_pixels(image: np.ndarray, rgb) -> int:
    """Pixels of the hue of ``rgb`` (within a third of the side hue turn), clearly coloured:
    shading and translucency over the grey ground change lightness and saturation, not hue."""
    pixels = image.reshape(-1, 3).astype(np.float64) / 255.0
    high, low = pixels.max(axis=1), pixels.min(axis=1)
    saturation = (high - low) / np.maximum(high, 1e-9)
    r, g, b = pixels.T
    hue = np.degrees(np.arctan2(np.sqrt(3) * (g - b), 2 * r - g - b)) % 360   # HSV-like hue
    target = np.degrees(np.arctan2(np.sqrt(3) * (rgb[1] - rgb[2]),
                                   2 * rgb[0] - rgb[1] - rgb[2])) % 360
    near = np.abs((hue - target + 180) % 360 - 180) < SIDE_HUE_TURN_DEG / 3
    return int(np.count_nonzero(near & (saturation > 0.25) & (high > 0.3)))


def _screen_pixels(image: np.ndarray) -> tuple[int, float]:
    """(pixels of the screen's bezel colour, grey-level spread of what the bezel encloses)."""
    bezel = np.array([(BEZEL_COLOUR >> s) & 255 for s in (16, 8, 0)])
    match = np.all(np.abs(image.astype(int) - bezel) <= 6, axis=2)
    if match.sum() < 50:
        return int(match.sum()), 0.0
    rows, cols = np.nonzero(match)
    inside = image[rows.min() + 8:rows.max() - 8, cols.min() + 8:cols.max() - 8]
    return int(match.sum()), float(inside.std()) if inside.size else 0.0


def test_chromium_shows_both_sides_of_a_body_in_their_colours(tmp_path):
    joints = pose_joints_m(np.r_[1.0, np.zeros(54)][None])[0] + [0.0, 0.95, -4.0]
    colours = body_colours(TRACK)
    with MeshcatView(print_url=False) as view, Chromium(tmp_path / "profile") as browser:
        browser.open(view.web_url)
        time.sleep(3)
        empty = browser.screenshot(tmp_path / "empty.png")
        view.write(TrackedPose(0, 0.0, TRACK, np.zeros(55), np.zeros(55), False, joints))
        view.end_frame(0)
        time.sleep(2)
        drawn = browser.screenshot(tmp_path / "body.png")
    for side in (1, 2):
        assert _hue_pixels(empty, colours[side]) < 20
        assert _hue_pixels(drawn, colours[side]) > 150, f"side {side}"


@pytest.mark.slow
def test_track_view_shows_bodies_and_video_from_start_to_end(tmp_path):
    """`track --view` on the sample (12 s, played at its own speed): screenshots at 2.5 s,
    6.5 s and 10.5 s of one page each show the left and right colours of track 0 and the video
    screen (its bezel around a textured picture); the run keeps the video's pace; when it
    ends, the viewer's port is closed."""
    proc = subprocess.Popen([sys.executable, "-m", "tracker.cli", str(SAMPLE), "--view",
                             "--quiet", "--json", str(tmp_path / "v.json")],
                            env={**os.environ, "PYTHONPATH": str(ROOT)}, cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    shots = []
    try:
        line = proc.stdout.readline()
        assert line.startswith("meshcat viewer: http://127.0.0.1:"), line + proc.stderr.read()
        url, started = line.split(": ", 1)[1].strip(), time.monotonic()
        with Chromium(tmp_path / "profile") as browser:
            browser.open(url)
            for name, at_s in (("start", 2.5), ("middle", 6.5), ("end", 10.5)):
                time.sleep(max(0.0, at_s - (time.monotonic() - started)))
                assert proc.poll() is None, "track ended early: not played at the video's speed"
                shots.append((name, browser.screenshot(tmp_path / f"view_{name}.png")))
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    keep = os.environ.get("VIEW_SCREENSHOTS")
    if keep:
        for name, _ in shots:
            shutil.copy(tmp_path / f"view_{name}.png", Path(keep) / f"view_{name}.png")
    colours = body_colours(0)
    for name, image in shots:
        assert _hue_pixels(image, colours[1]) > 150, f"{name}: left side (orange) not seen"
        assert _hue_pixels(image, colours[2]) > 150, f"{name}: right side (magenta) not seen"
        bezel, spread = _screen_pixels(image)
        assert bezel > 500 and spread > 10, f"{name}: video screen not seen ({bezel}, {spread})"
    import json
    summary = json.loads((tmp_path / "v.json").read_text())
    assert summary["frames"] == 361 and summary["fps"] > 0.95 * summary["video_fps"]
    port = int(url.split(":")[2].split("/")[0])
    with socket.socket() as s:
        assert s.connect_ex(("127.0.0.1", port)) != 0      # server gone with the command
