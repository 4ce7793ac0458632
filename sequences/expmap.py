"""Read the exponential-map CMU sequences of cmu_extra/expmap/ as CMU BVH motion.

Format (chaneyddtt/Convolutional-Sequence-to-Sequence-Model-for-Human-Dynamics, MIT licence,
``data/cmu_mocap``): one frame a line, 117 comma-separated numbers, the root position (3, CMU
units, Y up) then for each of 38 joints an exponential map (axis times angle, radians). The 38
joints are the 31 joints of the CMU BVH conversion with its 7 end sites inserted as joints
(parents, offsets and index tables of the source's ``forward_kinematics_cmu.py``, whose offsets
are skeleton.CMU_REST_OFFSETS and CMU_REST_END_SITES times 70). Its forward kinematics uses row
vectors, ``xyz = offset . R_parent + xyz_parent`` and ``R = R_local . R_parent``, so a joint's
local rotation in this project's column convention is the *transpose* of Rodrigues(expmap).

Because the skeleton, its rest pose and its joint frames are those of the CMU BVH conversion,
no fit is needed: each BVH joint takes its expmap joint's rotation (tests check that both
forward kinematics agree). The files are the conversion's frames at 120 fps, its added T-pose
frame included (train/walking/walking_1.txt is 02_01.bvh frame for frame; docs/cmu_extra.md).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from regressor.errors import SilhouettePoseError

from .bvh import Motion, matrices_to_euler, resample
from .skeleton import CMU_JOINT_NAMES, CMU_PARENTS, CMU_REST_OFFSETS
from .skeleton_tables import CMU_REST_END_SITES

#: Frames per second of the expmap files (found, not stated by the source: docs/cmu_extra.md).
EXPMAP_FPS = 120.0
#: Numbers per line: root position (3) + 38 joints x 3.
EXPMAP_WIDTH = 117
#: The source's 38 joints: CMU_JOINT_NAMES with the end sites (named "<joint>_end") inserted
#: after their joint, in the source's order.
EXPMAP_JOINTS: tuple[str, ...] = (
    "Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase", "LeftToeBase_end",
    "RHipJoint", "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase", "RightToeBase_end",
    "LowerBack", "Spine", "Spine1", "Neck", "Neck1", "Head", "Head_end",
    "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand", "LeftFingerBase", "LeftHandIndex1",
    "LeftHandIndex1_end", "LThumb", "LThumb_end",
    "RightShoulder", "RightArm", "RightForeArm", "RightHand", "RightFingerBase",
    "RightHandIndex1", "RightHandIndex1_end", "RThumb", "RThumb_end",
)
#: Parent of each of the 38 joints: the ``parent`` table of the source's
#: forward_kinematics_cmu.py (0-based), transcribed under its MIT licence, Copyright (c) 2018
#: Li Chen.
EXPMAP_PARENTS: np.ndarray = np.array(
    [-1, 0, 1, 2, 3, 4, 5, 0, 7, 8, 9, 10, 11, 0, 13, 14, 15, 16, 17, 18, 15, 20, 21, 22, 23,
     24, 25, 23, 27, 15, 29, 30, 31, 32, 33, 34, 32, 36], dtype=np.int64)
#: Index of each CMU BVH joint (CMU_JOINT_NAMES order) among the 38.
CMU_IN_EXPMAP: np.ndarray = np.array([EXPMAP_JOINTS.index(n) for n in CMU_JOINT_NAMES])


def _expmap_offsets() -> np.ndarray:
    """(38, 3) bone offsets, CMU units: the source's table divided by its factor 70."""
    out = np.zeros((len(EXPMAP_JOINTS), 3))
    out[CMU_IN_EXPMAP] = CMU_REST_OFFSETS
    for j, name in enumerate(CMU_JOINT_NAMES):
        if not np.isnan(CMU_REST_END_SITES[j]).any():
            out[EXPMAP_JOINTS.index(f"{name}_end")] = CMU_REST_END_SITES[j]
    out.flags.writeable = False
    return out


#: (38, 3) bone offsets of the source's skeleton, CMU units (subject 02's, for every file).
EXPMAP_OFFSETS = _expmap_offsets()


class ExpmapError(SilhouettePoseError, ValueError):
    """A malformed expmap file; the message names the file and line."""


def read_expmap(path: str | Path) -> np.ndarray:
    """The frames (T, 117) of an expmap text file; ExpmapError naming the file and line if a
    line has another count of numbers or a non-finite one, FileNotFoundError if absent."""
    path = Path(path)
    lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    rows = []
    for n, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            row = np.array([float(v) for v in line.split(",")])
        except ValueError:
            raise ExpmapError(f"{path.name} line {n}: not comma-separated numbers") from None
        if row.shape != (EXPMAP_WIDTH,):
            raise ExpmapError(f"{path.name} line {n}: expected {EXPMAP_WIDTH} numbers, got "
                              f"{len(row)}")
        if not np.isfinite(row).all():
            raise ExpmapError(f"{path.name} line {n}: non-finite value")
        rows.append(row)
    if not rows:
        raise ExpmapError(f"{path.name}: no frames")
    return np.stack(rows)


def expmap_local_rotations(frames: np.ndarray) -> np.ndarray:
    """Local rotations (T, 38, 3, 3), column convention (child vector in parent frame = R @ v),
    of expmap frames (T, 117): the transpose of Rodrigues(r), i.e. the rotation by -r."""
    frames = np.asarray(frames, dtype=np.float64)
    T = len(frames)
    r = frames[:, 3:].reshape(T * len(EXPMAP_JOINTS), 3)
    return Rotation.from_rotvec(-r).as_matrix().reshape(T, len(EXPMAP_JOINTS), 3, 3)


def expmap_positions(frames: np.ndarray) -> np.ndarray:
    """Joint positions (T, 38, 3), CMU units, Y up: the source's forward kinematics (with
    offsets in CMU units, so they agree with the root position)."""
    from .pose_vector import forward_kinematics
    frames = np.asarray(frames, dtype=np.float64)
    positions, _ = forward_kinematics(EXPMAP_OFFSETS, EXPMAP_PARENTS,
                                      expmap_local_rotations(frames), frames[:, :3])
    return positions


def _is_tpose(euler_deg: np.ndarray) -> np.ndarray:
    """(T,) bool: frames whose root rotation is zero and whose angles are all whole degrees
    (the T-pose frame the CMU BVH conversion adds; the expmap files kept it)."""
    whole = np.abs(euler_deg - np.round(euler_deg)) < 1e-4
    return whole.all(axis=(1, 2)) & (np.abs(euler_deg[:, 0]) < 1e-4).all(axis=1)


def expmap_to_motion(frames: np.ndarray, fps: float | None = 30.0,
                     source_fps: float = EXPMAP_FPS, source: str = "",
                     drop_tpose: bool = True) -> Motion:
    """A Motion on the 31-joint CMU skeleton (subject 02's offsets, ZYX channels) from expmap
    frames (T, 117), resampled from source_fps to fps (None keeps the source rate).
    drop_tpose drops a leading T-pose frame (see _is_tpose)."""
    frames = np.asarray(frames, dtype=np.float64)
    if frames.ndim != 2 or frames.shape[1] != EXPMAP_WIDTH or len(frames) == 0:
        raise ExpmapError(f"{source or 'expmap frames'}: expected (T, {EXPMAP_WIDTH}) frames, "
                          f"got {frames.shape}")
    local = expmap_local_rotations(frames)[:, CMU_IN_EXPMAP]
    euler = matrices_to_euler(local, ["ZYX"] * len(CMU_JOINT_NAMES))
    root = frames[:, :3].copy()
    if drop_tpose and len(frames) > 1 and _is_tpose(euler[:1])[0]:
        euler, root = euler[1:], root[1:]
    channels = [["Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"]]
    channels += [["Zrotation", "Yrotation", "Xrotation"] for _ in CMU_JOINT_NAMES[1:]]
    motion = Motion(names=list(CMU_JOINT_NAMES), parents=CMU_PARENTS.copy(),
                    offsets=np.array(CMU_REST_OFFSETS), end_sites=np.array(CMU_REST_END_SITES),
                    channels=channels, euler_deg=euler, root_position=root,
                    fps=float(source_fps), source=source)
    return motion if fps is None else resample(motion, fps)


def read_expmap_motion(path: str | Path, fps: float | None = 30.0) -> Motion:
    """An expmap file as a Motion on the CMU skeleton at ``fps`` (see expmap_to_motion)."""
    path = Path(path)
    return expmap_to_motion(read_expmap(path), fps=fps, source=path.name)


def motion_to_expmap(motion: Motion) -> np.ndarray:
    """Expmap frames (T, 117) of a Motion on the 31-joint CMU skeleton (the inverse of
    expmap_to_motion at the source rate; end sites get zero rotations)."""
    if list(motion.names) != list(CMU_JOINT_NAMES):
        raise ExpmapError("motion_to_expmap needs the 31-joint CMU skeleton")
    T = motion.n_frames
    r = np.zeros((T, len(EXPMAP_JOINTS), 3))
    local = motion.local_rotations().reshape(-1, 3, 3)
    r[:, CMU_IN_EXPMAP] = -Rotation.from_matrix(local).as_rotvec().reshape(T, -1, 3)
    return np.concatenate([motion.root_position, r.reshape(T, -1)], axis=1)


def expmap_files(root: str | Path) -> list[Path]:
    """Every ``*.txt`` sequence under an expmap folder (train/ and test/ by action), sorted;
    the source's Python files and licence are not sequences."""
    root = Path(root)
    if not root.is_dir():
        raise ExpmapError(f"expmap folder not found: {root}")
    return sorted(p for p in root.glob("*/*/*.txt"))


def expmap_name(path: str | Path) -> str:
    """A trial name for an expmap file: 'xm_train_walking_extra_13' for
    train/walking_extra/walking_13.txt (split, action folder, the file's number)."""
    path = Path(path)
    number = path.stem.rsplit("_", 1)[-1]
    return f"xm_{path.parent.parent.name}_{path.parent.name}_{number}"
