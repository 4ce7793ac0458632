"""Pose-vector conversions ``track`` does not run: motion capture -> pose vectors (data sets;
the way back is sequences.bvh_write's), canonical members (training) and each entry's body part
(reports).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from regressor.angles import POSE_DIM, wrap_deg

from .bvh_write import _as_euler
from .motion import Motion
from .pose_vector import (_JOINT_ORDER, _ROOT_ORDER, ANGLE_SLICE, PoseVectorError, _azimuth,
                          _joint_index, front_back_flip)
from .skeleton import FOLDED, POSE_JOINTS

#: Body part of each pose joint, for per-part error reports.
POSE_JOINT_PART: dict[str, str] = {
    "Hips": "torso", "Spine1": "torso", "Neck": "head", "Head": "head",
    "LeftShoulder": "left arm", "LeftArm": "left arm", "LeftForeArm": "left arm",
    "LeftHand": "left arm",
    "RightShoulder": "right arm", "RightArm": "right arm", "RightForeArm": "right arm",
    "RightHand": "right arm",
    "LeftUpLeg": "left leg", "LeftLeg": "left leg", "LeftFoot": "left leg",
    "RightUpLeg": "right leg", "RightLeg": "right leg", "RightFoot": "right leg",
}

#: Body part of each of the 55 entries (heading, torso, head, left/right arm, left/right leg;
#: the root's tilts count as torso).
PART_OF_ENTRY: tuple[str, ...] = tuple(
    ["heading", "heading", "torso", "torso"]
    + [POSE_JOINT_PART[joint] for joint in POSE_JOINTS[1:] for _ in range(3)])


def motion_to_pose_vectors(motion: Motion, camera_azimuth_deg=0.0) -> np.ndarray:
    """Pose vectors (T, 55) of a motion seen by a camera at azimuth camera_azimuth_deg (degrees,
    scalar or (T,)). Non-folded joints with ZYX channels keep the file's angles as they are."""
    T = motion.n_frames
    az = _azimuth(camera_azimuth_deg, T)
    index = _joint_index(motion.names)
    orders = motion.rotation_orders()
    local = motion.local_rotations()
    out = np.empty((T, POSE_DIM))

    root = index[POSE_JOINTS[0]]
    yaw, tilt_x, tilt_z = _as_euler(Rotation.from_matrix(local[:, root]), _ROOT_ORDER).T
    heading = np.radians(yaw - az)
    out[:, 0], out[:, 1], out[:, 2], out[:, 3] = np.cos(heading), np.sin(heading), tilt_x, tilt_z

    for k, joint in enumerate(POSE_JOINTS[1:]):
        cols = slice(4 + 3 * k, 7 + 3 * k)
        members = FOLDED.get(joint, (joint,))
        if len(members) == 1 and orders[index[joint]] == _JOINT_ORDER:
            out[:, cols] = motion.euler_deg[:, index[joint]]
            continue
        product = local[:, index[members[0]]]
        for member in members[1:]:
            product = product @ local[:, index[member]]
        out[:, cols] = _as_euler(Rotation.from_matrix(product), _JOINT_ORDER)
    return out


def flip_odd_part(vectors: np.ndarray) -> np.ndarray:
    """The part of pose vectors (55,) or (T, 55) that front_back_flip negates: (v - flip(v))/2,
    angle differences wrapped to (-180, 180] first (degrees; heading entries unitless).
    flip_odd_part(front_back_flip(v)) == -flip_odd_part(v)."""
    v = np.asarray(vectors, dtype=np.float64)
    f = front_back_flip(v)
    odd = (v - f) / 2.0
    odd[..., ANGLE_SLICE] = wrap_deg(v[..., ANGLE_SLICE] - f[..., ANGLE_SLICE]) / 2.0
    return odd


def canonical_member(vectors: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Of each pose and its front/back flip (one silhouette, two bodies), the one whose
    flip_odd_part has a non-negative projection on ``direction`` (55,): a choice that is the
    same for both members, so a regressor trained on it never sees one silhouette with two
    targets and does not average them (issue 9: in profile, which leg is forward).
    vectors: (55,) or (T, 55); returns the same shape."""
    v = np.asarray(vectors, dtype=np.float64)
    d = np.asarray(direction, dtype=np.float64)
    if d.shape != (POSE_DIM,) or not np.isfinite(d).all():
        raise PoseVectorError(f"direction must be {POSE_DIM} finite values, got shape {d.shape}")
    keep = flip_odd_part(v) @ d >= 0.0
    return np.where(keep[..., None], v, front_back_flip(v))
