"""Retarget the "DAZ-friendly" CMU dances of cmu_extra/dances/ onto the 31-joint CMU skeleton.

The dances (papagina/Auto_Conditioned_RNN_motion, MIT licence) are BVH files on another
skeleton (43 joints: hip, abdomen, chest, neck, head, collars, shoulders, ..., fingers; ZXY
channels; centimetres, Y up, facing +Z with the left side towards +X at rest, like CMU). Its
rest pose differs from CMU's (the CMU legs are splayed 20 degrees and the arms level, the DAZ
legs straight, collar bones and hands bent otherwise), so local angles do not carry over.

Method (vectorized over frames, no iterative fit): forward kinematics of the source gives
joint positions and global segment rotations. Each driven CMU joint then gets a global rotation
from one of two rules (RULES):
- "bone": the CMU bone points exactly where the source bone points (its direction from the
  source's 3-D joint positions) and its twist about the bone follows the source segment's twist
  (the source segment's axis ``hint`` projected off the bone): the TRIAD of (bone, hint).
- "same": the source segment's global rotation (pelvis hint, spine, neck, head, collars),
  where the two skeletons' rest frames agree and joint positions alone would not fix twist.
Local rotations follow as G_parent^T G; CMU joints that fold into one pose-vector joint
(skeleton.FOLDED) share the rotation evenly as the pose vector does; the others (hip joints,
fingers, toes) are identity. The root is placed so that the midpoint of the CMU hip joints
lies on the source's, scaled by the ratio of leg lengths. Bone directions are thus matched
exactly; positions differ by the skeletons' proportions (docs/cmu_extra.md gives the residual).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from regressor.errors import SilhouettePoseError

from .bvh import Motion, matrices_to_euler, read_bvh, resample
from .pose_vector import forward_kinematics
from .skeleton import CMU_JOINT_NAMES, CMU_PARENTS, CMU_REST_OFFSETS, CMU_UNIT_M, FOLDED
from .skeleton_tables import CMU_REST_END_SITES

_X, _Y, _Z = np.eye(3)

#: (CMU joint, source joint, rule, source bone end, CMU bone end, hint axis): how each driven
#: CMU joint's global rotation is found. Bone ends name the child joint whose position fixes
#: the bone's direction ("<joint>@end" = that joint's end site); the hint axis (rest frame)
#: fixes the twist. Rule "same" copies the source segment's global rotation.
RULES: tuple[tuple[str, str, str, str, str, np.ndarray], ...] = (
    ("Hips", "hip", "hips", "", "", _Y),
    ("Spine1", "chest", "same", "", "", _Y),
    ("Neck1", "neck", "same", "", "", _Y),
    ("Head", "head", "same", "", "", _Y),
    ("LeftShoulder", "lCollar", "same", "", "", _Y),
    ("RightShoulder", "rCollar", "same", "", "", _Y),
    ("LeftArm", "lShldr", "bone", "lForeArm", "LeftForeArm", _Z),
    ("LeftForeArm", "lForeArm", "bone", "lHand", "LeftHand", _Z),
    ("LeftHand", "lHand", "bone", "lMid1", "LeftHandIndex1", _Z),
    ("RightArm", "rShldr", "bone", "rForeArm", "RightForeArm", _Z),
    ("RightForeArm", "rForeArm", "bone", "rHand", "RightHand", _Z),
    ("RightHand", "rHand", "bone", "rMid1", "RightHandIndex1", _Z),
    ("LeftUpLeg", "lThigh", "bone", "lShin", "LeftLeg", _Z),
    ("LeftLeg", "lShin", "bone", "lFoot", "LeftFoot", _Z),
    ("LeftFoot", "lFoot", "bone", "lFoot@end", "LeftToeBase@end", _X),
    ("RightUpLeg", "rThigh", "bone", "rShin", "RightLeg", _Z),
    ("RightLeg", "rShin", "bone", "rFoot", "RightFoot", _Z),
    ("RightFoot", "rFoot", "bone", "rFoot@end", "RightToeBase@end", _X),
)
#: Source and CMU joints whose midpoints are the pelvis (hip joints) and set the root.
HIP_JOINTS = (("lThigh", "rThigh"), ("LeftUpLeg", "RightUpLeg"))
#: Joint pairs (source, CMU) compared by the fit residual.
RESIDUAL_PAIRS: tuple[tuple[str, str], ...] = (
    ("lThigh", "LeftUpLeg"), ("lShin", "LeftLeg"), ("lFoot", "LeftFoot"),
    ("lFoot@end", "LeftToeBase@end"), ("rThigh", "RightUpLeg"), ("rShin", "RightLeg"),
    ("rFoot", "RightFoot"), ("rFoot@end", "RightToeBase@end"),
    ("lShldr", "LeftArm"), ("lForeArm", "LeftForeArm"), ("lHand", "LeftHand"),
    ("rShldr", "RightArm"), ("rForeArm", "RightForeArm"), ("rHand", "RightHand"),
    ("head", "Head"),
)
#: Source frames dropped after the rest frame: the files start by settling from it (joint
#: rotations change by up to 59 degrees a frame over the first 7 frames, then by 5 or less).
SETTLING_FRAMES = 8
#: Frames per second of each dance folder (the BVH headers all say 120; the source's
#: readme.txt and the motion's speed say salsa is 60: docs/cmu_extra.md).
DANCE_FPS = {"salsa": 60.0, "indian": 120.0, "martial": 120.0}


class RetargetError(SilhouettePoseError, ValueError):
    """A source skeleton lacking a joint the retargeting needs."""


@dataclass
class Retargeted:
    """A retargeted motion and how well it fits. motion: on the CMU skeleton; residual_mm:
    (T, len(RESIDUAL_PAIRS)) distance between each CMU joint and its source joint (source
    scaled to the CMU leg length), millimetres; scale: CMU units per source unit."""

    motion: Motion
    residual_mm: np.ndarray
    scale: float


def _frames(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Orthonormal frames (..., 3, 3), columns [a, b', a x b'] with b' = b made normal to a."""
    e1 = a / np.linalg.norm(a, axis=-1, keepdims=True)
    e2 = b - (b * e1).sum(-1, keepdims=True) * e1
    e2 = e2 / np.linalg.norm(e2, axis=-1, keepdims=True)
    return np.stack([e1, e2, np.cross(e1, e2)], axis=-1)


def triad(a0: np.ndarray, b0: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotations (T, 3, 3) taking direction a0 (3,) exactly to a (T, 3) and the plane of
    (a0, b0) to that of (a, b) (b0, b need not be normal to a0, a)."""
    return _frames(a, b) @ _frames(a0, b0).T


@dataclass
class _Pose:
    """Forward kinematics of a skeleton: positions (T, J, 3), global rotations (T, J, 3, 3),
    end sites (T, J, 3) (NaN where none), joint names."""

    P: np.ndarray
    G: np.ndarray
    E: np.ndarray
    names: list[str]

    def point(self, name: str) -> np.ndarray:
        if name.endswith("@end"):
            return self.E[:, self.names.index(name[:-4])]
        return self.P[:, self.names.index(name)]


def _pose(names, parents, offsets, end_sites, local, root) -> _Pose:
    P, G = forward_kinematics(offsets, parents, local, root)
    E = P + np.einsum("tjab,jb->tja", G, np.nan_to_num(end_sites, nan=0.0))
    E[:, np.isnan(end_sites).any(axis=1)] = np.nan
    return _Pose(P, G, E, list(names))


def _rest_pose(names, parents, offsets, end_sites) -> _Pose:
    local = np.broadcast_to(np.eye(3), (1, len(names), 3, 3))
    return _pose(names, parents, offsets, end_sites, local, np.zeros((1, 3)))


def _leg_length(rest: _Pose, hip: str, knee: str, ankle: str) -> float:
    p = lambda n: rest.point(n)[0]  # noqa: E731
    return float(np.linalg.norm(p(knee) - p(hip)) + np.linalg.norm(p(ankle) - p(knee)))


def _check_source(names: list[str]) -> None:
    needed = {r[1] for r in RULES} | {r[3].removesuffix("@end") for r in RULES if r[3]}
    needed |= set(HIP_JOINTS[0])
    missing = sorted(needed - set(names))
    if missing:
        raise RetargetError(f"the source skeleton lacks joints {missing}")


def _cmu_rest() -> _Pose:
    return _rest_pose(CMU_JOINT_NAMES, CMU_PARENTS, CMU_REST_OFFSETS, CMU_REST_END_SITES)


def _rest_direction(rest: _Pose, joint: str, end: str) -> np.ndarray:
    return rest.point(end)[0] - rest.point(joint)[0]


def _hip_line(pose: _Pose, pair: tuple[str, str]) -> np.ndarray:
    """Right hip joint to left hip joint (T, 3)."""
    return pose.point(pair[0]) - pose.point(pair[1])


def _hip_middle(pose: _Pose, pair: tuple[str, str]) -> np.ndarray:
    return (pose.point(pair[0]) + pose.point(pair[1])) / 2.0


def cmu_targets(src: _Pose) -> dict[str, np.ndarray]:
    """Global rotations (T, 3, 3) of the driven CMU joints from a source pose (see RULES)."""
    cmu_rest = _cmu_rest()
    out = {}
    for cmu, joint, rule, src_end, cmu_end, hint in RULES:
        G = src.G[:, src.names.index(joint)]
        if rule == "same":
            out[cmu] = G
        elif rule == "hips":
            out[cmu] = triad(_hip_line(cmu_rest, HIP_JOINTS[1])[0], hint,
                             _hip_line(src, HIP_JOINTS[0]), G @ hint)
        else:
            out[cmu] = triad(_rest_direction(cmu_rest, cmu, cmu_end), hint,
                             src.point(src_end) - src.point(joint), G @ hint)
    return out


def cmu_local_rotations(targets: dict[str, np.ndarray]) -> np.ndarray:
    """Local rotations (T, 31, 3, 3) of the CMU skeleton reaching the ``targets`` global
    rotations; a folded chain (skeleton.FOLDED) whose last joint is a target shares the
    rotation evenly (each joint the 1/n power); all other joints are identity."""
    T = len(next(iter(targets.values())))
    J = len(CMU_JOINT_NAMES)
    local = np.broadcast_to(np.eye(3), (T, J, 3, 3)).copy()
    G = np.empty((T, J, 3, 3))
    chain_of = {members[0]: members for members in FOLDED.values()
                if members[-1] in targets}
    folded = {m for members in chain_of.values() for m in members}
    for j, name in enumerate(CMU_JOINT_NAMES):
        p = int(CMU_PARENTS[j])
        Gp = G[:, p] if p >= 0 else np.broadcast_to(np.eye(3), (T, 3, 3))
        if name in chain_of:
            members = chain_of[name]
            whole = np.swapaxes(Gp, -1, -2) @ targets[members[-1]]
            part = Rotation.from_matrix(whole).as_rotvec() / len(members)
            for m in members:
                local[:, CMU_JOINT_NAMES.index(m)] = Rotation.from_rotvec(part).as_matrix()
        elif name in targets and name not in folded:
            local[:, j] = np.swapaxes(Gp, -1, -2) @ targets[name]
        G[:, j] = Gp @ local[:, j]
    return local


def _cmu_channels() -> list[list[str]]:
    root = ["Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"]
    return [root] + [["Zrotation", "Yrotation", "Xrotation"] for _ in CMU_JOINT_NAMES[1:]]


def retarget(source: Motion) -> Retargeted:
    """The source motion (a dance BVH's skeleton, see RULES) on the 31-joint CMU skeleton
    (subject 02's offsets, ZYX channels, the source's rate), with the fit's residual."""
    _check_source(source.names)
    src = _pose(source.names, source.parents, source.offsets, source.end_sites,
                source.local_rotations(), source.root_position)
    src_rest = _rest_pose(source.names, source.parents, source.offsets, source.end_sites)
    cmu_rest = _cmu_rest()
    leg = ("lThigh", "lShin", "lFoot"), ("LeftUpLeg", "LeftLeg", "LeftFoot")
    scale = _leg_length(cmu_rest, *leg[1]) / _leg_length(src_rest, *leg[0])
    local = cmu_local_rotations(cmu_targets(src))
    G_root = local[:, 0]
    root = scale * _hip_middle(src, HIP_JOINTS[0]) - G_root @ _hip_middle(cmu_rest,
                                                                            HIP_JOINTS[1])[0]
    cmu = _pose(CMU_JOINT_NAMES, CMU_PARENTS, CMU_REST_OFFSETS, CMU_REST_END_SITES, local, root)
    residual = np.stack([np.linalg.norm(cmu.point(c) - scale * src.point(s), axis=-1)
                         for s, c in RESIDUAL_PAIRS], axis=1)
    euler = matrices_to_euler(local, ["ZYX"] * len(CMU_JOINT_NAMES))
    motion = Motion(names=list(CMU_JOINT_NAMES), parents=CMU_PARENTS.copy(),
                    offsets=np.array(CMU_REST_OFFSETS), end_sites=np.array(CMU_REST_END_SITES),
                    channels=_cmu_channels(), euler_deg=euler, root_position=root,
                    fps=source.fps, source=source.source)
    return Retargeted(motion, residual * CMU_UNIT_M * 1000.0, float(scale))


def source_from_cmu(cmu_motion: Motion, template: Motion) -> Motion:
    """The inverse of retarget: a CMU-skeleton motion on the source skeleton of ``template``
    (its joints outside RULES held at identity). Builds test sequences in the source format;
    retarget() of the result gives back the driven CMU joints' global rotations."""
    _check_source(template.names)
    cmu = _pose(cmu_motion.names, cmu_motion.parents, cmu_motion.offsets, cmu_motion.end_sites,
                cmu_motion.local_rotations(), cmu_motion.root_position)
    cmu_rest = _cmu_rest()
    src_rest = _rest_pose(template.names, template.parents, template.offsets,
                          template.end_sites)
    T, J = cmu_motion.n_frames, len(template.names)
    targets = {}
    for c, joint, rule, src_end, cmu_end, hint in RULES:
        Gc = cmu.G[:, cmu.names.index(c)]
        if rule == "same":
            targets[joint] = Gc
        elif rule == "hips":
            targets[joint] = triad(_hip_line(src_rest, HIP_JOINTS[0])[0], hint,
                                   Gc @ _hip_line(cmu_rest, HIP_JOINTS[1])[0], Gc @ hint)
        else:
            targets[joint] = triad(_rest_direction(src_rest, joint, src_end), hint,
                                   Gc @ _rest_direction(cmu_rest, c, cmu_end), Gc @ hint)
    local = np.broadcast_to(np.eye(3), (T, J, 3, 3)).copy()
    G = np.empty((T, J, 3, 3))
    for j, name in enumerate(template.names):
        p = int(template.parents[j])
        Gp = G[:, p] if p >= 0 else np.broadcast_to(np.eye(3), (T, 3, 3))
        if name in targets:
            local[:, j] = np.swapaxes(Gp, -1, -2) @ targets[name]
        G[:, j] = Gp @ local[:, j]
    scale = _leg_length(cmu_rest, "LeftUpLeg", "LeftLeg", "LeftFoot") / _leg_length(
        src_rest, "lThigh", "lShin", "lFoot")
    middle = _hip_middle(cmu, HIP_JOINTS[1]) / scale
    root = middle - G[:, 0] @ _hip_middle(src_rest, HIP_JOINTS[0])[0]
    euler = matrices_to_euler(local, template.rotation_orders())
    return Motion(names=list(template.names), parents=template.parents.copy(),
                  offsets=template.offsets.copy(), end_sites=template.end_sites.copy(),
                  channels=[list(c) for c in template.channels], euler_deg=euler,
                  root_position=root, fps=cmu_motion.fps, source="")


def dance_fps(path: str | Path) -> float:
    """The true frame rate of a dance file, by its folder (DANCE_FPS); RetargetError if the
    folder is not one of the dances'."""
    kind = Path(path).parent.name
    if kind not in DANCE_FPS:
        raise RetargetError(f"{path}: not in a dance folder ({', '.join(DANCE_FPS)})")
    return DANCE_FPS[kind]


def read_dance(path: str | Path, fps: float | None = 30.0) -> Retargeted:
    """A dance BVH retargeted to the CMU skeleton at ``fps`` (None: the true source rate).
    The file's first frame (the rest T-pose the conversion added, root rotation zero) and the
    SETTLING_FRAMES after it are dropped; the header's frame time is replaced by the folder's
    true rate (dance_fps)."""
    path = Path(path)
    source = read_bvh(path, fps=None, drop_tpose=False)
    if source.n_frames > 1 and np.all(source.euler_deg[0, 0] == 0.0):
        first = min(1 + SETTLING_FRAMES, source.n_frames - 1)
        source.euler_deg = source.euler_deg[first:]
        source.root_position = source.root_position[first:]
    source.fps = dance_fps(path)
    out = retarget(source)
    if fps is not None:
        ratio = source.fps / fps
        out.motion = resample(out.motion, fps)
        step = round(ratio)
        if abs(ratio - step) < 1e-9:
            out.residual_mm = out.residual_mm[::step]
    return out


def dance_files(root: str | Path) -> list[Path]:
    """The dance BVH files under root (salsa/, indian/, martial/; not standard.bvh), sorted."""
    root = Path(root)
    if not root.is_dir():
        raise RetargetError(f"dances folder not found: {root}")
    return sorted(p for kind in DANCE_FPS for p in (root / kind).glob("*.bvh"))


def dance_name(path: str | Path) -> str:
    """A trial name for a dance file: 'xd_salsa_01' for salsa/01.bvh."""
    path = Path(path)
    return f"xd_{path.parent.name}_{path.stem}"
