"""scripts/evaluate_real.py's --masks: refused before any tracking when it cannot be written,
and the sheet it writes."""
from __future__ import annotations

import shutil

import cv2
import numpy as np
import pytest

from conftest import load_script
from sequences.pose2sim import REFERENCE_TRC


@pytest.fixture(scope="module")
def evaluate_real():
    return load_script("evaluate_real")


def test_unwritable_mask_sheets_and_plots_are_refused_in_one_line_before_tracking(
        evaluate_real, tmp_path, capsys):
    for option in ("--masks", "--plot"):
        check = evaluate_real._png_path_problem
        assert check(option, None) is None and check(option, tmp_path / "m.png") is None
        assert "PNG" in check(option, tmp_path / "m.jpg")
        # main refuses at once, without the trial (a missing trial would fail later).
        for argv, words in (([option, str(tmp_path / "m")], "PNG"),
                            ([option, str(tmp_path / "missing" / "m.png")], "no folder"),
                            ([option, str(tmp_path / "m.png"), "--json", str(tmp_path / "m.png")],
                             "")):
            with pytest.raises(SystemExit) as stop:
                evaluate_real.main(["--trial", str(tmp_path / "none")] + argv)
            assert stop.value.code == 2
            err = capsys.readouterr().err.strip()
            assert words in err and "\n" not in err


def test_the_plot_has_a_row_per_view(evaluate_real, tmp_path):
    pytest.importorskip("matplotlib")
    from lab.report import plot_real_video
    t = np.arange(50)
    view = {"view": "cam01", "frames": t, "reference": np.full((50, 4), 40.0),
            "filtered": np.full((50, 4), 50.0), "smoothed": np.full((50, 4), 45.0),
            "constant": np.full(4, 30.0), "reference_heading": np.zeros(50),
            "filtered_heading": np.full(50, 20.0), "smoothed_heading": np.full(50, 10.0)}
    path = tmp_path / "plot.png"
    plot_real_video(path, [view, dict(view, view="cam02")], ["L knee", "R knee", "L elbow",
                                                              "R elbow"])
    image = cv2.imread(str(path))
    assert image is not None and image.shape[0] > 250 and image.shape[1] > 800


def test_the_mask_sheet_has_one_row_per_view(evaluate_real, tmp_path):
    tile = np.zeros((evaluate_real._TILE_PX, 40), np.uint8)
    tile[20:140, 10:30] = 255
    path = tmp_path / "sheet.png"
    evaluate_real.write_mask_sheet(path, [[tile] * 8, [tile[:, :30]] * 8])
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    assert image.shape == (2 * (evaluate_real._TILE_PX + 6), 8 * 46)
    assert (image == 255).sum() == 16 * 120 * 20
    with pytest.raises(evaluate_real.Pose2SimError, match="cannot write"):
        evaluate_real.write_mask_sheet(tmp_path / "no" / "sheet.png", [[tile]])


def _view(err: float, train: float) -> dict:
    flexion = {"error_per_angle": [err] * 4, "error": err, "truth_mean_error_mean": 13.0,
               "constant_error_mean": train, "corr_per_angle": [0.5] * 4}
    heading = {"within_45": 1.0, "rms_deg": 10.0}
    smoothed = {"error_per_angle": [err - 1] * 4, "error": err - 1.0,
                "corr_per_angle": [0.6, 0.5, 0.4, 0.3]}
    lagged = {"error_per_angle": [err - 0.5] * 4, "error": err - 0.5,
              "corr_per_angle": [0.55, 0.45, 0.35, 0.25]}
    return {"tracks": 1, "filtered": {"frames": 100, "flexion": flexion, "heading": heading},
            "raw": {"frames": 100, "flexion": flexion, "heading": heading},
            "smoothed": {"frames": 100, "flexion": smoothed,
                         "heading": {"within_45": 0.5, "rms_deg": 9.0}},
            "lagged": {"frames": 100, "flexion": lagged,
                       "heading": {"within_45": 0.75, "rms_deg": 9.5}}}


def _result(evaluate_real) -> dict:
    """An evaluation result of two views (20 and 30 degrees; train 22 and 24) for the table."""
    per_view = {"cam01": _view(20.0, 22.0), "cam02": _view(30.0, 24.0)}
    cross = {"frames": 100, "heading_rms_deg": 50.0, "random_heading_rms_deg": 104.0,
             "body_angle_disagreement_deg": 8.0}
    return {"views": per_view, "mean": evaluate_real._means(per_view),
            "cross_view": {"filtered": cross, "raw": cross, "smoothed": cross}}


def test_the_table_puts_both_constants_beside_the_error(evaluate_real):
    result = _result(evaluate_real)
    assert result["mean"]["training_mean_flexion_error"] == pytest.approx(23.0)
    lines = evaluate_real.format_table(result).splitlines()
    assert "train" in lines[1]
    assert lines[3].split("|")[1].split()[-3:] == ["20.0", "13.0", "22.0"]
    assert lines[5].split("|")[1].split()[-3:] == ["25.0", "13.0", "23.0"]
    assert ("smoothed poses (track's JSON and BVH): flexion error 24.0 deg (mean over views), "
            "corr. 0.60 / 0.50 / 0.40 / 0.30, heading within 45 deg 50 / 50 %") in lines
    assert ("lagged poses (track --lag 0.5, the live view's): flexion error 24.5 deg (mean over "
            "views), corr. 0.55 / 0.45 / 0.35 / 0.25, heading within 45 deg 75 / 75 %") in lines
    from tracker.cli import VIEW_LAG_S
    assert evaluate_real.LAG_S == VIEW_LAG_S
    for view in result["views"].values():          # a result saved before they were measured
        del view["lagged"]
    assert "lagged poses" not in evaluate_real.format_table(result)


def test_the_table_says_when_the_silhouettes_were_corrected_by_the_reference(evaluate_real):
    result = _result(evaluate_real)
    assert "corrected by the reference" not in evaluate_real.format_table(result)
    for view in result["views"].values():
        view["reference_masks"] = "cut"
    assert "corrected by the reference (cut; a diagnostic" in evaluate_real.format_table(result)
    for mode in ("drawn", "rendered"):
        assert evaluate_real.build_parser().parse_args(["--reference-masks", mode]) \
            .reference_masks == mode


def test_the_table_gives_the_body_angles_beside_the_constant_where_measured(evaluate_real):
    result = _result(evaluate_real)
    assert "body_error_deg" not in result["mean"]
    assert "53 body angles against" not in evaluate_real.format_table(result)
    for error, view in zip((9.0, 11.0), result["views"].values()):
        view["filtered"]["body"] = {"error_deg": error, "constant_error_deg": 12.5,
                                    "offset_free_error_deg": error - 4.0,
                                    "constant_offset_free_error_deg": 6.0,
                                    "top_angles": {"mean": 0.25}}
    per_view = result["views"]
    assert evaluate_real._means(per_view)["body_error_deg"] == pytest.approx(10.0)
    assert "cam01 9.0 / 12.5 / 5.0 / 6.0 / 0.25, cam02 11.0 / 12.5 / 7.0 / 6.0 / 0.25" in \
        evaluate_real.format_table(result)


def test_a_reference_lacking_a_keypoint_the_fit_needs_is_a_one_line_error(
        evaluate_real, pose2sim_trial, tmp_path, capsys):
    copy = tmp_path / "balancing"
    shutil.copytree(pose2sim_trial, copy)
    trc = copy / REFERENCE_TRC
    lines = trc.read_text().splitlines()
    lines[3] = lines[3].replace("LBigToe", "LToeTip")
    trc.write_text("\n".join(lines) + "\n")
    assert evaluate_real.main(["--trial", str(copy)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("evaluate_real: error: the keypoints lack ['LBigToe']")
    assert not any("Traceback" in line for line in err)
