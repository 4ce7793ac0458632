"""scripts/evaluate_real.py's trials, MediaPipe peer options and 8-limb-angle table: refusals
before any work, and the table and summary line of a hand-made result."""
from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from conftest import load_script, refused_in_one_line
from sequences.measures import LIMB_ANGLE_NAMES, angle_measures
from sequences.pose2sim import TRIALS, VIEWS, trial_roots


@pytest.fixture(scope="module")
def evaluate_real():
    return load_script("evaluate_real")


def test_trial_names_mean_the_shared_trials_and_anything_else_a_folder(tmp_path):
    assert list(trial_roots("all")) == ["balancing", "swings"]
    assert trial_roots("swings") == {"swings": TRIALS["swings"]}
    assert trial_roots(tmp_path / "mine") == {"mine": tmp_path / "mine"}


def test_mediapipe_that_cannot_be_scored_is_refused_before_any_work(evaluate_real, tmp_path,
                                                                    capsys):
    trial = ["--trial", str(tmp_path / "none")]
    if importlib.util.find_spec("mediapipe") is None:
        err = refused_in_one_line(evaluate_real, trial + ["--peer", "mediapipe"], capsys)
        assert "mediapipe is not installed" in err and "--peer-results" in err
    (tmp_path / "mp" / "none").mkdir(parents=True)
    err = refused_in_one_line(evaluate_real, trial + ["--peer-results", str(tmp_path / "mp")],
                              capsys)
    assert "no none/cam01.npz" in err and "run_mediapipe.py" in err


def test_mask_sheets_and_plots_need_one_trial(evaluate_real, tmp_path, capsys):
    err = refused_in_one_line(evaluate_real, ["--masks", str(tmp_path / "m.png")], capsys)
    assert "one trial" in err


def _measures(shift: float, frames: int = 50) -> dict:
    t = np.arange(frames)[:, None]
    truth = 40 + 10 * np.sin(t / 5 + np.arange(8))
    return angle_measures(truth + shift, truth, LIMB_ANGLE_NAMES, np.full(8, 30.0))


def _result(peer: bool) -> dict:
    limbs = {"mean": _measures(5.0), "pooled": _measures(5.0, 200)}
    view = {"filtered": {"frames": 50, "limbs": _measures(5.0), "heading": {"rms_deg": 33.0}}}
    result = {"views": {v: view for v in VIEWS}, "limbs": limbs,
              "limbs_smoothed": {"mean": _measures(3.0), "pooled": _measures(3.0, 200)},
              "cross_view": {"filtered": {"heading_rms_deg": 99.4},
                             "smoothed": {"heading_rms_deg": 88.0}}}
    if peer:
        result["peer"] = {"views": {v: {"frames": 50, "limbs": _measures(-2.0),
                                        "heading": {"rms_deg": 12.0}} for v in VIEWS},
                          "limbs": {"mean": _measures(-2.0), "pooled": _measures(-2.0, 200)},
                          "cross_view_heading_rms_deg": 20.2}
    return result


def test_the_limb_table_has_ours_and_the_peer_per_view_and_a_summary(evaluate_real):
    lines = evaluate_real.format_limb_table("balancing", _result(peer=True)).splitlines()
    assert lines[0].startswith("balancing: 8 limb angles")
    rows = [line for line in lines if line.startswith(("ours ", "MediaPipe ")) and "|" in line]
    assert len(rows) == 2 * (len(VIEWS) + 2)
    assert rows[0].startswith("ours cam01") and "MediaPipe pooled" in rows[-1]
    assert " 1.00 " in rows[0] and "  5.0 " in rows[0] and "   33" in rows[0]
    summary = lines[-1]
    assert summary.startswith("balancing summary: ours mean corr 1.00, mean error 5.0 deg, "
                              "cross-view heading RMS 99, flexion error 5.0")
    assert "training-mean" in summary and "MediaPipe mean corr 1.00, mean error 2.0" in summary
    assert ("ours smoothed (track's JSON) mean corr 1.00, mean error 3.0 deg, cross-view "
            "heading RMS 88, flexion error 3.0") in summary
    assert "smoothed poses (track's JSON and BVH): mean corr 1.00, mean error 3.0" in lines[-3]
    assert "cross-view heading RMS 20" in summary


def test_the_summary_gives_flexion_for_balancing_only_and_the_peer_when_scored(evaluate_real):
    summary = evaluate_real.summary_line("swings", _result(peer=False))
    assert summary.startswith("swings summary: ours mean corr 1.00, mean error 5.0 deg")
    assert "flexion" not in summary and "MediaPipe" not in summary
