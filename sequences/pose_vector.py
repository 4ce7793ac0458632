"""The 55-D pose vector and its conversions to rotations and joint positions.

Layout (POSE_DIM = 55), angles in degrees: [0] cos(heading), [1] sin(heading); [2] Hips_x,
[3] Hips_z, the root's tilts; [4:55] 17 joints (POSE_JOINTS[1:]) x (z, y, x) Euler angles,
local rotation R = Rz @ Ry @ Rx (intrinsic ZYX, the CMU BVH channels); folded joints
(skeleton.FOLDED) carry the product of their CMU joints' rotations.

The root's rotation is R_root = Ry(yaw) @ Rx(Hips_x) @ Rz(Hips_z) (Hips_x in [-90, 90]) and
heading = yaw - camera_azimuth. World: Y up, the subject at rest faces +Z; a camera at azimuth
``az`` sits in direction Ry(az) @ (0, 0, 1) looking at it. Heading 0 faces the camera; a
positive heading turns the subject counter-clockwise seen from above. The (cos, sin) pair
need not have unit norm: the norm measures how unambiguous an estimate was. Lengths: CMU units."""
from __future__ import annotations

import re
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from regressor.angles import POSE_DIM, wrap_deg
from regressor.errors import SilhouettePoseError

if TYPE_CHECKING:
    from .motion import Motion
from .skeleton import (CMU_JOINT_NAMES, CMU_PARENTS, CMU_REST_OFFSETS, FOLDED, POSE_JOINTS,
                       pose_joint_indices)

#: Entries that are angles in degrees (all but the heading's cos and sin).
ANGLE_SLICE = slice(2, POSE_DIM)
_ROOT_ORDER = "YXZ"    # R_root = Ry(yaw) @ Rx(tilt_x) @ Rz(tilt_z), intrinsic
_JOINT_ORDER = "ZYX"   # R = Rz @ Ry @ Rx, intrinsic, as the CMU BVH channels


class PoseVectorError(SilhouettePoseError, ValueError):
    """Pose vectors or a skeleton of the wrong shape or content."""


def pose_vector_names() -> list[str]:
    """The 55 entry names: heading_cos, heading_sin, Hips_x, Hips_z, Spine1_z, Spine1_y, ..."""
    return ["heading_cos", "heading_sin", "Hips_x", "Hips_z"] + [
        f"{joint}_{axis}" for joint in POSE_JOINTS[1:] for axis in "zyx"]


def _as_vectors(vectors: np.ndarray) -> np.ndarray:
    v = np.asarray(vectors, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != POSE_DIM:
        raise PoseVectorError(f"pose vectors must have shape (T, {POSE_DIM}), got {v.shape}")
    if not np.isfinite(v).all():
        row = int(np.flatnonzero(~np.isfinite(v).all(axis=1))[0])
        raise PoseVectorError(f"pose vector of frame {row} has a non-finite value")
    return v


def _azimuth(camera_azimuth_deg, T: int) -> np.ndarray:
    az = np.asarray(camera_azimuth_deg, dtype=np.float64)
    if az.ndim == 0:
        return np.full(T, float(az))
    if az.shape != (T,):
        raise PoseVectorError(f"camera_azimuth_deg must be a scalar or shape ({T},), "
                              f"got {az.shape}")
    return az


def _joint_index(names) -> dict[str, int]:
    index = {name: i for i, name in enumerate(names)}
    for joint in POSE_JOINTS:
        for member in FOLDED.get(joint, (joint,)):
            if member not in index:
                raise PoseVectorError(f"skeleton lacks joint {member!r} needed by the pose vector")
    return index


def heading_deg(vectors: np.ndarray) -> np.ndarray:
    """Heading (T,) in degrees in (-180, 180] from pose vectors (T, 55): atan2(sin, cos)."""
    v = _as_vectors(vectors)
    return wrap_deg(np.degrees(np.arctan2(v[:, 1], v[:, 0])))


def pose_vectors_to_local_rotations(vectors: np.ndarray, camera_azimuth_deg=0.0,
                                    names=CMU_JOINT_NAMES) -> np.ndarray:
    """Local joint rotations (T, J, 3, 3) on a skeleton with joint ``names`` from pose vectors
    (T, 55); folded joints get the 1/n power of the pose joint's rotation each, joints outside
    the pose identity. camera_azimuth_deg: scalar or (T,)."""
    v = _as_vectors(vectors)
    T = len(v)
    az = _azimuth(camera_azimuth_deg, T)
    index = _joint_index(names)
    out = np.broadcast_to(np.eye(3), (T, len(names), 3, 3)).copy()

    yaw = np.degrees(np.arctan2(v[:, 1], v[:, 0])) + az
    root_angles = np.stack([yaw, v[:, 2], v[:, 3]], axis=1)
    out[:, index[POSE_JOINTS[0]]] = Rotation.from_euler(_ROOT_ORDER, root_angles,
                                                        degrees=True).as_matrix()
    # One scipy call for every joint (its per-call cost dominates at T = 1, per frame).
    joints = POSE_JOINTS[1:]
    angles = v[:, 4:4 + 3 * len(joints)].reshape(T * len(joints), 3)
    rotations = Rotation.from_euler(_JOINT_ORDER, angles, degrees=True)
    matrices = rotations.as_matrix().reshape(T, len(joints), 3, 3)
    n_members = np.array([len(FOLDED.get(joint, (joint,))) for joint in joints])
    folded = np.flatnonzero(n_members > 1)
    rotvec = rotations.as_rotvec().reshape(T, len(joints), 3)[:, folded]
    matrices[:, folded] = Rotation.from_rotvec(
        (rotvec / n_members[folded][None, :, None]).reshape(-1, 3)
    ).as_matrix().reshape(T, len(folded), 3, 3)
    for k, joint in enumerate(joints):
        for member in FOLDED.get(joint, (joint,)):
            out[:, index[member]] = matrices[:, k]
    return out


def forward_kinematics(offsets: np.ndarray, parents: np.ndarray, local_rot: np.ndarray,
                       root_position: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Global joint positions (T, J, 3) (offsets' unit) and rotations (T, J, 3, 3) from bone
    offsets (J, 3), parents (J,) (-1: the root; parents before children), local_rot (T, J, 3,
    3) and root_position (T, 3)."""
    offsets = np.asarray(offsets, dtype=np.float64)
    parents = np.asarray(parents)
    J = len(parents)
    if offsets.shape != (J, 3) or local_rot.ndim != 4 or local_rot.shape[1:] != (J, 3, 3):
        raise PoseVectorError(f"forward_kinematics: offsets {offsets.shape}, parents ({J},) and "
                              f"local_rot {local_rot.shape} do not match (J, 3) / (T, J, 3, 3)")
    T = local_rot.shape[0]
    root_position = np.asarray(root_position, dtype=np.float64)
    if root_position.shape != (T, 3):
        raise PoseVectorError(f"root_position must have shape ({T}, 3), got "
                              f"{root_position.shape}")
    positions = np.empty((T, J, 3))
    rotations = np.empty((T, J, 3, 3))
    for j in range(J):
        p = int(parents[j])
        if p < 0:
            positions[:, j] = root_position + offsets[j]
            rotations[:, j] = local_rot[:, j]
            continue
        if p >= j:
            raise PoseVectorError(f"joint {j} has parent {p}: parents must precede children")
        positions[:, j] = positions[:, p] + rotations[:, p] @ offsets[j]
        rotations[:, j] = rotations[:, p] @ local_rot[:, j]
    return positions, rotations


def joint_positions(vectors: np.ndarray, template: Motion | np.ndarray | None = None,
                    root_position=None, camera_azimuth_deg=0.0) -> np.ndarray:
    """Positions (T, 18, 3) of the POSE_JOINTS, CMU units, from pose vectors (T, 55).
    template: a Motion (its skeleton), (31, 3) CMU bone offsets, or None (CMU_REST_OFFSETS);
    root_position (T, 3), None: the origin."""
    v = _as_vectors(vectors)
    if hasattr(template, "parents"):          # a Motion
        names, parents, offsets = template.names, template.parents, template.offsets
    else:
        offsets = CMU_REST_OFFSETS if template is None else np.asarray(template, np.float64)
        names, parents = CMU_JOINT_NAMES, CMU_PARENTS
        if offsets.shape != (len(names), 3):
            raise PoseVectorError(f"offsets must have shape ({len(names)}, 3) for the CMU "
                                  f"skeleton, got {offsets.shape}")
    if root_position is None:
        root_position = np.zeros((len(v), 3))
    local = pose_vectors_to_local_rotations(v, camera_azimuth_deg, names)
    positions, _ = forward_kinematics(offsets, parents, local, root_position)
    return positions[:, pose_joint_indices(names)]


def _front_back_permutation() -> tuple[np.ndarray, np.ndarray]:
    """(index (55,) int, sign (55,)) of the front/back flip: flipped = sign * v[index]. Left
    and right entries exchanged; the z and y angles (Hips_z too) and cos(heading) negated."""
    names = pose_vector_names()
    other_side = {"Left": "Right", "Right": "Left"}
    index = [names.index(re.sub("^(Left|Right)", lambda m: other_side[m[1]], name))
             for name in names]
    sign = np.where([name.endswith(("_z", "_y")) for name in names], -1.0, 1.0)
    sign[0] = -1.0                                   # cos(180 - h) = -cos h; sin unchanged
    return np.array(index, dtype=np.int64), sign


_FLIP_INDEX, _FLIP_SIGN = _front_back_permutation()


def front_back_flip(vectors: np.ndarray) -> np.ndarray:
    """The pose whose silhouette matches, (55,) or (T, 55) like vectors: the body mirrored in
    depth along the line of sight, which a silhouette cannot tell from it (the derivation:
    docs/code_notes/model.md). Heading h -> 180 - h ((cos, sin) -> (-cos, sin), norm kept),
    Hips_z and each joint's z and y negated, left and right joints exchanged. A signed
    permutation: flipping twice is the identity exactly."""
    v = np.asarray(vectors, dtype=np.float64)
    if v.shape[-1:] != (POSE_DIM,) or v.ndim > 2:
        raise PoseVectorError(f"pose vectors must have shape (55,) or (T, 55), got {v.shape}")
    out = v[..., _FLIP_INDEX] * _FLIP_SIGN
    angles = out[..., ANGLE_SLICE]
    angles[angles == -180.0] = 180.0               # negated 180 back into (-180, 180]
    return out


def image_mirror(vectors: np.ndarray) -> np.ndarray:
    """The pose of the body in the image flipped left to right, (55,) or (T, 55) like vectors:
    front_back_flip turned 180 degrees about the vertical (heading h -> -h, left and right
    exchanged). Mirroring twice is the identity."""
    out = front_back_flip(vectors)
    out[..., :2] = -out[..., :2]
    return out
