"""Hand-made motions on the CMU skeleton for tests that must run without ../shared."""
from __future__ import annotations

import numpy as np

from sequences.bvh import Motion
from sequences.skeleton import CMU_JOINT_NAMES, CMU_PARENTS, CMU_REST_OFFSETS
from sequences.skeleton_tables import CMU_REST_END_SITES

ROOT_CHANNELS = ["Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"]
JOINT_CHANNELS = ["Zrotation", "Yrotation", "Xrotation"]


def cmu_motion(euler_deg: np.ndarray, root_position: np.ndarray, fps: float = 30.0,
               source: str = "synthetic") -> Motion:
    """A Motion on the CMU skeleton (subject 02's rest offsets) from local angles
    (T, 31, 3) degrees in the BVH channel order (Z, Y, X) and root positions (T, 3) CMU units."""
    channels = [list(ROOT_CHANNELS)] + [list(JOINT_CHANNELS)] * (len(CMU_JOINT_NAMES) - 1)
    return Motion(names=list(CMU_JOINT_NAMES), parents=CMU_PARENTS.copy(),
                  offsets=CMU_REST_OFFSETS.copy(), end_sites=CMU_REST_END_SITES.copy(),
                  channels=channels, euler_deg=np.asarray(euler_deg, dtype=np.float64),
                  root_position=np.asarray(root_position, dtype=np.float64), fps=fps,
                  source=source)


def joint(name: str) -> int:
    """Index of a CMU joint."""
    return CMU_JOINT_NAMES.index(name)


def gait_walk(T: int, heading_deg) -> Motion:
    """A walk along +X at 30 fps, the legs and arms swinging at 1 Hz and the knees bending;
    heading_deg: the root's rotation about the vertical, a number or one per frame (T,)."""
    euler = np.zeros((T, len(CMU_JOINT_NAMES), 3))
    phase = np.arange(T) * 2 * np.pi / 30
    for name, amp in (("LeftUpLeg", 30), ("RightUpLeg", -30), ("LeftArm", -25),
                      ("RightArm", 25)):
        euler[:, joint(name), 2] = amp * np.sin(phase)
    for name in ("LeftLeg", "RightLeg"):
        euler[:, joint(name), 2] = 40 * np.maximum(0, np.sin(phase + 1.0))
    for name, z in (("LeftArm", -70), ("RightArm", 70)):
        euler[:, joint(name), 0] = z
    euler[:, 0, 1] = heading_deg
    root = np.column_stack([0.5 * np.arange(T), np.full(T, 17.0), np.zeros(T)])
    return cmu_motion(euler, root, fps=30.0, source="walker")
