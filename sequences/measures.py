"""Honest measures of pose sequences (DESIGN.md, "Error and jitter measures").

A small mean angular error can hide a flat output: many angles barely move. So every error here
stands beside what a constant achieves, and the limbs are judged by what a viewer sees move:

- body angle error (the 53 joint angles, the heading left out) beside a **constant** pose's
  (e.g. the training mean), and the **skill** 1 - error / constant error;
- the same error with each angle's constant offset forgiven (**offset-free**), beside the
  constant's: how well the output follows the motion, whatever each subject's own offsets;
- the **correlation** with the truth of the m most-moving angles;
- knee and elbow **flexion** (forward kinematics) error and correlation, beside the error of a
  constant flexion, and the same for the 8 **limb angles** (flexion, and hip and shoulder as
  the thigh and upper arm against the trunk) from any 3-D joints;
- **MPJPE** and **PA-MPJPE** in millimetres on the CMU skeleton.

Pose vectors are (T, 55) as in sequences.pose_vector (degrees, heading as (cos, sin)); angles are
degrees; lengths are millimetres unless a name says otherwise. A correlation involving a series
that does not move (zero variance) is 0: a constant output carries no information about motion.
"""
from __future__ import annotations

import numpy as np

from regressor.angles import POSE_DIM, wrap_deg

from .pose_vector import heading_deg, joint_positions, pose_vector_names
from .skeleton import CMU_UNIT_M, POSE_JOINTS

#: Columns of the pose vector holding the 53 body (joint) angles: all but the heading pair.
BODY_ANGLES = slice(2, POSE_DIM)
#: Order of the four flexion angles.
FLEXION_NAMES: tuple[str, ...] = ("L knee", "R knee", "L elbow", "R elbow")
#: (proximal, middle, distal) pose joints of each flexion angle: hip-knee-ankle,
#: shoulder-elbow-wrist. Flexion is the angle between the bones middle - proximal and
#: distal - middle: 0 for a straight limb.
FLEXION_JOINTS: tuple[tuple[str, str, str], ...] = (
    ("LeftUpLeg", "LeftLeg", "LeftFoot"), ("RightUpLeg", "RightLeg", "RightFoot"),
    ("LeftArm", "LeftForeArm", "LeftHand"), ("RightArm", "RightForeArm", "RightHand"),
)
#: The 8 limb angles: knee and elbow flexion (FLEXION_NAMES, first), then hip (the thigh against
#: the trunk) and shoulder (the upper arm against the trunk); limb_angles_from_points.
LIMB_ANGLE_NAMES: tuple[str, ...] = FLEXION_NAMES + ("L hip", "R hip", "L shoulder",
                                                     "R shoulder")
#: The 3-D points the limb angles are computed from, in this order (Pose2Sim's names).
LIMB_POINTS: tuple[str, ...] = ("LHip", "RHip", "LKnee", "RKnee", "LAnkle", "RAnkle",
                                "LShoulder", "RShoulder", "LElbow", "RElbow", "LWrist", "RWrist")
#: The pose joint (skeleton.POSE_JOINTS) at each of LIMB_POINTS.
LIMB_POSE_JOINTS: dict[str, str] = {
    "LHip": "LeftUpLeg", "RHip": "RightUpLeg", "LKnee": "LeftLeg", "RKnee": "RightLeg",
    "LAnkle": "LeftFoot", "RAnkle": "RightFoot", "LShoulder": "LeftArm",
    "RShoulder": "RightArm", "LElbow": "LeftForeArm", "RElbow": "RightForeArm",
    "LWrist": "LeftHand", "RWrist": "RightHand"}
_LIMB_FLEXION = (("LHip", "LKnee", "LAnkle"), ("RHip", "RKnee", "RAnkle"),
                 ("LShoulder", "LElbow", "LWrist"), ("RShoulder", "RElbow", "RWrist"))
#: Joints of MPJPE: the pose joints at distinct places on the CMU skeleton (Neck and both
#: Shoulders sit at Spine1 and are left out). The root is kept, as in the field's 17-joint
#: Human3.6M set; root-aligned, its error is 0.
MPJPE_JOINTS: tuple[str, ...] = (
    "Hips", "Spine1", "Head", "LeftArm", "LeftForeArm", "LeftHand",
    "RightArm", "RightForeArm", "RightHand", "LeftUpLeg", "LeftLeg", "LeftFoot",
    "RightUpLeg", "RightLeg", "RightFoot",
)
MM_PER_CMU_UNIT = CMU_UNIT_M * 1000.0
DEFAULT_TOP_ANGLES = 8


class MeasureError(ValueError):
    """Arrays given to a measure have the wrong shape or non-finite values."""


def _as_poses(vectors, name: str, frames: int | None = None) -> np.ndarray:
    v = np.asarray(vectors, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != POSE_DIM:
        raise MeasureError(f"{name}: pose vectors must have shape (T, {POSE_DIM}), got {v.shape}")
    if frames is not None and len(v) != frames:
        raise MeasureError(f"{name}: {len(v)} frames, expected {frames} (as the truth)")
    if not np.isfinite(v).all():
        raise MeasureError(f"{name}: NaN or infinity in the pose vectors")
    return v


def _pair(estimate, truth, min_frames: int = 1) -> tuple[np.ndarray, np.ndarray]:
    truth = _as_poses(truth, "truth")
    if len(truth) < min_frames:
        raise MeasureError(f"truth: needs at least {min_frames} frames, got {len(truth)}")
    return _as_poses(estimate, "estimate", len(truth)), truth


def _constant(constant_pose, frames: int) -> np.ndarray:
    c = np.asarray(constant_pose, dtype=np.float64)
    if c.shape != (POSE_DIM,):
        raise MeasureError(f"constant pose must have shape ({POSE_DIM},), got {c.shape}")
    return _as_poses(np.tile(c, (frames, 1)), "constant pose")


# ---------------------------------------------------------------- angles, constant, skill

def body_angle_error(estimate, truth) -> float:
    """Mean over frames and the 53 body angles of |wrap(estimate - truth)|, degrees.

    estimate, truth: (T, 55) pose vectors. The heading is not included (see heading_errors)."""
    est, tru = _pair(estimate, truth)
    return float(np.abs(wrap_deg(est[:, BODY_ANGLES] - tru[:, BODY_ANGLES])).mean())


def constant_error(truth, constant_pose) -> float:
    """body_angle_error of a constant pose (55,) (e.g. the training mean) held for every frame of
    truth (T, 55); degrees."""
    tru = _as_poses(truth, "truth")
    return body_angle_error(_constant(constant_pose, len(tru)), tru)


def offset_free_error(estimate, truth) -> float:
    """body_angle_error with each angle's constant offset forgiven: the mean over frames and the
    53 body angles of |d - circular mean of d over the frames|, d = wrap(estimate - truth),
    degrees. What is left is how well the output follows the motion: an output that is the
    truth plus a fixed offset per angle (a subject's own way of holding a wrist, which no
    silhouette shows) scores 0, a constant output the truth's own mean absolute deviation about
    its circular mean (not 0: compare with that, as pose_measures does).

    estimate, truth: (T, 55) pose vectors."""
    est, tru = _pair(estimate, truth)
    d = wrap_deg(est[:, BODY_ANGLES] - tru[:, BODY_ANGLES])
    return float(np.abs(wrap_deg(d - circular_mean_deg(d))).mean())


def constant_offset_free_error(truth, constant_pose) -> float:
    """offset_free_error of a constant pose (55,) held for every frame of truth (T, 55): the
    truth's own mean absolute deviation about its circular mean, degrees (what a still output
    scores there)."""
    tru = _as_poses(truth, "truth")
    return offset_free_error(_constant(constant_pose, len(tru)), tru)


def skill(error: float, baseline_error: float) -> float:
    """1 - error / baseline_error: 1 is perfect, 0 no better than the constant, < 0 worse."""
    if not baseline_error > 0:
        raise MeasureError(f"skill: the baseline error must be > 0, got {baseline_error}")
    return float(1.0 - error / baseline_error)


def heading_errors(estimate, truth) -> np.ndarray:
    """Heading error (T,) degrees in (-180, 180] of pose vectors estimate, truth (T, 55)."""
    est, tru = _pair(estimate, truth)
    return wrap_deg(heading_deg(est) - heading_deg(tru))


# ---------------------------------------------------------------- correlation

def circular_mean_deg(angles) -> np.ndarray:
    """Circular mean (A,) degrees of angles (T, A) degrees, per column."""
    a = np.radians(np.asarray(angles, dtype=np.float64))
    return np.degrees(np.arctan2(np.sin(a).mean(axis=0), np.cos(a).mean(axis=0)))


def unwrap_about_mean(angles) -> np.ndarray:
    """Angles (T, A) degrees moved by multiples of 360 to lie within 180 of their column's
    circular mean, so a motion across +-180 is continuous (T, A)."""
    a = np.asarray(angles, dtype=np.float64)
    mean = circular_mean_deg(a)
    return mean + wrap_deg(a - mean)


def correlation(a, b) -> np.ndarray:
    """Pearson correlation (A,) of the columns of a and b (T, A); 0 where a column of either
    does not vary."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 2 or len(a) < 2:
        raise MeasureError(f"correlation: needs two equal (T >= 2, A) arrays, got {a.shape} "
                           f"and {b.shape}")
    da, db = a - a.mean(axis=0), b - b.mean(axis=0)
    sa, sb = np.sqrt((da ** 2).mean(axis=0)), np.sqrt((db ** 2).mean(axis=0))
    # A spread at rounding level (relative to the values) is no motion.
    moving = (sa > 1e-9 * (np.abs(a).max(axis=0) + 1.0)) & \
        (sb > 1e-9 * (np.abs(b).max(axis=0) + 1.0))
    out = np.zeros(a.shape[1])
    out[moving] = (da * db).mean(axis=0)[moving] / (sa * sb)[moving]
    return out


def most_moving_angles(truth, m: int = DEFAULT_TOP_ANGLES) -> np.ndarray:
    """Columns (m,) int of the pose vector (within 2..54) of the m body angles of truth (T, 55)
    with the largest std over the sequence (unwrapped about their circular mean), largest
    first. The heading is excluded."""
    tru = _as_poses(truth, "truth")
    if not 1 <= m <= tru.shape[1] - 2:
        raise MeasureError(f"m must be in 1..{tru.shape[1] - 2}, got {m}")
    std = unwrap_about_mean(tru[:, BODY_ANGLES]).std(axis=0)
    return BODY_ANGLES.start + np.argsort(-std, kind="stable")[:m]


def top_angle_correlation(estimate, truth, m: int = DEFAULT_TOP_ANGLES) -> dict:
    """Correlation with the truth of the m most-moving body angles (most_moving_angles).

    estimate, truth: (T >= 2, 55). Each series is unwrapped about its own circular mean.
    Returns {"angles": m names, "truth_std_deg": (m,), "per_angle": (m,), "mean": float}
    (lists, JSON-ready)."""
    est, tru = _pair(estimate, truth, min_frames=2)
    cols = most_moving_angles(tru, m)
    a, b = unwrap_about_mean(est[:, cols]), unwrap_about_mean(tru[:, cols])
    r = correlation(a, b)
    names = pose_vector_names()
    return {"angles": [names[c] for c in cols], "truth_std_deg": b.std(axis=0).tolist(),
            "per_angle": r.tolist(), "mean": float(r.mean())}


# ---------------------------------------------------------------- flexion

def flexion_from_points(proximal, middle, distal) -> np.ndarray:
    """Flexion (...,) degrees in [0, 180] at ``middle``: the angle between the bones
    middle - proximal and distal - middle (0 = straight). Points (..., 3), any length unit."""
    p, m, d = (np.asarray(x, dtype=np.float64) for x in (proximal, middle, distal))
    u, w = m - p, d - m
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(u, w), axis=-1),
                                 (u * w).sum(axis=-1)))


def flexion_from_joints(joints) -> np.ndarray:
    """Knee and elbow flexion (T, 4) degrees (FLEXION_NAMES order) from pose-joint positions
    (T, 18, 3) in POSE_JOINTS order (as pose_vector.joint_positions returns)."""
    j = np.asarray(joints, dtype=np.float64)
    if j.ndim != 3 or j.shape[1:] != (len(POSE_JOINTS), 3):
        raise MeasureError(f"joints must have shape (T, {len(POSE_JOINTS)}, 3), got {j.shape}")
    idx = np.array([[POSE_JOINTS.index(n) for n in trio] for trio in FLEXION_JOINTS])  # (4, 3)
    return flexion_from_points(j[:, idx[:, 0]], j[:, idx[:, 1]], j[:, idx[:, 2]])


def flexion_deg(vectors, template=None) -> np.ndarray:
    """Knee and elbow flexion (T, 4) degrees (L knee, R knee, L elbow, R elbow; 0 = straight)
    of pose vectors (T, 55), by forward kinematics on the CMU skeleton (template as in
    pose_vector.joint_positions; None = skeleton.CMU_REST_OFFSETS)."""
    v = _as_poses(vectors, "pose vectors")
    return flexion_from_joints(joint_positions(v, template))


def _as_angles(angles, name: str, names, frames: int | None = None) -> np.ndarray:
    f = np.asarray(angles, dtype=np.float64)
    if f.ndim != 2 or f.shape[1] != len(names) or (frames is not None and len(f) != frames):
        want = f"({frames if frames is not None else 'T'}, {len(names)})"
        raise MeasureError(f"{name}: angles must have shape {want}, got {f.shape}")
    if not np.isfinite(f).all():
        raise MeasureError(f"{name}: NaN or infinity in the angles")
    return f


def angle_measures(estimate, truth, names, constant=None) -> dict:
    """Angle series estimate (T >= 2, A) against truth (T, A), degrees, columns named by names
    (A,) (e.g. FLEXION_NAMES, LIMB_ANGLE_NAMES).

    Returns (JSON-ready): "names"; "error_per_angle" (A,) mean |difference| over frames and
    "error" their mean; "corr_per_angle" (A,) and "corr" their mean; "truth_mean_error" (A,) and
    "truth_mean_error_mean": the error of a constant at the truth's own mean; with constant
    (A,) (e.g. the training-mean pose's angles), "constant_error" (A,) and
    "constant_error_mean" likewise; "frames"."""
    tru = _as_angles(truth, "truth", names)
    est = _as_angles(estimate, "estimate", names, len(tru))
    err = np.abs(est - tru).mean(axis=0)
    r = correlation(est, tru)
    own = np.abs(tru - tru.mean(axis=0)).mean(axis=0)
    out = {"names": list(names), "frames": int(len(tru)), "error_per_angle": err.tolist(),
           "error": float(err.mean()), "corr_per_angle": r.tolist(), "corr": float(r.mean()),
           "truth_mean_error": own.tolist(), "truth_mean_error_mean": float(own.mean())}
    if constant is not None:
        c = _as_angles(np.reshape(constant, (1, -1)), "constant", names)[0]
        const = np.abs(tru - c).mean(axis=0)
        out.update(constant_error=const.tolist(), constant_error_mean=float(const.mean()))
    return out


def flexion_measures(estimate_flexion, truth_flexion, constant_flexion=None) -> dict:
    """angle_measures of knee and elbow flexion (T >= 2, 4) in FLEXION_NAMES order (with
    constant_flexion (4,), e.g. the training-mean pose's, its "constant_error")."""
    return angle_measures(estimate_flexion, truth_flexion, FLEXION_NAMES, constant_flexion)


# ---------------------------------------------------------------- the 8 limb angles

def limb_angles_from_points(points) -> np.ndarray:
    """The 8 limb angles (..., 8) degrees in LIMB_ANGLE_NAMES order from 3-D points (..., 12, 3)
    in LIMB_POINTS order (any length unit, any axes). Knee and elbow: flexion (0 = straight).
    Hip: the thigh (hip -> knee) against the trunk's downward line (mid-shoulder -> mid-hip);
    shoulder: the upper arm (shoulder -> elbow) against the same line; 0 = along the trunk
    (standing, arm hanging), 90 = thigh or arm out at a right angle (in any direction:
    flexion, abduction or both)."""
    p = np.asarray(points, dtype=np.float64)
    if p.shape[-2:] != (len(LIMB_POINTS), 3):
        raise MeasureError(f"limb points must have shape (..., {len(LIMB_POINTS)}, 3), got "
                           f"{p.shape}")
    at = {name: p[..., i, :] for i, name in enumerate(LIMB_POINTS)}
    down = ((at["LHip"] + at["RHip"]) - (at["LShoulder"] + at["RShoulder"])) / 2
    out = [flexion_from_points(at[a], at[b], at[c]) for a, b, c in _LIMB_FLEXION]
    for root, end in (("LHip", "LKnee"), ("RHip", "RKnee"),
                      ("LShoulder", "LElbow"), ("RShoulder", "RElbow")):
        # The angle between two directions: flexion of (root - down, root, end).
        out.append(flexion_from_points(at[root] - down, at[root], at[end]))
    return np.stack(out, axis=-1)


def limb_angles_deg(vectors, template=None) -> np.ndarray:
    """The 8 limb angles (T, 8) degrees (LIMB_ANGLE_NAMES) of pose vectors (T, 55), by forward
    kinematics on the CMU skeleton (template as in pose_vector.joint_positions)."""
    v = _as_poses(vectors, "pose vectors")
    joints = joint_positions(v, template)
    return limb_angles_from_points(joints[:, [POSE_JOINTS.index(LIMB_POSE_JOINTS[n])
                                              for n in LIMB_POINTS]])


# ---------------------------------------------------------------- MPJPE

def joints_mm(vectors, template=None) -> np.ndarray:
    """MPJPE_JOINTS positions (T, 15, 3) millimetres, root at the origin, of pose vectors
    (T, 55) by forward kinematics on the CMU skeleton (template as in joint_positions). The
    frame is the camera's (heading 0 faces it; Y up)."""
    v = _as_poses(vectors, "pose vectors")
    idx = [POSE_JOINTS.index(n) for n in MPJPE_JOINTS]
    return joint_positions(v, template)[:, idx] * MM_PER_CMU_UNIT


def _as_joint_pair(estimate, truth) -> tuple[np.ndarray, np.ndarray]:
    e, t = np.asarray(estimate, dtype=np.float64), np.asarray(truth, dtype=np.float64)
    if e.shape != t.shape or e.ndim != 3 or e.shape[2] != 3:
        raise MeasureError(f"joints: estimate {e.shape} and truth {t.shape} must be equal "
                           f"(T, J, 3) arrays")
    if not (np.isfinite(e).all() and np.isfinite(t).all()):
        raise MeasureError("joints: NaN or infinity in the positions")
    return e, t


def mpjpe(estimate_joints, truth_joints) -> float:
    """Mean over frames and joints of the Euclidean distance between estimate and truth joints
    (T, J, 3), in their unit (millimetres from joints_mm)."""
    e, t = _as_joint_pair(estimate_joints, truth_joints)
    return float(np.linalg.norm(e - t, axis=2).mean())


def procrustes_align(estimate_joints, truth_joints) -> np.ndarray:
    """estimate_joints (T, J, 3) moved per frame by the similarity (rotation, uniform scale,
    translation; no reflection) that best fits truth_joints (T, J, 3) in least squares
    (Umeyama 1991). Returns (T, J, 3)."""
    e, t = _as_joint_pair(estimate_joints, truth_joints)
    mu_e, mu_t = e.mean(axis=1, keepdims=True), t.mean(axis=1, keepdims=True)
    X, Y = e - mu_e, t - mu_t
    U, S, Vt = np.linalg.svd(np.einsum("tji,tjk->tik", X, Y))      # H = X^T Y (T, 3, 3)
    d = np.sign(np.linalg.det(np.einsum("tij,tjk->tik", U, Vt)))    # -1: would reflect
    d[d == 0] = 1.0
    D = np.ones((len(e), 3))
    D[:, 2] = d
    R = np.einsum("tji,tj,tkj->tik", Vt, D, U)                      # V D U^T (T, 3, 3)
    sq = (X ** 2).sum(axis=(1, 2))
    scale = np.where(sq > 0, (S * D).sum(axis=1) / np.where(sq > 0, sq, 1.0), 1.0)
    return scale[:, None, None] * np.einsum("tik,tjk->tji", R, X) + mu_t


def pa_mpjpe(estimate_joints, truth_joints) -> float:
    """MPJPE after per-frame similarity Procrustes alignment of the estimate to the truth;
    joints (T, J, 3), in their unit (millimetres from joints_mm)."""
    return mpjpe(procrustes_align(estimate_joints, truth_joints), truth_joints)


# ---------------------------------------------------------------- everything for reports

def _with_heading_of(poses: np.ndarray, truth: np.ndarray) -> np.ndarray:
    out = poses.copy()
    out[:, :2] = truth[:, :2] / np.hypot(truth[:, :1], truth[:, 1:2]).clip(1e-12)
    return out


def pose_measures(estimate, truth, constant_pose, m: int = DEFAULT_TOP_ANGLES,
                  template=None) -> dict:
    """Every measure of estimated pose vectors (T >= 2, 55) against truth (T, 55), beside a
    constant pose (55,) (e.g. the training mean). JSON-ready dict; degrees and millimetres:

    - "error_deg" (53 body angles), "constant_error_deg", "skill";
    - "offset_free_error_deg", "constant_offset_free_error_deg": the same with each angle's
      constant offset forgiven (offset_free_error), for the estimate and the constant pose;
    - "heading_rms_deg", "heading_within_45" (fraction of frames);
    - "top_angles": top_angle_correlation with m angles;
    - "flexion": flexion_measures, with the constant pose's flexion as "constant_error";
    - "mpjpe_mm", "pa_mpjpe_mm"; "constant_mpjpe_mm", "constant_pa_mpjpe_mm": the constant body
      pose turned to the true heading (its heading is not an estimate);
    - "frames".
    template: skeleton for forward kinematics (as pose_vector.joint_positions)."""
    est, tru = _pair(estimate, truth, min_frames=2)
    const = _with_heading_of(_constant(constant_pose, len(tru)), tru)
    error, baseline = body_angle_error(est, tru), body_angle_error(const, tru)
    heading = np.abs(heading_errors(est, tru))
    flex_t = flexion_deg(tru, template)
    j_est, j_tru, j_const = (joints_mm(p, template) for p in (est, tru, const))
    return {
        "frames": int(len(tru)),
        "error_deg": error, "constant_error_deg": baseline, "skill": skill(error, baseline),
        "offset_free_error_deg": offset_free_error(est, tru),
        "constant_offset_free_error_deg": offset_free_error(const, tru),
        "heading_rms_deg": float(np.sqrt((heading ** 2).mean())),
        "heading_within_45": float((heading <= 45.0).mean()),
        "top_angles": top_angle_correlation(est, tru, m),
        "flexion": flexion_measures(flexion_deg(est, template), flex_t,
                                    flexion_deg(const[:1], template)[0]),
        "mpjpe_mm": mpjpe(j_est, j_tru), "pa_mpjpe_mm": pa_mpjpe(j_est, j_tru),
        "constant_mpjpe_mm": mpjpe(j_const, j_tru),
        "constant_pa_mpjpe_mm": pa_mpjpe(j_const, j_tru),
    }


def novelty_summary(novelty) -> dict:
    """Per-frame novelty (n,) (regressor.estimator.PoseEstimates.novelty: distance to the
    training silhouettes over their own 99th percentile; NaN where unknown) summarised:
    {"median", "share_above_1"} (share of known frames above 1, where the regressor
    extrapolates); both None when no frame is known."""
    known = np.asarray(novelty, dtype=float).reshape(-1)
    known = known[np.isfinite(known)]
    if not len(known):
        return {"median": None, "share_above_1": None}
    return {"median": float(np.median(known)), "share_above_1": float((known > 1.0).mean())}
