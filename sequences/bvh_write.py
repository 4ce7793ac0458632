"""Writing BVH files (what ``track --bvh`` needs; reading is sequences.bvh): pose vectors as a
Motion on a skeleton (pose_vectors_to_motion), a Motion as a BVH file (write_bvh)."""
from __future__ import annotations

import io
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from .motion import Motion
from .pose_vector import (_JOINT_ORDER, PoseVectorError, _as_vectors, _joint_index,
                          pose_vectors_to_local_rotations)
from .skeleton import FOLDED, POSE_JOINTS


# Nine decimals: angles re-derived from rotations (folded joints, the root) then survive a
# write/read cycle to well within 1e-6 degrees.
_DECIMALS = 9


def _as_euler(rotation: Rotation, order: str) -> np.ndarray:
    # Near gimbal lock scipy warns and sets the third angle to zero; the angles still give the
    # same rotation, which is all the conversions need.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return rotation.as_euler(order, degrees=True)


def pose_vectors_to_motion(vectors: np.ndarray, template: Motion, root_position=None,
                           camera_azimuth_deg=0.0) -> Motion:
    """A Motion on ``template``'s skeleton (and fps) from pose vectors (T, 55); root_position
    (T, 3) CMU units, None: template.root_position[0]. Non-folded ZYX joints get the vector's
    angles unchanged; joints outside the pose zeros."""
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
            if joint != POSE_JOINTS[0] and joint not in FOLDED and orders[j] == _JOINT_ORDER:
                k = POSE_JOINTS.index(joint) - 1
                euler[:, j] = v[:, 4 + 3 * k: 7 + 3 * k]
            else:
                euler[:, j] = _as_euler(Rotation.from_matrix(local[:, j]), orders[j])
    return Motion(names=list(template.names), parents=template.parents.copy(),
                  offsets=template.offsets.copy(), end_sites=template.end_sites.copy(),
                  channels=[list(c) for c in template.channels], euler_deg=euler,
                  root_position=root_position.copy(), fps=template.fps, source="")


def _format_vec(values) -> str:
    return " ".join(f"{v:.{_DECIMALS}f}" for v in values)


def write_bvh(path: str | Path, motion: Motion) -> None:
    """Write ``motion`` as a BVH file that read_bvh(path, fps=None, drop_tpose=False) reads
    back to within 1e-6 (angles in degrees, positions in CMU units; 9 decimals are written)."""
    J = len(motion.names)
    out: list[str] = ["HIERARCHY"]

    def emit(j: int, depth: int) -> None:
        pad = "\t" * depth
        kind = "ROOT" if motion.parents[j] < 0 else "JOINT"
        chans = motion.channels[j]
        out.extend([f"{pad}{kind} {motion.names[j]}", f"{pad}{{",
                    f"{pad}\tOFFSET {_format_vec(motion.offsets[j])}",
                    f"{pad}\tCHANNELS {len(chans)} {' '.join(chans)}"])
        for child in np.flatnonzero(motion.parents == j):
            emit(int(child), depth + 1)
        if not np.isnan(motion.end_sites[j]).any():
            out.extend([f"{pad}\tEnd Site", f"{pad}\t{{",
                        f"{pad}\t\tOFFSET {_format_vec(motion.end_sites[j])}", f"{pad}\t}}"])
        out.append(f"{pad}}}")

    emit(int(np.flatnonzero(motion.parents < 0)[0]), 0)
    T = motion.n_frames
    out += ["MOTION", f"Frames: {T}", f"Frame Time: {1.0 / motion.fps:.10g}"]
    frames = np.concatenate([motion.root_position.reshape(T, 3),
                             motion.euler_deg.reshape(T, J * 3)], axis=1)
    buffer = io.StringIO()
    np.savetxt(buffer, frames, fmt=f"%.{_DECIMALS}f")
    Path(path).write_text("\n".join(out) + "\n" + buffer.getvalue(), encoding="utf-8")
