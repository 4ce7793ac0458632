"""scripts/draw_fitted_body.py: one-line errors, and the drawing on the real trial (skips
without ../shared)."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import cv2
import pytest

from conftest import SHARED

_SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "draw_fitted_body.py"
TRIAL = SHARED / "data" / "pose2sim" / "balancing"


@pytest.fixture(scope="module")
def script():
    spec = importlib.util.spec_from_file_location("draw_fitted_body", _SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_bad_names_and_trials_are_one_line_errors(script, tmp_path, capsys):
    assert script.main([str(tmp_path / "x.gif")]) == 1
    assert script.main([str(tmp_path / "x.jpg"), "--trial", str(tmp_path / "none")]) == 1
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 2 and all(e.startswith("draw_fitted_body: error: ") for e in errors)
    assert "x.gif" in errors[0] and "not found" in errors[1]


def test_the_outline_is_drawn_over_each_view(script, tmp_path, capsys):
    if not TRIAL.is_dir():
        pytest.skip(f"Pose2Sim trial not found at {TRIAL} (needs ../shared beside the repo)")
    assert script.main([str(tmp_path / "x.jpg"), "--frames", "500"]) == 1
    assert "no reference" in capsys.readouterr().err
    out = tmp_path / "fit.png"
    assert script.main([str(out), "--frames", "30", "70"]) == 0
    image = cv2.imread(str(out))
    assert image.shape[0] == 4 * script._TILE_PX                  # a row per view
    red = (image[..., 2] > 200) & (image[..., 1] < 60) & (image[..., 0] < 60)
    assert red.sum() > 4 * 2 * 200                                # an outline in every tile
