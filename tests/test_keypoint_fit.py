"""sequences.keypoint_fit: the project's body fitted to 3-D keypoints (inverse kinematics), on
keypoints made from the body itself in real poses, and on Pose2Sim's reference (skips without
../shared)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sequences.body import BodyShape, Skinner, load_body
from sequences.keypoint_fit import (KEYPOINTS, KeypointFitError, _Posed, fit_body,
                                    fitted_joints, pose_in_view)
from sequences.measures import flexion_from_points
from sequences.pose2sim import (Camera, load_trial, reference_flexion, render_view_masks,
                                video_frames)
from sequences.pose_vector import heading_deg, pose_vectors_to_local_rotations

_TRUTH = Path(__file__).resolve().parents[1] / "sequences" / "data" / \
    "sample_spiral_walk.truth.npz"
#: Keypoint name -> the body point it is made from (as the fit's BONES pair them).
_MADE_FROM = {"LHip": "LeftUpLeg", "RHip": "RightUpLeg", "LKnee": "LeftLeg", "RKnee": "RightLeg",
              "LAnkle": "LeftFoot", "RAnkle": "RightFoot", "LBigToe": "LeftToeBase@tail",
              "RBigToe": "RightToeBase@tail", "LShoulder": "LeftArm", "RShoulder": "RightArm",
              "LElbow": "LeftForeArm", "RElbow": "RightForeArm", "LWrist": "LeftHand",
              "RWrist": "RightHand", "Head": "Head@tail"}
_FLEXION = (("LeftUpLeg", "LeftLeg", "LeftFoot"), ("RightUpLeg", "RightLeg", "RightFoot"),
            ("LeftArm", "LeftForeArm", "LeftHand"), ("RightArm", "RightForeArm", "RightHand"))


@pytest.fixture(scope="module")
def body():
    return load_body()


def _flexion(joints, body) -> np.ndarray:
    j = list(body.joint_names).index
    return flexion_from_points(*(np.stack([joints[:, j(trio[k])] for trio in _FLEXION], axis=1)
                                 for k in range(3)))


def _keypoints_of(body, pose, root_m, shape) -> np.ndarray:
    """Keypoints (T, 15, 3) of the body posed by pose vectors (T, 55) at hips root_m (T, 3)."""
    posed = _Posed(Skinner(body, shape=shape))
    params = np.concatenate([heading_deg(pose)[:, None], pose[:, 2:], root_m], axis=1)
    joints, ends = posed.state(params)
    return np.stack([posed.point(joints, ends, _MADE_FROM[n]) for n in KEYPOINTS], axis=1)


@pytest.mark.slow
def test_real_poses_are_recovered_from_the_bodys_own_keypoints(body):
    pose = np.load(_TRUTH, allow_pickle=False)["pose"][[0, 40, 80], 0]   # a spiral walk
    root = np.array([[0.1, 0.95, -1.0], [0.2, 0.94, -1.1], [0.3, 0.95, -1.2]])
    shape = BodyShape(1.05, 1.0)
    points = _keypoints_of(body, pose, root, shape)
    fit = fit_body(points, KEYPOINTS, body)
    assert fit.shape.height_scale == pytest.approx(1.05, abs=0.01)
    assert fit.direction_error_deg.max() < 1.0
    made = _flexion(Skinner(body, shape=shape).joints(
        pose_vectors_to_local_rotations(pose, 0.0), root)[0], body)
    assert np.abs(_flexion(fitted_joints(fit, body), body) - made).max() < 1.5
    heading_error = (heading_deg(fit.pose) - heading_deg(pose) + 180) % 360 - 180
    assert np.abs(heading_error).max() < 3.0
    assert np.abs(fit.root_m - root).max() < 0.05


def test_missing_or_non_finite_keypoints_are_refused(body):
    points = np.zeros((2, len(KEYPOINTS), 3))
    with pytest.raises(KeypointFitError, match="lack"):
        fit_body(points[:, 1:], KEYPOINTS[1:], body)
    points[1, 3, 0] = np.nan
    with pytest.raises(KeypointFitError, match="non-finite"):
        fit_body(points, KEYPOINTS, body)
    with pytest.raises(KeypointFitError, match=r"\(T, 15, 3\)"):
        fit_body(points[0], KEYPOINTS, body)


def test_a_pose_in_view_turns_the_heading_by_the_camera_azimuth():
    pose = np.zeros((2, 55))
    pose[:, 0], pose[:, 4] = 1.0, 12.0                     # heading 0, one body angle
    seen = pose_in_view(pose, np.array([30.0, -90.0]))
    assert heading_deg(seen) == pytest.approx([-30.0, 90.0])
    assert np.array_equal(seen[:, 2:], pose[:, 2:])


def test_the_fitted_body_renders_where_a_calibrated_camera_sees_its_hips(body):
    pose = np.load(_TRUTH, allow_pickle=False)["pose"][:1, 0]
    skinner = Skinner(body)
    vertices = skinner.pose(pose_vectors_to_local_rotations(pose, 0.0), np.array([[0, 0.9, 0]]))
    # A camera 4 m away along trc +Z at the hips' height, looking back along -Z (trc (X, Y, Z)
    # = calibration world (Y, Z, X)): camera x = trc X, y (down) = -trc Y, z = -trc Z.
    R = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]])
    centre_world = np.array([4.0, 0.0, 0.9])
    K = np.array([[500.0, 0, 160], [0, 500.0, 240], [0, 0, 1]])
    camera = Camera("test", K, np.zeros(4), R, -R @ centre_world, (320, 480))
    masks = render_view_masks(vertices, body.faces, body.patch_start, camera)
    assert masks.shape == (1, 480, 320)
    rows, cols = np.nonzero(masks[0])
    assert 300 < len(rows) and abs(cols.mean() - 160) < 20
    # Hips at the principal point's row; head ~0.8 m above, feet ~0.9 m below (125 px/m).
    assert rows.min() < 240 - 80 and rows.max() > 240 + 80
    assert render_view_masks(vertices, body.faces, body.patch_start, camera,
                             (480, 300)).shape == (1, 480, 300)


@pytest.mark.slow
def test_the_pose2sim_reference_is_fitted_within_a_degree_of_its_flexion(body, pose2sim_trial):
    trial = load_trial(pose2sim_trial)
    frames = video_frames(trial)[:4]
    fit = fit_body(trial.points(frames), trial.reference.names, body)
    assert np.median(fit.direction_error_deg) < 1.0
    assert np.abs(_flexion(fitted_joints(fit, body), body)
                  - reference_flexion(trial, frames)).max() < 2.0
