"""The 53 body angles as 6-D rotations, a continuous representation for regression targets.

Euler angles are a discontinuous chart of a rotation; the first two columns of its matrix are
continuous, and any 6 numbers map back to a rotation by Gram-Schmidt (Zhou et al., CVPR 2019).
A training option (regressor.training.MixtureOptions.limb_net_output). The root's two tilts
stay angles; each of the 17 joints' (z, y, x) angles (R = Rz @ Ry @ Rx, intrinsic ZYX)
becomes its matrix's columns 0 and 1, (x0, y0, z0, x1, y1, z1).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .angles import N_ANGLES

#: Joints after the root in the 53 angles, their Euler order (R = Rz @ Ry @ Rx, intrinsic).
N_JOINTS, EULER_ORDER = (N_ANGLES - 3) // 3, "ZYX"
#: Values per pose: the root's two tilts, then 6 per joint (106 with the heading's cos, sin).
ROT6D_LENGTH = 2 + 6 * N_JOINTS


def angles_to_rot6d(angles_deg: np.ndarray) -> np.ndarray:
    """The 53 body angles (N, 53), degrees -> (N, ROT6D_LENGTH): the root's two tilts
    (degrees) as they are, then each joint's rotation matrix's first two columns."""
    a = np.asarray(angles_deg, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != N_ANGLES - 1:
        raise ValueError(f"angles must have shape (N, {N_ANGLES - 1}), got {a.shape}")
    R = Rotation.from_euler(EULER_ORDER, a[:, 2:].reshape(-1, 3), degrees=True).as_matrix()
    return np.hstack([a[:, :2], R[:, :, :2].transpose(0, 2, 1).reshape(len(a), 6 * N_JOINTS)])


def rot6d_to_angles(values: np.ndarray) -> np.ndarray:
    """(N, ROT6D_LENGTH) -> the 53 body angles (N, 53), degrees in (-180, 180]: each joint's
    6 numbers made a rotation by Gram-Schmidt, then its ZYX angles with the middle one in
    [-90, 90] (as scipy; at +-90 the first angle takes the whole turn, the last is 0). In
    numpy: 3 x faster than scipy per row, and it runs per person per frame."""
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != ROT6D_LENGTH:
        raise ValueError(f"values must have shape (N, {ROT6D_LENGTH}), got {v.shape}")
    cols = v[:, 2:].reshape(len(v), N_JOINTS, 2, 3)
    a = cols[..., 0, :] / np.maximum(np.linalg.norm(cols[..., 0, :], axis=-1, keepdims=True),
                                     1e-12)
    b = cols[..., 1, :] - (a * cols[..., 1, :]).sum(axis=-1, keepdims=True) * a
    b = b / np.maximum(np.linalg.norm(b, axis=-1, keepdims=True), 1e-12)
    # R = Rz(z) Ry(y) Rx(x) = [a b a x b]: R20 = -sin y, R21 = cos y sin x, R22 = cos y cos x,
    # R10 = sin z cos y, R00 = cos z cos y; at cos y = 0 (x = 0): R01 = -sin z, R11 = cos z.
    r22 = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    cos_y = np.hypot(b[..., 2], r22)
    locked = cos_y < 1e-9
    y = np.arctan2(-a[..., 2], cos_y)
    x = np.where(locked, 0.0, np.arctan2(b[..., 2], r22))
    z = np.where(locked, np.arctan2(-b[..., 0], b[..., 1]), np.arctan2(a[..., 1], a[..., 0]))
    joints = np.degrees(np.stack([z, y, x], axis=-1)).reshape(len(v), 3 * N_JOINTS)
    return np.hstack([v[:, :2], joints])
