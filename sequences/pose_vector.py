"""The 55-D pose vector and every conversion to and from it.

Layout (POSE_DIM = 55), all angles in degrees:
    [0] cos(heading), [1] sin(heading)
    [2] Hips_x, [3] Hips_z: root tilt angles
    [4:55] 17 joints (POSE_JOINTS[1:]) x (z, y, x) Euler angles: local rotation R = Rz @ Ry @ Rx
           (intrinsic ZYX, the CMU BVH channel order). Folded joints (skeleton.FOLDED) carry the
           product of their CMU joints' local rotations.

Root and heading. The root's global rotation is decomposed as
    R_root = Ry(yaw) @ Rx(Hips_x) @ Rz(Hips_z)      (yaw in (-180, 180], Hips_x in [-90, 90])
and heading = yaw - camera_azimuth. World frame: Y up; at rest the subject faces +Z. A camera
with azimuth ``az`` sits in direction Ry(az) @ (0, 0, 1) from the subject, looking at it. So
heading 0 means the subject faces the camera, and a positive heading means the subject is
turned counter-clockwise seen from above (right-handed about +Y) away from facing the camera.
Moving the camera by +d degrees of azimuth changes the heading by -d. The (cos, sin) pair need
not have unit norm: heading = atan2(sin, cos); the norm measures how unambiguous an estimate was.

Lengths are CMU units (skeleton.CMU_UNIT_M metres each).
"""
from __future__ import annotations

import warnings

import numpy as np
from scipy.spatial.transform import Rotation

from regressor.angles import POSE_DIM, wrap_deg
from regressor.errors import SilhouettePoseError

from .motion import Motion
from .skeleton import (CMU_JOINT_NAMES, CMU_PARENTS, CMU_REST_OFFSETS, FOLDED, POSE_JOINT_PART,
                       POSE_JOINTS, pose_joint_indices)

#: Entries that are angles in degrees (all but the heading's cos and sin).
ANGLE_SLICE = slice(2, POSE_DIM)
_ROOT_ORDER = "YXZ"    # R_root = Ry(yaw) @ Rx(tilt_x) @ Rz(tilt_z), intrinsic
_JOINT_ORDER = "ZYX"   # R = Rz @ Ry @ Rx, intrinsic, as the CMU BVH channels


class PoseVectorError(SilhouettePoseError, ValueError):
    """Pose vectors or a skeleton of the wrong shape or content."""


def pose_vector_names() -> list[str]:
    """The 55 entry names: heading_cos, heading_sin, Hips_x, Hips_z, Spine1_z, Spine1_y, ..."""
    names = ["heading_cos", "heading_sin", "Hips_x", "Hips_z"]
    for joint in POSE_JOINTS[1:]:
        names += [f"{joint}_z", f"{joint}_y", f"{joint}_x"]
    return names


def angle_mask() -> np.ndarray:
    """(55,) bool: True for entries that are angles in degrees."""
    mask = np.zeros(POSE_DIM, dtype=bool)
    mask[ANGLE_SLICE] = True
    return mask


def body_part_names() -> list[str]:
    """Body part of each of the 55 entries: heading, torso, head, left/right arm, left/right leg.

    The root tilt angles count as torso.
    """
    parts = ["heading", "heading", "torso", "torso"]
    for joint in POSE_JOINTS[1:]:
        parts += [POSE_JOINT_PART[joint]] * 3
    return parts


#: Body part of each entry (tuple of 55 strings), see body_part_names().
PART_OF_ENTRY: tuple[str, ...] = tuple(body_part_names())


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


def _as_euler(rotation: Rotation, order: str) -> np.ndarray:
    # Near gimbal lock scipy warns and sets the third angle to zero; the angles still give the
    # same rotation, which is all the conversions need.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return rotation.as_euler(order, degrees=True)


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


def heading_norm(vectors: np.ndarray) -> np.ndarray:
    """Norm (T,) of the (cos, sin) heading pair of pose vectors (T, 55); 1 for exact poses."""
    v = _as_vectors(vectors)
    return np.hypot(v[:, 0], v[:, 1])


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


def pose_vectors_to_local_rotations(vectors: np.ndarray, camera_azimuth_deg=0.0,
                                    names=CMU_JOINT_NAMES) -> np.ndarray:
    """Local joint rotations (T, J, 3, 3) on a skeleton with joint ``names`` (default: the 31
    CMU joints) from pose vectors (T, 55). Folded joints get the 1/n power of the pose joint's
    rotation each; joints outside the pose are identity. camera_azimuth_deg: scalar or (T,)."""
    v = _as_vectors(vectors)
    T = len(v)
    az = _azimuth(camera_azimuth_deg, T)
    index = _joint_index(names)
    out = np.broadcast_to(np.eye(3), (T, len(names), 3, 3)).copy()

    yaw = np.degrees(np.arctan2(v[:, 1], v[:, 0])) + az
    root_angles = np.stack([yaw, v[:, 2], v[:, 3]], axis=1)
    out[:, index[POSE_JOINTS[0]]] = Rotation.from_euler(_ROOT_ORDER, root_angles,
                                                        degrees=True).as_matrix()
    # Every joint's rotation in one call (scipy's per-call cost dominates at T = 1, the
    # tracker's per-frame case); folded joints then take the 1/n power of theirs.
    joints = POSE_JOINTS[1:]
    angles = v[:, 4:4 + 3 * len(joints)].reshape(T * len(joints), 3)
    rotations = Rotation.from_euler(_JOINT_ORDER, angles, degrees=True)
    matrices = rotations.as_matrix().reshape(T, len(joints), 3, 3)
    n_members = np.array([len(FOLDED.get(joint, (joint,))) for joint in joints])
    folded = np.flatnonzero(n_members > 1)
    if len(folded):
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
    """Global joint positions (T, J, 3) and rotations (T, J, 3, 3).

    offsets: (J, 3) bone offsets (any length unit; output has the same); parents: (J,) int with
    -1 for the root and every parent before its child; local_rot: (T, J, 3, 3); root_position:
    (T, 3). Joint j sits at position[parent] + R_global[parent] @ offsets[j] and turns by
    R_global[j] = R_global[parent] @ local_rot[j].
    """
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


def joint_positions(vectors: np.ndarray, template: Motion | np.ndarray | None = None,
                    root_position=None, camera_azimuth_deg=0.0) -> np.ndarray:
    """Positions (T, 18, 3) of the POSE_JOINTS, CMU units, from pose vectors (T, 55).

    template: a Motion (its skeleton), or (31, 3) bone offsets of the CMU skeleton, or None for
    skeleton.CMU_REST_OFFSETS. root_position: (T, 3), None puts the root at the origin.
    With camera_azimuth_deg = 0 the camera looks from +Z, so heading 0 faces it.
    """
    v = _as_vectors(vectors)
    if isinstance(template, Motion):
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
    """(index (55,) int, sign (55,)) of the front/back flip: flipped = sign * v[index]."""
    names = pose_vector_names()
    position = {name: i for i, name in enumerate(names)}

    def other_side(name: str) -> str:
        for a, b in (("Left", "Right"), ("Right", "Left")):
            if name.startswith(a):
                return b + name[len(a):]
        return name

    index = np.array([position[other_side(name)] for name in names], dtype=np.int64)
    sign = np.ones(POSE_DIM)
    sign[0] = -1.0                                   # cos(180 - h) = -cos h; sin unchanged
    sign[3] = -1.0                                   # Hips_z
    for i, name in enumerate(names[4:], start=4):
        if name.endswith(("_z", "_y")):
            sign[i] = -1.0
    return index, sign


_FLIP_INDEX, _FLIP_SIGN = _front_back_permutation()


def front_back_flip(vectors: np.ndarray) -> np.ndarray:
    """The pose whose silhouette matches: the body mirrored in depth along the line of sight.

    vectors: (55,) or (T, 55) pose vectors; returns the same shape. A silhouette (a projection
    along the line of sight) cannot tell a body from its reflection D = diag(1, 1, -1) in depth
    (camera frame, z along the line of sight, reflection plane through the root). Writing
    D = Ry(180) @ Mx with Mx = diag(-1, 1, 1) the body's left/right mirror, the reflected body is
    a proper pose of the mirrored skeleton (left and right bones exchanged, Mx @ offset):
    every global rotation G becomes D @ G @ Mx, hence
    - root: Ry(yaw) Rx(a) Rz(b) -> Ry(180 - yaw) Rx(a) Rz(-b): heading h -> 180 - h,
      i.e. (cos, sin) -> (-cos, sin) with the norm (the ambiguity measure) kept; Hips_x kept,
      Hips_z negated;
    - every other joint: local rotation L -> Mx @ L @ Mx, which for R = Rz(z) Ry(y) Rx(x) is
      Rz(-z) Ry(-y) Rx(x); and left and right joints exchange their angles.
    Seen from the front (h = 0) this is h + 180 with left and right exchanged, the paper's
    front/back confusion; seen in profile (h = 90) the heading stays and only the limbs swap
    (which leg is nearer the camera). It is a signed permutation, so flipping twice is the
    identity exactly.
    """
    v = np.asarray(vectors, dtype=np.float64)
    if v.shape[-1:] != (POSE_DIM,) or v.ndim > 2:
        raise PoseVectorError(f"pose vectors must have shape (55,) or (T, 55), got {v.shape}")
    out = v[..., _FLIP_INDEX] * _FLIP_SIGN
    angles = out[..., ANGLE_SLICE]
    angles[angles == -180.0] = 180.0               # negated 180 back into (-180, 180]
    return out


def image_mirror(vectors: np.ndarray) -> np.ndarray:
    """The pose of the body seen in the mirror image (the video flipped left to right).

    vectors: (55,) or (T, 55) pose vectors; returns the same shape. The image's left/right
    mirror is diag(-1, 1, 1) in the camera frame, the depth reflection of front_back_flip
    turned 180 degrees about the vertical: the flipped pose with its heading h -> -h, i.e.
    (cos, sin) -> (cos, -sin) (norm kept), left and right joints exchanged. Mirroring twice is
    the identity exactly; the member facing the camera's half stays so (cos is kept). The
    training mirrors its silhouettes with it (lab.training, limb networks).
    """
    out = front_back_flip(vectors)
    out[..., 0] = -out[..., 0]
    out[..., 1] = -out[..., 1]
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
