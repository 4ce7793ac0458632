"""scripts/draw_fitted_body.py: one-line errors, and the drawing on the real trial (skips
without ../shared)."""
from __future__ import annotations

import cv2
import pytest

from conftest import load_script


@pytest.fixture(scope="module")
def script():
    return load_script("draw_fitted_body")


def test_bad_names_and_trials_are_one_line_errors(script, tmp_path, capsys):
    assert script.main([str(tmp_path / "x.gif")]) == 1
    assert script.main([str(tmp_path / "x.jpg"), "--trial", str(tmp_path / "none")]) == 1
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 2 and all(e.startswith("draw_fitted_body: error: ") for e in errors)
    assert "x.gif" in errors[0] and "not found" in errors[1]


def test_the_outline_is_drawn_over_each_view(script, pose2sim_trial, tmp_path, capsys):
    assert script.main([str(tmp_path / "x.jpg"), "--trial", str(pose2sim_trial),
                        "--frames", "500"]) == 1
    assert "no reference" in capsys.readouterr().err
    out = tmp_path / "fit.png"
    assert script.main([str(out), "--trial", str(pose2sim_trial), "--frames", "30", "70"]) == 0
    image = cv2.imread(str(out))
    assert image.shape[0] == 4 * script._TILE_PX                  # a row per view
    red = (image[..., 2] > 200) & (image[..., 1] < 60) & (image[..., 0] < 60)
    assert red.sum() > 4 * 2 * 200                                # an outline in every tile
