"""Evaluation: measures on hand-made sequences with known answers, the generic filter, and a
small end-to-end evaluation (rendered CMU frames; the paper's data) with its report."""
from __future__ import annotations

import json

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
from lab.evaluation import (AnkurOptions, EvaluatedSequence, angle_parts, ankur_sequence,
                                evaluate, heading_ambiguity, measure_angles, measure_points,
                                rendered_sequence)
from regressor.angles import angles_to_pose
from tracker.tracks.filtering import ConstantVelocityFilter, FilterError
from tracker.tracks.filterpy_runs import forward
from lab.report import format_table
from tracker.pipeline import TrackerSettings

PER_FRAME_MODEL = DEFAULT_MODEL_PATH.with_name("per_frame_model.npz")


@pytest.fixture(autouse=True, scope="module")
def one_blas_thread():
    with threadpool_limits(limits=1, user_api="blas"):
        yield


def poses(angles: np.ndarray) -> np.ndarray:
    """(T, 54) angles deg -> (T, 55) pose vectors with unit (cos, sin)."""
    return angles_to_pose(angles)


def test_constant_angle_offset_gives_that_error_everywhere():
    rng = np.random.default_rng(0)
    truth = rng.uniform(-150, 150, (20, 54))
    m = measure_angles(poses(truth + 10.0), poses(truth))
    assert m["error"] == pytest.approx(10.0)
    assert m["heading_rms_deg"] == pytest.approx(10.0)
    assert m["accel_error"] == pytest.approx(0.0, abs=1e-9)
    assert set(m["per_part"]) == set(angle_parts())
    assert all(v == pytest.approx(10.0) for v in m["per_part"].values())


def test_errors_and_jitter_wrap_around_180():
    t = np.arange(30, dtype=float)
    truth = np.zeros((30, 54))
    truth[:, 0] = 170.0 + 2.0 * t          # heading crosses +180 at frame 5
    truth[:, 5] = -175.0 - 1.0 * t         # a joint angle crosses -180
    est = truth.copy()
    est[:, 0] += 4.0                       # 4 deg off, across the seam too
    m = measure_angles(poses(est), poses(truth))
    assert m["heading_rms_deg"] == pytest.approx(4.0)
    assert m["per_part"]["heading"] == pytest.approx(4.0)
    # Constant-rate motion has no second difference, however often it wraps.
    assert m["jitter"] == pytest.approx(0.0, abs=1e-9)
    assert evaluate(EvaluatedSequence("s", "deg", poses(truth), {"stacked": poses(est)})
                    )["ground_truth_jitter"] == pytest.approx(0.0, abs=1e-9)


def test_alternating_error_has_known_jitter_and_acceleration_error():
    truth = np.zeros((10, 54))
    est = truth + np.where(np.arange(10) % 2, 1.0, -1.0)[:, None]   # +-1 deg zig-zag
    m = measure_angles(poses(est), poses(truth))
    assert m["error"] == pytest.approx(1.0)
    assert m["jitter"] == pytest.approx(4.0)          # |1 - 2(-1) + 1| = 4
    assert m["accel_error"] == pytest.approx(4.0)


def test_point_measures_on_known_offsets_and_motion():
    T, P = 12, 21
    t = np.arange(T, dtype=float)[:, None]
    truth = np.repeat(0.5 * t**2, 3 * P, axis=1)            # constant acceleration
    est = truth + np.tile([3.0, 4.0, 0.0], P)               # 5 units off at every point
    m = measure_points(est, truth)
    assert m["error"] == pytest.approx(5.0)
    assert m["accel_error"] == pytest.approx(0.0, abs=1e-9)
    assert m["jitter"] == pytest.approx(np.sqrt(3.0))       # second difference 1 per axis
    assert len(m["per_part"]) == P and m["per_part"]["point 0"] == pytest.approx(5.0)


def test_heading_ambiguity_counts_large_errors_in_ambiguous_frames():
    truth = np.zeros((10, 54))
    est = truth.copy()
    est[[1, 2, 3], 0] = 180.0      # front/back flips
    est[7, 0] = 60.0               # one large error in a clear frame
    est[8, 0] = 10.0               # a small one
    ambiguous = np.zeros(10, bool)
    ambiguous[[1, 2, 3, 4]] = True
    a = heading_ambiguity(poses(est), poses(truth), ambiguous)
    assert (a["large_error_frames"], a["large_errors_in_ambiguous"]) == (4, 3)
    assert a["share_of_large_in_ambiguous"] == pytest.approx(0.75)
    assert a["heading_rms_ambiguous_deg"] == pytest.approx(np.sqrt(3 * 180.0**2 / 4))
    assert a["heading_rms_unambiguous_deg"] == pytest.approx(np.sqrt((60.0**2 + 10.0**2) / 6))


def _walk_like_truth(T: int = 60) -> np.ndarray:
    """Pose vectors (T, 55) whose body angles swing sinusoidally (degrees), heading fixed."""
    t = np.arange(T)[:, None]
    angles = 20.0 * np.sin(t / 5.0 + np.arange(54)[None] * 0.3)
    angles[:, 0] = 30.0
    return poses(angles)


def test_honest_measures_tell_a_constant_output_from_a_tracking_one():
    truth = _walk_like_truth()
    constant = truth.mean(axis=0)
    seq = EvaluatedSequence("hand-made", "deg", truth,
                            {"kalman": truth.copy(), "stacked": np.tile(constant, (len(truth), 1))},
                            constant=constant)
    result = evaluate(seq)
    perfect, flat = result["methods"]["kalman"], result["methods"]["stacked"]
    assert perfect["skill"] == pytest.approx(1.0) and perfect["top_angles"]["mean"] == pytest.approx(1.0)
    assert perfect["mpjpe_mm"] == pytest.approx(0.0, abs=1e-6)
    assert flat["skill"] == pytest.approx(0.0, abs=1e-9) and flat["top_angles"]["mean"] == 0.0
    table = format_table(result)
    assert "constant" in table and "skill" in table and "corr8" in table


def test_point_sequences_get_a_constant_baseline_and_skill():
    rng = np.random.default_rng(1)
    truth = rng.normal(size=(30, 9))
    seq = EvaluatedSequence("points", "units", truth, {"kalman": truth + 0.0},
                            constant=truth.mean(axis=0))
    m = evaluate(seq)["methods"]["kalman"]
    assert m["skill"] == pytest.approx(1.0) and m["constant_error"] > 0


def test_constant_velocity_filter_reduces_noise_on_points():
    rng = np.random.default_rng(0)
    t = np.arange(200)[:, None] / 30.0
    truth = np.hstack([np.sin(2 * np.pi * 0.5 * t + k) * 10 for k in range(6)])
    noisy = truth + rng.normal(0, 1.0, truth.shape)
    cv = ConstantVelocityFilter(6, 30.0, R=np.ones(6), q=(10 * (np.pi) ** 2) ** 2, rate_std=50.0)
    filtered, smoothed = forward(cv, noisy), cv.smooth(noisy, window=64, lag=32)
    rms = lambda a: np.sqrt(((a - truth) ** 2).mean())  # noqa: E731
    assert rms(smoothed) < rms(filtered) < 0.8 * rms(noisy)
    with pytest.raises(FilterError, match=r"shape \(T, 6\)"):
        forward(cv, noisy[:, :5])
    with pytest.raises(FilterError, match="NaN"):
        cv.smooth(np.full((3, 6), np.nan))


def test_end_to_end_on_rendered_frames_with_report(cmu_bvh_dir, tmp_path):
    pytest.importorskip("matplotlib")
    from lab.report import format_table, write_report
    stacked, per_frame = load_pose_model(), load_pose_model(PER_FRAME_MODEL)
    seq = rendered_sequence(cmu_bvh_dir / "16_11.bvh", stacked, per_frame, spiral_deg_per_s=30.0,
                            frames=40)
    result = evaluate(seq)
    assert result["frames"] == 40 and result["units"] == "deg"
    m = result["methods"]
    assert set(m) == {"per_frame", "stacked", "kalman", "smoothed"}
    assert all(np.isfinite(v["error"]) and 0 < v["error"] < 30 for v in m.values())
    assert m["kalman"]["jitter"] < m["stacked"]["jitter"]
    assert m["smoothed"]["jitter"] < m["kalman"]["jitter"]
    assert set(result["ambiguity"]) == {"per_frame", "stacked", "kalman"}
    readme = write_report(tmp_path, seq, result)
    assert "| kalman |" in readme.read_text()
    assert all((tmp_path / f).stat().st_size > 1000 for f in ("heading.png", "parts.png",
                                                               "jitter.png"))
    saved = json.loads((tmp_path / "result.json").read_text())
    assert saved["frames"] == 40
    # the report records the joints' inflation the filters used (the model's: it gives
    # canonical pairs), not the setting's "model's choice" placeholder
    assert saved["settings"]["filter"]["ambiguous_joint_factor"] == \
        TrackerSettings().joint_factor(stacked) == 2.0
    assert "per_frame" in format_table(result)


def test_end_to_end_on_the_papers_data(ankur_mat):
    options = AnkurOptions(noise=0.1, min_gain=400.0, cv_folds=2, r_scale=1.0)
    result = evaluate(ankur_sequence(ankur_mat, options, frames=60))
    m = result["methods"]
    assert result["units"] == "units" and result["frames"] == 60
    assert "heading_rms_deg" not in m["kalman"]
    # The README's mean-pose baseline is 6.34 units over the whole test sequence.
    assert all(v["error"] < 5.0 for v in m.values())
    assert m["kalman"]["jitter"] < m["stacked"]["jitter"]
