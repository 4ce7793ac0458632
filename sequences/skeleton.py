"""The CMU motion-capture skeleton and the 18 joints of the pose vector. Conventions of every
module that touches joints: Y up; at rest the CMU character faces +Z (toes point +Z), its left
side towards +X; lengths in CMU units (CMU_UNIT_M metres); joints in the CMU BVH conversion's
order (parents before children)."""
from __future__ import annotations

import numpy as np

#: Metres per CMU BVH length unit ((1/0.45) inch).
CMU_UNIT_M = 0.056444

#: The 31 joints of the CMU BVH conversion, in file order (a parent precedes its children).
CMU_JOINT_NAMES: tuple[str, ...] = (
    "Hips",
    "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase",
    "RHipJoint", "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase",
    "LowerBack", "Spine", "Spine1", "Neck", "Neck1", "Head",
    "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand", "LeftFingerBase", "LeftHandIndex1",
    "LThumb",
    "RightShoulder", "RightArm", "RightForeArm", "RightHand", "RightFingerBase",
    "RightHandIndex1", "RThumb",
)

#: Parent index of each joint of CMU_JOINT_NAMES (-1 for the root).
CMU_PARENTS: np.ndarray = np.array([
    -1,
    0, 1, 2, 3, 4,
    0, 6, 7, 8, 9,
    0, 11, 12, 13, 14, 15,
    13, 17, 18, 19, 20, 21,
    20,
    13, 24, 25, 26, 27,
    28, 27], dtype=np.int64)

#: Bone offsets (31, 3) in CMU units of CMU subject 02 (e.g. trial 02_01), used as the default
#: skeleton when no BVH template is at hand (drawing, tests without the data set).
CMU_REST_OFFSETS: np.ndarray = np.array([
    [0.0, 0.0, 0.0],
    [0.0, 0.0, 0.0], [1.65674, -1.80282, 0.62477], [2.5972, -7.13576, 0.0],
    [2.49236, -6.8477, 0.0], [0.19704, -0.54136, 2.14581],
    [0.0, 0.0, 0.0], [-1.6107, -1.80282, 0.62476], [-2.59502, -7.12977, 0.0],
    [-2.4678, -6.78024, 0.0], [-0.23024, -0.63258, 2.13368],
    [0.0, 0.0, 0.0], [0.01961, 2.0545, -0.14112], [0.01021, 2.06436, -0.05921],
    [0.0, 0.0, 0.0], [0.00713, 1.56711, 0.14968], [0.03429, 1.56041, -0.10006],
    [0.0, 0.0, 0.0], [3.54205, 0.90436, -0.17364], [4.86513, 0.0, 0.0],
    [3.35554, 0.0, 0.0], [0.0, 0.0, 0.0], [0.66117, 0.0, 0.0],
    [0.0, 0.0, 0.0],
    [0.0, 0.0, 0.0], [-3.49802, 0.75994, -0.32616], [-5.02649, 0.0, 0.0],
    [-3.36431, 0.0, 0.0], [0.0, 0.0, 0.0],
    [-0.73041, 0.0, 0.0], [0.0, 0.0, 0.0],
])

CMU_REST_OFFSETS.flags.writeable = False
CMU_PARENTS.flags.writeable = False

#: The 18 joints of the pose vector (after Agarwal & Triggs), in pose-vector order.
POSE_JOINTS: tuple[str, ...] = (
    "Hips", "Spine1", "Neck", "Head",
    "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand",
    "RightShoulder", "RightArm", "RightForeArm", "RightHand",
    "LeftUpLeg", "LeftLeg", "LeftFoot",
    "RightUpLeg", "RightLeg", "RightFoot",
)

#: Pose joints whose rotation is the product of several CMU joints' local rotations (parent
#: first). Going back, the rotation is split evenly: each CMU joint gets its 1/n power.
FOLDED: dict[str, tuple[str, ...]] = {
    "Spine1": ("LowerBack", "Spine", "Spine1"),
    "Neck": ("Neck", "Neck1"),
}

#: (parent, child) pose-joint pairs of a stick skeleton (on the CMU skeleton Spine1, Neck and
#: both Shoulders sit at one point).
BONES_FOR_DRAWING: tuple[tuple[str, str], ...] = (
    ("Hips", "Spine1"), ("Spine1", "Neck"), ("Neck", "Head"),
    ("Spine1", "LeftShoulder"), ("LeftShoulder", "LeftArm"), ("LeftArm", "LeftForeArm"),
    ("LeftForeArm", "LeftHand"),
    ("Spine1", "RightShoulder"), ("RightShoulder", "RightArm"), ("RightArm", "RightForeArm"),
    ("RightForeArm", "RightHand"),
    ("Hips", "LeftUpLeg"), ("LeftUpLeg", "LeftLeg"), ("LeftLeg", "LeftFoot"),
    ("Hips", "RightUpLeg"), ("RightUpLeg", "RightLeg"), ("RightLeg", "RightFoot"),
)


def pose_joint_indices(names: list[str] | tuple[str, ...]) -> np.ndarray:
    """Indices (18,) int of POSE_JOINTS within a skeleton's joint ``names``; KeyError naming
    the first pose joint the skeleton lacks."""
    index = {name: i for i, name in enumerate(names)}
    missing = [name for name in POSE_JOINTS if name not in index]
    if missing:
        raise KeyError(f"skeleton lacks pose joint {missing[0]!r}")
    return np.array([index[name] for name in POSE_JOINTS], dtype=np.int64)
