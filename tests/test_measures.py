"""Honest measures (sequences.measures) on hand-made sequences with known answers."""
from __future__ import annotations

import numpy as np
import pytest

from regressor.angles import wrap_deg
from sequences.measures import (FLEXION_NAMES, MM_PER_CMU_UNIT, MeasureError,
                                body_angle_error, constant_error, correlation, flexion_deg,
                                flexion_from_points, flexion_measures, joints_mm,
                                most_moving_angles, mpjpe, offset_free_error, pa_mpjpe,
                                pose_measures, procrustes_align, skill,
                                top_angle_correlation, unwrap_about_mean)
from sequences.pose_vector import POSE_DIM, pose_vector_names

NAMES = pose_vector_names()


def _col(name: str) -> int:
    return NAMES.index(name)


def _rest(T: int = 1) -> np.ndarray:
    """Rest poses (T, 55) facing the camera."""
    v = np.zeros((T, POSE_DIM))
    v[:, 0] = 1.0
    return v


def _moving(T: int = 60) -> np.ndarray:
    """Poses (T, 55) whose heading turns and 8 body angles swing with different amplitudes."""
    t = np.linspace(0, 2 * np.pi, T)
    v = _rest(T)
    v[:, 0], v[:, 1] = np.cos(t / 2), np.sin(t / 2)
    v[:, _col("LeftLeg_z")] = 40 + 35 * np.sin(t)
    v[:, _col("RightLeg_z")] = 40 + 30 * np.cos(t)
    v[:, _col("LeftForeArm_y")] = 50 + 25 * np.sin(2 * t)
    v[:, _col("RightForeArm_y")] = -50 + 24 * np.cos(2 * t)
    v[:, _col("LeftUpLeg_x")] = 20 * np.sin(t + 1)
    v[:, _col("RightUpLeg_x")] = 15 * np.sin(t + 2)
    v[:, _col("Spine1_y")] = 10 * np.sin(3 * t)
    v[:, _col("Head_x")] = 5 * np.sin(4 * t)
    return v


def test_straight_limbs_have_zero_flexion():
    assert np.allclose(flexion_deg(_rest()), 0.0, atol=1e-3)   # offsets rounded in the file


def test_right_angle_knee_and_elbow_give_90_degrees():
    v = _rest()
    v[0, _col("LeftLeg_z")] = 90.0         # z is perpendicular to the CMU thigh
    v[0, _col("RightForeArm_y")] = -90.0   # y is perpendicular to the CMU forearm
    flex = flexion_deg(v)[0]
    assert np.allclose(flex, [90.0, 0.0, 0.0, 90.0], atol=1e-3)


def test_flexion_from_points_straight_and_folded():
    p, m = np.zeros(3), np.array([0.0, -1.0, 0.0])
    assert flexion_from_points(p, m, [0.0, -2.0, 0.0]) == pytest.approx(0.0)
    assert flexion_from_points(p, m, [1.0, -1.0, 0.0]) == pytest.approx(90.0)
    assert flexion_from_points(p, m, [0.0, -0.5, 0.0]) == pytest.approx(180.0)


def test_perfect_estimate_scores_skill_one_correlation_one_mpjpe_zero():
    truth = _moving()
    out = pose_measures(truth, truth, _rest()[0])
    assert out["error_deg"] == pytest.approx(0.0)
    assert out["skill"] == pytest.approx(1.0)
    assert out["top_angles"]["mean"] == pytest.approx(1.0)
    assert out["flexion"]["error"] == pytest.approx(0.0, abs=1e-9)
    assert out["flexion"]["corr"] == pytest.approx(1.0)
    assert out["mpjpe_mm"] == pytest.approx(0.0, abs=1e-6)
    assert out["pa_mpjpe_mm"] == pytest.approx(0.0, abs=1e-6)
    assert out["heading_rms_deg"] == pytest.approx(0.0, abs=1e-9)


def test_constant_output_scores_skill_zero_and_correlation_zero():
    truth = _moving()
    const = truth.mean(axis=0)
    est = np.tile(const, (len(truth), 1))
    out = pose_measures(est, truth, const)
    assert out["skill"] == pytest.approx(0.0)
    assert out["error_deg"] == pytest.approx(out["constant_error_deg"])
    assert out["top_angles"]["per_angle"] == [0.0] * 8
    assert out["flexion"]["corr_per_angle"] == [0.0] * 4


def test_skill_of_half_the_constant_error_is_one_half():
    assert skill(2.0, 4.0) == pytest.approx(0.5)
    with pytest.raises(MeasureError, match="baseline"):
        skill(1.0, 0.0)


def test_constant_error_is_the_mean_absolute_body_angle_offset():
    truth = _rest(5)
    const = _rest()[0]
    const[_col("LeftLeg_z")] = 53.0            # one of 53 body angles off by 53 degrees
    assert constant_error(truth, const) == pytest.approx(1.0)


def test_error_wraps_at_180():
    a, b = _rest(3), _rest(3)
    a[:, _col("LeftArm_z")] = 179.0
    b[:, _col("LeftArm_z")] = -179.0
    assert body_angle_error(a, b) == pytest.approx(2.0 / 53)


def test_offset_free_error_forgives_a_fixed_offset_per_angle_and_nothing_else():
    truth = _moving()
    shifted = truth.copy()
    shifted[:, _col("LeftForeArm_y")] += 20.0        # a subject's own way of holding an arm
    shifted[:, _col("RightFoot_x")] -= 10.6
    assert body_angle_error(shifted, truth) == pytest.approx(30.6 / 53)
    assert offset_free_error(shifted, truth) == pytest.approx(0.0, abs=1e-9)
    lagging = np.roll(truth, 5, axis=0)              # the same motion, late: not forgiven
    assert offset_free_error(lagging, truth) > 0.1


def test_offset_free_error_of_a_still_pose_is_the_truths_own_deviation():
    truth = _rest(4)
    truth[:, _col("LeftLeg_z")] = [30.0, 50.0, 30.0, 50.0]   # mean 40, every frame 10 off it
    still = np.tile(_rest()[0], (4, 1))
    assert offset_free_error(still, truth) == pytest.approx(10.0 / 53)
    m = pose_measures(truth, truth, _rest()[0])
    assert m["offset_free_error_deg"] == pytest.approx(0.0, abs=1e-9)
    assert m["constant_offset_free_error_deg"] == pytest.approx(10.0 / 53)


def test_offset_free_error_wraps_at_180():
    truth = _rest(4)
    truth[:, _col("LeftArm_z")] = [170.0, -170.0, 175.0, -175.0]
    shifted = truth.copy()
    shifted[:, _col("LeftArm_z")] = wrap_deg(truth[:, _col("LeftArm_z")] + 15.0)  # past 180
    assert offset_free_error(shifted, truth) == pytest.approx(0.0, abs=1e-9)


def test_correlation_of_an_angle_crossing_180_is_one():
    t = np.linspace(0, 1, 50)
    truth = _rest(50)
    truth[:, _col("LeftArm_z")] = 170 + 20 * t           # 170 .. 190 = 170 .. -170 wrapped
    truth[:, 2:] = (truth[:, 2:] + 180) % 360 - 180
    est = truth.copy()
    est[:, _col("LeftArm_z")] = (truth[:, _col("LeftArm_z")] + 3 + 180) % 360 - 180
    out = top_angle_correlation(est, truth, m=1)
    assert out["angles"] == ["LeftArm_z"]
    assert out["truth_std_deg"][0] == pytest.approx(np.std(20 * t))
    assert out["per_angle"][0] == pytest.approx(1.0)


def test_unwrap_about_mean_keeps_values_within_180_of_the_circular_mean():
    a = np.array([[170.0], [-170.0], [180.0]])
    assert np.allclose(unwrap_about_mean(a)[:, 0], [170.0, 190.0, 180.0])


def test_most_moving_angles_are_ranked_by_truth_std_and_exclude_heading():
    cols = most_moving_angles(_moving(), m=3)
    assert [NAMES[c] for c in cols] == ["LeftLeg_z", "RightLeg_z", "LeftForeArm_y"]


def test_correlation_is_zero_where_a_series_is_constant():
    a = np.column_stack([np.arange(5.0), np.ones(5)])
    assert np.allclose(correlation(a, a), [1.0, 0.0])
    assert correlation(a, -a)[0] == pytest.approx(-1.0)


def test_flexion_measures_report_the_truths_own_mean_as_a_constant():
    truth = np.column_stack([np.linspace(0, 40, 9)] * 4)
    out = flexion_measures(truth + 5.0, truth, constant_flexion=np.full(4, 20.0))
    assert out["names"] == list(FLEXION_NAMES)
    assert out["error"] == pytest.approx(5.0)
    assert out["corr"] == pytest.approx(1.0)
    expected = np.abs(np.linspace(0, 40, 9) - 20).mean()
    assert out["truth_mean_error_mean"] == pytest.approx(expected)
    assert out["constant_error_mean"] == pytest.approx(expected)


def test_mpjpe_is_in_millimetres():
    truth = _rest()
    est = truth.copy()
    est[0, _col("LeftLeg_z")] = 180.0          # the shank folds back onto the thigh
    j_est, j_tru = joints_mm(est), joints_mm(truth)
    shank_mm = np.hypot(2.49236, 6.8477) * MM_PER_CMU_UNIT
    assert mpjpe(j_est, j_tru) == pytest.approx(2 * shank_mm / 15, rel=1e-6)
    assert 400 < shank_mm < 420     # a 41 cm shank


def test_pa_mpjpe_ignores_a_global_rotation_scale_and_shift():
    rng = np.random.default_rng(0)
    truth = joints_mm(_moving(10))
    angle = np.radians(70)
    R = np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0],
                  [-np.sin(angle), 0, np.cos(angle)]])
    moved = 1.7 * truth @ R.T + rng.normal(size=3) * 100
    assert mpjpe(moved, truth) > 100
    assert pa_mpjpe(moved, truth) == pytest.approx(0.0, abs=1e-6)
    assert np.allclose(procrustes_align(moved, truth), truth, atol=1e-6)


def test_pa_mpjpe_does_not_reflect():
    truth = joints_mm(_moving(4))
    mirrored = truth * np.array([-1.0, 1.0, 1.0])
    assert pa_mpjpe(mirrored, truth) > 1.0


def test_bad_shapes_are_refused_with_a_clear_error():
    with pytest.raises(MeasureError, match=r"shape \(T, 55\)"):
        body_angle_error(np.zeros((3, 54)), _rest(3))
    with pytest.raises(MeasureError, match="frames"):
        body_angle_error(_rest(2), _rest(3))
    with pytest.raises(MeasureError, match="constant pose"):
        constant_error(_rest(3), np.zeros(54))
    bad = _rest(3)
    bad[1, 5] = np.nan
    with pytest.raises(MeasureError, match="NaN"):
        pose_measures(bad, _rest(3), _rest()[0])


def test_novelty_summary_counts_frames_beyond_the_training_rows():
    from sequences.measures import novelty_summary
    s = novelty_summary([0.5, 0.9, 1.2, np.nan, 3.0])
    assert s == {"median": pytest.approx(1.05), "share_above_1": pytest.approx(0.5)}
    assert novelty_summary([np.nan]) == {"median": None, "share_above_1": None}
