"""The project's skinned body fitted to 3-D keypoints (inverse kinematics), and rendered.

Why: on a real video with a 3-D keypoint reference (Pose2Sim's balancing trial) the reference
gives knee and elbow flexion and a heading, but no pose vector, so it cannot say whether a bad
estimate comes from the silhouettes or from poses the regressor never learned. Fitting the
training renderer's body (sequences.body) to the keypoints gives a pose vector per frame; that
body rendered through the real cameras is a silhouette of the true pose that looks exactly like
a training render (lab.reference_masks ``rendered``).

The fit matches bone *directions*, not positions: the keypoints come from another skeleton
(a pose estimator's hips and shoulders, not CMU's joints), so positions cannot all be matched
at once, but directions can (hip to knee, knee to ankle, ankle to big toe, shoulder to elbow,
elbow to wrist, the hip and shoulder lines, the trunk and the head). Flexion is a function of
directions alone, so it is reproduced exactly (within ~1 degree). Angles the keypoints do not
determine (the twists of limbs about their own axis, hands, collar bones) are held near 0 by a
weak prior. The mid-hip position is matched in metres.

Conventions: keypoint coordinates are metres, Y up, right-handed (Pose2Sim's trc frame is
one). Fitted pose vectors have camera azimuth 0, so their heading is the body's world yaw
(sequences.pose_vector); :func:`pose_in_view` gives them relative to a camera.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.optimize import least_squares

from regressor.angles import POSE_DIM, angles_to_pose, wrap_deg
from regressor.errors import SilhouettePoseError

from .body import BodyModel, BodyShape, Skinner, load_body
from .pose_vector import pose_vectors_to_local_rotations

#: Keypoint names the fit needs (Pose2Sim's / HALPE's names).
KEYPOINTS: tuple[str, ...] = ("LHip", "RHip", "LKnee", "RKnee", "LAnkle", "RAnkle", "LBigToe",
                              "RBigToe", "LShoulder", "RShoulder", "LElbow", "RElbow", "LWrist",
                              "RWrist", "Head")
#: (from keypoints, to keypoints, from body point, to body point): each bone's direction is
#: matched. A tuple of keypoints means their midpoint; body points are joints of the body's
#: rig, "midhip" / "midshoulder" the midpoints of the hip / shoulder joints, "X@tail" the end
#: of bone X.
BONES: tuple[tuple[tuple[str, ...], tuple[str, ...], str, str], ...] = (
    (("LHip",), ("LKnee",), "LeftUpLeg", "LeftLeg"),
    (("LKnee",), ("LAnkle",), "LeftLeg", "LeftFoot"),
    (("LAnkle",), ("LBigToe",), "LeftFoot", "LeftToeBase@tail"),
    (("RHip",), ("RKnee",), "RightUpLeg", "RightLeg"),
    (("RKnee",), ("RAnkle",), "RightLeg", "RightFoot"),
    (("RAnkle",), ("RBigToe",), "RightFoot", "RightToeBase@tail"),
    (("LShoulder",), ("LElbow",), "LeftArm", "LeftForeArm"),
    (("LElbow",), ("LWrist",), "LeftForeArm", "LeftHand"),
    (("RShoulder",), ("RElbow",), "RightArm", "RightForeArm"),
    (("RElbow",), ("RWrist",), "RightForeArm", "RightHand"),
    (("RHip",), ("LHip",), "RightUpLeg", "LeftUpLeg"),
    (("RShoulder",), ("LShoulder",), "RightArm", "LeftArm"),
    (("RHip", "LHip"), ("RShoulder", "LShoulder"), "midhip", "midshoulder"),
    (("RShoulder", "LShoulder"), ("Head",), "midshoulder", "Head@tail"),
)
#: Weak prior on the 53 body angles (per degree, against direction errors of unit vectors:
#: 10 degrees of an angle weigh as much as a 0.6 degree direction error).
PRIOR_PER_DEG = 1e-3
#: Pull towards the previous frame's angles (per degree): keeps undetermined angles steady.
STEADY_PER_DEG = 5e-4
#: Weight of the mid-hip position error (per metre) against direction errors.
HIP_PER_M = 3.0
_N_PARAMS = 1 + 53 + 3          # yaw (deg), the 53 body angles (deg), hips position (m)
_FIRST_YAW_STARTS_DEG = (0.0, 90.0, -90.0, 180.0)


class KeypointFitError(SilhouettePoseError, ValueError):
    """Keypoints missing, malformed or non-finite."""


@dataclass(frozen=True)
class BodyFit:
    """The fitted body. pose: (T, 55) pose vectors at camera azimuth 0 (heading = world yaw);
    root_m: (T, 3) metres, the hips joint in the keypoints' frame; shape: the body's shape
    (height from the keypoints' leg length; girth 1); direction_error_deg: (T, len(BONES))
    angle between each fitted bone and the keypoints' one."""

    pose: np.ndarray
    root_m: np.ndarray
    shape: BodyShape
    direction_error_deg: np.ndarray


def _midpoint(points: np.ndarray, names: list[str], which: tuple[str, ...]) -> np.ndarray:
    return np.mean([points[..., names.index(n), :] for n in which], axis=0)


def _unit(d: np.ndarray) -> np.ndarray:
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _check_keypoints(points, names) -> tuple[np.ndarray, list[str]]:
    points = np.asarray(points, dtype=np.float64)
    names = list(names)
    missing = [n for n in KEYPOINTS if n not in names]
    if missing:
        raise KeypointFitError(f"the keypoints lack {missing} (have {names})")
    if points.ndim != 3 or points.shape[1:] != (len(names), 3) or len(points) == 0:
        raise KeypointFitError(f"keypoints must be (T, {len(names)}, 3) metres, got "
                               f"{points.shape}")
    used = [names.index(n) for n in KEYPOINTS]
    if not np.isfinite(points[:, used]).all():
        raise KeypointFitError("the keypoints have non-finite values")
    return points, names


class _Posed:
    """The body's points the fit compares, for parameter vectors (T, 57)."""

    def __init__(self, skinner: Skinner):
        self.skinner = skinner
        self.index = list(skinner.body.joint_names).index

    def state(self, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint positions and bone ends (T, 31, 3) metres."""
        params = np.atleast_2d(params)
        # parameters 0..53 are the pose's 54 angles (yaw as the heading)
        local = pose_vectors_to_local_rotations(angles_to_pose(params[:, :54]), 0.0)
        return self.skinner.joints_and_ends(local, params[:, 54:57])

    def point(self, joints, ends, name: str) -> np.ndarray:
        """A named body point (T, 3) (see BONES)."""
        if name == "midhip":
            return (joints[:, self.index("LeftUpLeg")] + joints[:, self.index("RightUpLeg")]) / 2
        if name == "midshoulder":
            return (joints[:, self.index("LeftArm")] + joints[:, self.index("RightArm")]) / 2
        if name.endswith("@tail"):
            return ends[:, self.index(name[:-len("@tail")])]
        return joints[:, self.index(name)]

    def directions(self, params) -> tuple[np.ndarray, np.ndarray]:
        """Unit bone directions (T, len(BONES), 3) and the mid-hip (T, 3) metres."""
        joints, ends = self.state(params)
        d = np.stack([_unit(self.point(joints, ends, b) - self.point(joints, ends, a))
                      for _, _, a, b in BONES], axis=1)
        return d, self.point(joints, ends, "midhip")


def fitted_shape(points: np.ndarray, names: list[str], body: BodyModel) -> BodyShape:
    """The body shape whose thigh + shank length is the keypoints' median (girth 1)."""
    hip, knee, ankle = (points[:, names.index(n)] for n in ("LHip", "LKnee", "LAnkle"))
    leg = np.median(np.linalg.norm(knee - hip, axis=1) + np.linalg.norm(ankle - knee, axis=1))
    rest = Skinner(body)
    joint = list(body.joint_names).index
    body_leg = (np.linalg.norm(rest.offsets[joint("LeftLeg")])
                + np.linalg.norm(rest.offsets[joint("LeftFoot")]))
    return BodyShape(float(np.clip(leg / body_leg, 0.5, 2.0)), 1.0)


def fit_body(points, names, body: BodyModel | None = None,
             progress: Callable[[int, int], None] | None = None) -> BodyFit:
    """Fit the body to keypoints (T, K, 3) metres (Y up) named ``names`` (K,), frame by frame
    (each frame starts from the previous one's fit; the first from four yaws). progress(t, T)
    is called after each frame. About 0.3 s a frame."""
    points, names = _check_keypoints(points, names)
    body = load_body() if body is None else body
    shape = fitted_shape(points, names, body)
    posed = _Posed(Skinner(body, shape=shape))
    targets = np.stack([_unit(_midpoint(points, names, b) - _midpoint(points, names, a))
                        for a, b, _, _ in BONES], axis=1)                 # (T, B, 3)
    hips = _midpoint(points, names, ("LHip", "RHip"))                      # (T, 3)

    def residual(x, target, hip, previous):
        d, mid = posed.directions(x)
        steady = (STEADY_PER_DEG * (x[1:54] - previous[1:54]) if previous is not None
                  else np.zeros(0))
        return np.concatenate([(d[0] - target).ravel(), HIP_PER_M * (mid[0] - hip),
                               PRIOR_PER_DEG * x[1:54], steady])

    T = len(points)
    params = np.zeros((T, _N_PARAMS))
    x = np.zeros(_N_PARAMS)
    x[54:57] = hips[0]
    lh, rh = points[0, names.index("LHip")], points[0, names.index("RHip")]
    facing = np.cross(lh - rh, [0.0, 1.0, 0.0])
    x[0] = np.degrees(np.arctan2(facing[0], facing[2]))
    for t in range(T):
        starts = [x] if t else [x + np.r_[yaw, np.zeros(_N_PARAMS - 1)]
                                for yaw in _FIRST_YAW_STARTS_DEG]
        previous = params[t - 1] if t else None
        fits = [least_squares(residual, s, args=(targets[t], hips[t], previous), x_scale="jac")
                for s in starts]
        x = min(fits, key=lambda f: f.cost).x
        x[:54] = wrap_deg(x[:54])
        params[t] = x
        if progress is not None:
            progress(t + 1, T)
    d, _ = posed.directions(params)
    error = np.degrees(np.arccos(np.clip((d * targets).sum(axis=-1), -1.0, 1.0)))
    return BodyFit(angles_to_pose(params[:, :54]), params[:, 54:57].copy(), shape, error)


def posed_vertices(fit: BodyFit, body: BodyModel | None = None) -> np.ndarray:
    """The fitted body's vertices (T, V, 3) metres, in the keypoints' frame."""
    body = load_body() if body is None else body
    skinner = Skinner(body, shape=fit.shape)
    return skinner.pose(pose_vectors_to_local_rotations(fit.pose, 0.0), fit.root_m)


def fitted_joints(fit: BodyFit, body: BodyModel | None = None) -> np.ndarray:
    """The fitted body's joint positions (T, 31, 3) metres (body joint order)."""
    body = load_body() if body is None else body
    skinner = Skinner(body, shape=fit.shape)
    P, _ = skinner.joints(pose_vectors_to_local_rotations(fit.pose, 0.0), fit.root_m)
    return P


def pose_in_view(pose: np.ndarray, camera_azimuth_deg) -> np.ndarray:
    """Pose vectors (T, 55) at camera azimuth 0 made relative to a camera at azimuth
    camera_azimuth_deg (degrees, scalar or (T,)): heading = yaw - azimuth."""
    pose = np.asarray(pose, dtype=np.float64)
    if pose.ndim != 2 or pose.shape[1] != POSE_DIM:
        raise KeypointFitError(f"poses must be (T, {POSE_DIM}), got {pose.shape}")
    heading = np.arctan2(pose[:, 1], pose[:, 0]) - np.radians(camera_azimuth_deg)
    out = pose.copy()
    norm = np.hypot(pose[:, 0], pose[:, 1])
    out[:, 0], out[:, 1] = norm * np.cos(heading), norm * np.sin(heading)
    return out
