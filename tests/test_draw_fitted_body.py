"""scripts/draw_fitted_body.py: one-line errors, and the drawing on the real trial (skips
without ../shared)."""
from __future__ import annotations

import cv2
import pytest

from conftest import load_script, refused_in_one_line


@pytest.fixture(scope="module")
def script():
    return load_script("draw_fitted_body")


def test_bad_names_and_trials_are_one_line_errors(script, tmp_path, capsys):
    # Options, refused by the parser (exit 2) before any work.
    assert "x.gif" in refused_in_one_line(script, [str(tmp_path / "x.gif")], capsys)
    err = refused_in_one_line(script, [str(tmp_path / "x.jpg"), "--trial",
                                       str(tmp_path / "none")], capsys)
    assert f"--trial {tmp_path / 'none'}: no such folder" in err


@pytest.mark.slow
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
