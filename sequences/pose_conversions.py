"""Pose-vector conversions ``track`` does not run: motion capture <-> pose vectors (data sets,
BVH output), canonical members (training) and each entry's body part (reports). Importable
from sequences.pose_vector too.
"""
from __future__ import annotations

import warnings

import numpy as np
from scipy.spatial.transform import Rotation

from regressor.angles import POSE_DIM, wrap_deg

from .motion import Motion
from .pose_vector import (_JOINT_ORDER, _ROOT_ORDER, ANGLE_SLICE, PoseVectorError, _as_vectors,
                          _azimuth, _joint_index, front_back_flip,
                          pose_vectors_to_local_rotations)
from .skeleton import FOLDED, POSE_JOINT_PART, POSE_JOINTS

#: Body part of each of the 55 entries (heading, torso, head, left/right arm, left/right leg;
#: the root's tilts count as torso).
PART_OF_ENTRY: tuple[str, ...] = tuple(
    ["heading", "heading", "torso", "torso"]
    + [POSE_JOINT_PART[joint] for joint in POSE_JOINTS[1:] for _ in range(3)])


def _as_euler(rotation: Rotation, order: str) -> np.ndarray:
    # Near gimbal lock scipy warns and sets the third angle to zero; the angles still give the
    # same rotation, which is all the conversions need.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return rotation.as_euler(order, degrees=True)


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


def pose_vectors_to_motion(vectors: np.ndarray, template: Motion, root_position=None,
                           camera_azimuth_deg=0.0) -> Motion:
    """A Motion (BVH channels) on ``template``'s skeleton from pose vectors (T, 55).

    root_position: (T, 3) CMU units; None holds the root at template.root_position[0].
    Non-folded ZYX joints get the vector's angles unchanged; joints outside the pose get zeros.
    The result has template.fps and an empty source.
    """
    v = _as_vectors(vectors)
    T = len(v)
    if root_position is None:
        root_position = np.repeat(template.root_position[:1], T, axis=0)
    root_position = np.asarray(root_position, dtype=np.float64)
    if root_position.shape != (T, 3):
        raise PoseVectorError(f"root_position must have shape ({T}, 3), got "
                              f"{root_position.shape}")
    index = _joint_index(template.names)
    orders = template.rotation_orders()
    local = pose_vectors_to_local_rotations(v, camera_azimuth_deg, template.names)
    euler = np.zeros((T, len(template.names), 3))
    for joint in POSE_JOINTS:
        for member in FOLDED.get(joint, (joint,)):
            j = index[member]
            if joint != POSE_JOINTS[0] and member == joint and joint not in FOLDED \
                    and orders[j] == _JOINT_ORDER:
                k = POSE_JOINTS.index(joint) - 1
                euler[:, j] = v[:, 4 + 3 * k: 7 + 3 * k]
            else:
                euler[:, j] = _as_euler(Rotation.from_matrix(local[:, j]), orders[j])
    return Motion(names=list(template.names), parents=template.parents.copy(),
                  offsets=template.offsets.copy(), end_sites=template.end_sites.copy(),
                  channels=[list(c) for c in template.channels], euler_deg=euler,
                  root_position=root_position.copy(), fps=template.fps, source="")


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
