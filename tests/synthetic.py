"""Hand-made motions on the CMU skeleton for tests that must run without ../shared."""
from __future__ import annotations

import numpy as np

from sequences.bvh import Motion
from sequences.skeleton import CMU_JOINT_NAMES, CMU_PARENTS, CMU_REST_END_SITES, CMU_REST_OFFSETS

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
