"""Angles and the pose vector's size, shared by every package (``regressor`` imports neither
of the others, DESIGN.md). POSE_DIM = 55: the heading's (cos, sin), then 53 angles in degrees
(sequences/pose_vector.py). N_ANGLES = 54: the heading (atan2(sin, cos)) and the 53, the
filter's state. Every angle is wrapped to (-180, 180] by :func:`wrap_deg`.
"""
from __future__ import annotations

import numpy as np

POSE_DIM = 55
N_ANGLES = 54                      # heading + 53 joint angles, the filter's state


def wrap_deg(angles) -> np.ndarray:
    """Angles in degrees, any shape -> the same angles in (-180, 180] (float64)."""
    wrapped = np.mod(np.asarray(angles, dtype=np.float64) + 180.0, 360.0) - 180.0
    return np.where(wrapped <= -180.0, wrapped + 360.0, wrapped)


def pose_angles(poses) -> np.ndarray:
    """Pose vectors (..., 55) -> the 54 angles (..., 54) deg: heading = atan2(sin, cos), then
    entries 2..54 as they are."""
    poses = np.asarray(poses, dtype=np.float64)
    heading = np.degrees(np.arctan2(poses[..., 1], poses[..., 0]))
    return np.concatenate([heading[..., None], poses[..., 2:]], axis=-1)


def heading_norm(poses) -> np.ndarray:
    """Norm (...) of the (cos, sin) heading pair of pose vectors (..., 55): low = ambiguous."""
    poses = np.asarray(poses, dtype=np.float64)
    return np.hypot(poses[..., 0], poses[..., 1])


def angles_to_pose(angles) -> np.ndarray:
    """Angles (..., 54) deg -> pose vectors (..., 55): heading as unit (cos, sin), the rest
    wrapped to (-180, 180]."""
    angles = np.asarray(angles, dtype=np.float64)
    heading = np.radians(angles[..., 0])
    return np.concatenate([np.cos(heading)[..., None], np.sin(heading)[..., None],
                           wrap_deg(angles[..., 1:])], axis=-1)

