"""Pose2Sim's balancing trial (sequences.pose2sim): reading, projection, reference flexion and
heading. Tests on the real files skip when ../shared/data/pose2sim is absent."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import SHARED
from sequences.pose2sim import (VIEWS, Camera, Pose2SimError, load_trial, project_points,
                                project_reference, read_calibration, read_trc,
                                reference_flexion, reference_heading_deg, video_frames)
from sequences.pose2sim_measures import (cross_view_measures, reference_cross_view_check,
                                         subject_rows, view_measures)
from sequences.pose_vector import pose_vector_names

TRIAL = SHARED / "data" / "pose2sim" / "balancing"
#: The data's README: true heading relative to each camera, roughly (degrees).
README_HEADING = {"cam01": 52.0, "cam02": 3.0, "cam03": -118.0, "cam04": 169.0}


@pytest.fixture(scope="module")
def trial():
    if not TRIAL.is_dir():
        pytest.skip(f"Pose2Sim trial not found at {TRIAL} (needs ../shared beside the repo)")
    return load_trial(TRIAL)


def _trc_text(rows: list[str], names=("A", "B")) -> str:
    head = "\t\t\t".join(names)
    coords = "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, len(names) + 1))
    return ("PathFileType\t4\t(X/Y/Z)\tx.trc\n"
            "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\n"
            f"60\t60\t{len(rows)}\t{len(names)}\tmm\n"
            f"Frame#\tTime\t{head}\t\t\n\t\t{coords}\n" + "\n".join(rows) + "\n")


def test_trc_is_read_in_metres(tmp_path):
    path = tmp_path / "x.trc"
    path.write_text(_trc_text(["1\t0.0\t1000\t2000\t3000\t0\t0\t0",
                               "2\t0.1\t1000\t2000\t3000\t0\t0\t500"]))
    ref = read_trc(path)
    assert ref.names == ("A", "B")
    assert ref.frames.tolist() == [1, 2]
    assert np.allclose(ref.points[0, 0], [1.0, 2.0, 3.0])
    assert np.allclose(ref.keypoint("B")[1], [0.0, 0.0, 0.5])


def test_malformed_or_missing_trc_is_refused_in_one_line(tmp_path):
    path = tmp_path / "bad.trc"
    path.write_text(_trc_text(["1\t0.0\t1\t2\t3\t4"]))
    with pytest.raises(Pose2SimError, match="data columns"):
        read_trc(path)
    path.write_text("hello\n")
    with pytest.raises(Pose2SimError, match="not a .trc file"):
        read_trc(path)
    with pytest.raises(Pose2SimError, match="cannot read"):
        read_trc(tmp_path / "missing.trc")


def test_bad_calibration_is_refused(tmp_path):
    path = tmp_path / "calib.toml"
    path.write_text('[cam_01]\nname = "cam_01"\nmatrix = [[1, 0, 0], [0, 1, 0]]\n'
                    'distortions = [0, 0, 0, 0]\nrotation = [0, 0, 0]\ntranslation = [0, 0, 1]\n'
                    'size = [10, 10]\n')
    with pytest.raises(Pose2SimError, match="cam_01"):
        read_calibration(path)
    path.write_text("not = [toml")
    with pytest.raises(Pose2SimError, match="TOML"):
        read_calibration(path)


def test_projection_of_a_point_on_the_optical_axis_is_the_principal_point():
    K = np.array([[1000.0, 0, 500], [0, 1000, 900], [0, 0, 1]])
    cam = Camera("c", K, np.array([0.1, 0.01, 0.0, 0.0]), np.eye(3), np.zeros(3), (1000, 1800))
    # world (0, 0, 2) on the axis = trc (0, 2, 0); world (0.2, 0, 2) = trc (0, 2, 0.2)
    px = project_points(np.array([[0.0, 2.0, 0.0], [0.0, 2.0, 0.2]]), cam)
    assert np.allclose(px[0], [500, 900])
    assert px[1, 0] == pytest.approx(500 + 1000 * 0.1 * (1 + 0.1 * 0.01 + 0.01 * 1e-4))


def test_reference_keypoints_project_inside_every_image(trial):
    frames = video_frames(trial)
    for view in VIEWS:
        px = project_reference(view, frames, trial)
        w, h = trial.camera(view).size
        assert px.shape == (len(frames), 21, 2)
        assert (px[..., 0] > 0).all() and (px[..., 0] < w).all(), view
        assert (px[..., 1] > 0).all() and (px[..., 1] < h).all(), view


def test_reference_flexion_is_plausible(trial):
    flex = reference_flexion(trial, video_frames(trial))
    assert flex.shape == (100, 4)
    assert (flex >= 0).all() and (flex < 150).all()
    assert (flex.std(axis=0) > 3).all()          # the limbs move in this clip


def test_reference_heading_matches_the_data_readme(trial):
    frames = video_frames(trial)
    for view, expected in README_HEADING.items():
        heading = np.radians(reference_heading_deg(trial, view, frames))
        mean = np.degrees(np.arctan2(np.sin(heading).mean(), np.cos(heading).mean()))
        assert abs((mean - expected + 180) % 360 - 180) < 3, view


def test_frames_without_reference_are_refused(trial):
    with pytest.raises(Pose2SimError, match="video frame 100 has no reference"):
        reference_flexion(trial, [5, 100])
    with pytest.raises(Pose2SimError, match="no view"):
        project_reference("cam09", [0], trial)


# ---------------------------------------------------------------- measures against the reference

def _poses_with_heading(heading_deg_: np.ndarray, knee_deg: float = 0.0) -> np.ndarray:
    v = np.zeros((len(heading_deg_), 55))
    v[:, 0], v[:, 1] = np.cos(np.radians(heading_deg_)), np.sin(np.radians(heading_deg_))
    v[:, pose_vector_names().index("LeftLeg_z")] = knee_deg
    return v


def test_subject_is_the_box_holding_the_mid_hip_nearest_its_centre():
    frames = np.array([0, 0, 1, 1, 2])
    boxes = np.array([[0, 0, 10, 10], [0, 0, 100, 100], [50, 50, 10, 10],
                      [0, 0, 100, 100], [200, 200, 5, 5]])
    hips = np.full((5, 2), 5.0)
    assert subject_rows(frames, boxes, hips).tolist() == [0, 3]


def test_reference_headings_are_consistent_across_views(trial):
    frames = video_frames(trial)
    assert reference_cross_view_check(trial, frames, VIEWS) < 1e-6
    poses = {v: _poses_with_heading(reference_heading_deg(trial, v, frames)) for v in VIEWS}
    cross = cross_view_measures(trial, frames, poses)
    assert cross["heading_rms_deg"] < 1e-6
    assert cross["body_angle_disagreement_deg"] == 0.0
    assert len(cross["pairs"]) == 6


def test_one_view_shifted_by_90_degrees_shows_in_three_pairs(trial):
    frames = video_frames(trial)[:10]
    poses = {v: _poses_with_heading(reference_heading_deg(trial, v, frames)) for v in VIEWS}
    poses["cam02"] = _poses_with_heading(reference_heading_deg(trial, "cam02", frames) + 90)
    cross = cross_view_measures(trial, frames, poses)
    assert cross["heading_rms_deg"] == pytest.approx(90 * np.sqrt(3 / 6))
    assert cross["heading_rms_per_pair"]["cam01-cam03"] == pytest.approx(0.0, abs=1e-6)


def test_view_measures_of_the_reference_heading_and_a_straight_body(trial):
    frames = video_frames(trial)
    ref = reference_flexion(trial, frames)
    out = view_measures(trial, "cam03", frames,
                        _poses_with_heading(reference_heading_deg(trial, "cam03", frames)))
    assert out["heading"]["rms_deg"] < 1e-6 and out["heading"]["within_45"] == 1.0
    assert out["flexion"]["error_per_angle"] == pytest.approx(np.abs(ref).mean(axis=0))
    assert out["flexion"]["corr"] == 0.0            # a straight body does not move


def test_view_measures_score_a_given_constant_pose_beside_the_reference_mean(trial):
    frames = video_frames(trial)
    ref = reference_flexion(trial, frames)
    straight = _poses_with_heading(np.zeros(len(frames)))
    out = view_measures(trial, "cam02", frames, straight, constant_pose=straight[0])
    # The estimate is the constant itself, so the two errors agree; the reference's own mean
    # is a different (better) constant.
    assert out["flexion"]["constant_error"] == pytest.approx(out["flexion"]["error_per_angle"])
    assert out["flexion"]["constant_error_mean"] == pytest.approx(np.abs(ref).mean())
    assert out["flexion"]["truth_mean_error_mean"] < out["flexion"]["constant_error_mean"]
    assert "constant_error" not in view_measures(trial, "cam02", frames, straight)["flexion"]
