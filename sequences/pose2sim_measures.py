"""Estimated poses of Pose2Sim's trials judged against their 3-D reference.

Per view: knee and elbow flexion and the 8 limb angles (sequences.measures.LIMB_ANGLE_NAMES)
against the reference's (beside a constant at the reference's own mean), and the heading
against the reference heading relative to that camera; the same for MediaPipe's landmarks
(peer_view_measures). Across views: the same body is seen by four cameras at known azimuths, so
at each instant the estimated headings of views i and j must differ by az_j - az_i, and the 53
body angles must agree.

Poses are (T, 55) pose vectors (sequences.pose_vector), one per video frame listed in
``frames`` (T,) int; angles in degrees.
"""
from __future__ import annotations

from itertools import combinations

import numpy as np

from .keypoint_fit import BodyFit, fit_body, pose_in_view
from . import mediapipe_peer
from .measures import (BODY_ANGLES, LIMB_ANGLE_NAMES, angle_measures, body_angle_error,
                       constant_error, constant_offset_free_error, flexion_deg,
                       flexion_measures, limb_angles_deg, offset_free_error, skill,
                       top_angle_correlation)
from .pose2sim import (Trial, camera_azimuth_deg, project_reference, reference_flexion,
                       reference_heading_deg, reference_limb_angles, video_frames)
from regressor.angles import wrap_deg

from .pose_vector import heading_deg

WITHIN_DEG = 45.0                 # a heading error this large is a wrong view, not noise
RANDOM_HEADING_RMS_DEG = 180.0 / np.sqrt(3.0)   # RMS of a uniformly random heading error


def _rms(x) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def subject_rows(frames, bbox_px, hips_px) -> np.ndarray:
    """Which tracker outputs are the subject. frames (n,) int: video frame of each output (one
    per person and frame); bbox_px (n, 4): (x, y, w, h) pixels; hips_px (n, 2): the reference's
    projected mid-hip at that frame. Returns row indices (m,), at most one per frame, in frame
    order: among the rows whose box holds the mid-hip, the one whose box centre is nearest it;
    frames where no box holds it are left out."""
    frames = np.asarray(frames, dtype=np.int64)
    x, y, w, h = np.asarray(bbox_px, dtype=np.float64).T
    hx, hy = np.asarray(hips_px, dtype=np.float64).T
    inside = (hx >= x) & (hx <= x + w) & (hy >= y) & (hy <= y + h)
    dist = np.hypot(x + w / 2 - hx, y + h / 2 - hy)
    order = np.lexsort((dist, ~inside, frames))
    _, first = np.unique(frames[order], return_index=True)
    best = order[first]
    return best[inside[best]]


def heading_measures(estimate_deg, reference_deg) -> dict:
    """Heading estimate (T,) against reference (T,), degrees: "rms_deg", "median_abs_deg",
    "within_45" (fraction of frames with |error| <= 45)."""
    err = np.abs(wrap_deg(np.asarray(estimate_deg, float) - np.asarray(reference_deg, float)))
    return {"rms_deg": _rms(err), "median_abs_deg": float(np.median(err)),
            "within_45": float((err <= WITHIN_DEG).mean())}


def reference_body(trial: Trial, progress=None) -> BodyFit:
    """The project's body fitted to the reference keypoints of every video frame with a
    reference (sequences.keypoint_fit.fit_body; ~0.3 s a frame; progress(t, T))."""
    frames = video_frames(trial)
    return fit_body(trial.points(frames), trial.reference.names, progress=progress)


def reference_poses(trial: Trial, view: str, fit: BodyFit, frames) -> np.ndarray:
    """The fitted reference body's pose vectors (T, 55) at video frames (T,), heading relative
    to a view's camera (fit: reference_body(trial))."""
    frames = np.asarray(frames, dtype=np.int64)
    rows = np.searchsorted(video_frames(trial), frames)
    return pose_in_view(fit.pose[rows], camera_azimuth_deg(trial, view, frames))


def body_measures(poses, reference, constant_pose) -> dict:
    """The 53 body angles of estimated poses (T >= 2, 55) against the fitted reference body's
    (T, 55): "error_deg", "constant_error_deg" (constant_pose (55,) held still), "skill",
    "offset_free_error_deg" and "constant_offset_free_error_deg" (the same with each angle's
    constant offset forgiven: sequences.measures.offset_free_error), "top_angles"
    (sequences.measures.top_angle_correlation). Angles the keypoints do not fix (limb twists,
    hands, collar bones) are ~0 in the reference: read the correlation of the most-moving
    angles (which the keypoints fix) before the error."""
    error = body_angle_error(poses, reference)
    baseline = constant_error(reference, constant_pose)
    return {"error_deg": error, "constant_error_deg": baseline, "skill": skill(error, baseline),
            "offset_free_error_deg": offset_free_error(poses, reference),
            "constant_offset_free_error_deg": constant_offset_free_error(reference,
                                                                         constant_pose),
            "top_angles": top_angle_correlation(poses, reference)}


def view_measures(trial: Trial, view: str, frames, poses, constant_pose=None,
                  fit: BodyFit | None = None) -> dict:
    """One view's estimated poses (T >= 2, 55) at video frames (T,) against the reference:
    {"frames", "flexion": sequences.measures.flexion_measures (its "truth_mean_error" is the
    constant reference-mean flexion's error; with constant_pose (55,), e.g. the model's
    training-mean pose, also that pose's "constant_error"), "limbs": the same for the 8 limb
    angles (sequences.measures.angle_measures), "heading": heading_measures}; with
    fit (reference_body) and constant_pose also "body": body_measures."""
    frames = np.asarray(frames, dtype=np.int64)
    constant = None if constant_pose is None else flexion_deg(
        np.asarray(constant_pose, dtype=np.float64)[None])[0]
    limbs = None if constant_pose is None else limb_angles_deg(
        np.asarray(constant_pose, dtype=np.float64)[None])[0]
    out = {"frames": int(len(frames)),
           "flexion": flexion_measures(flexion_deg(poses), reference_flexion(trial, frames),
                                       constant),
           "limbs": angle_measures(limb_angles_deg(poses), reference_limb_angles(trial, frames),
                                   LIMB_ANGLE_NAMES, limbs),
           "heading": heading_measures(heading_deg(poses),
                                       reference_heading_deg(trial, view, frames))}
    if fit is not None and constant_pose is not None:
        out["body"] = body_measures(poses, reference_poses(trial, view, fit, frames),
                                    constant_pose)
    return out


def cross_view_measures(trial: Trial, frames, poses_by_view: dict[str, np.ndarray]) -> dict:
    """Consistency of the views' estimates at the same video frames (T,): poses_by_view maps
    each view to (T, 55). For every pair of views (i, j) and frame, the heading difference
    error wrap((h_i - h_j) - (az_j - az_i)) and the mean over the 53 body angles of
    |wrap(a_i - a_j)|. Returns {"frames", "pairs", "heading_rms_deg" (random headings would
    give RANDOM_HEADING_RMS_DEG), "heading_rms_per_pair", "body_angle_disagreement_deg",
    "body_angle_disagreement_per_pair"}. A flat output agrees with itself across views:
    read the disagreement beside the body angles' motion, not alone."""
    frames = np.asarray(frames, dtype=np.int64)
    views = sorted(poses_by_view)
    az = {v: camera_azimuth_deg(trial, v, frames) for v in views}
    head = {v: heading_deg(poses_by_view[v]) for v in views}
    body = {v: np.asarray(poses_by_view[v], float)[:, BODY_ANGLES] for v in views}
    pairs = list(combinations(views, 2))
    h_err = np.array([wrap_deg((head[i] - head[j]) - (az[j] - az[i])) for i, j in pairs])
    b_err = np.array([np.abs(wrap_deg(body[i] - body[j])).mean(axis=1) for i, j in pairs])
    names = [f"{i}-{j}" for i, j in pairs]
    return {"frames": int(len(frames)), "pairs": names,
            "heading_rms_deg": _rms(h_err),
            "heading_rms_per_pair": dict(zip(names, np.sqrt((h_err ** 2).mean(axis=1)).tolist())),
            "random_heading_rms_deg": RANDOM_HEADING_RMS_DEG,
            "body_angle_disagreement_deg": float(b_err.mean()),
            "body_angle_disagreement_per_pair": dict(zip(names, b_err.mean(axis=1).tolist()))}


def reference_cross_view_check(trial: Trial, frames, views) -> float:
    """Cross-view heading RMS (degrees) of the reference headings themselves: 0 up to rounding,
    a check that heading and azimuth conventions agree."""
    frames = np.asarray(frames, dtype=np.int64)
    ref = {v: reference_heading_deg(trial, v, frames) for v in views}
    az = {v: camera_azimuth_deg(trial, v, frames) for v in views}
    return _rms([wrap_deg((ref[i] - ref[j]) - (az[j] - az[i]))
                 for i, j in combinations(sorted(views), 2)])


def pooled_limb_measures(trial: Trial, frames_by_view: dict, angles_by_view: dict,
                         constant=None) -> dict:
    """The 8 limb angles over several views: frames_by_view maps each view to its video frames
    (T_v,), angles_by_view to the estimated limb angles (T_v, 8) degrees; constant (8,) as in
    angle_measures. Returns {"mean": each per-view figure of angle_measures averaged over the
    views, "pooled": angle_measures of all views' frames together}."""
    views = list(frames_by_view)
    truth = {v: reference_limb_angles(trial, frames_by_view[v]) for v in views}
    each = [angle_measures(angles_by_view[v], truth[v], LIMB_ANGLE_NAMES, constant)
            for v in views]
    mean = {key: np.mean([m[key] for m in each], axis=0).tolist() for key in each[0]
            if key != "names"}
    pooled = angle_measures(np.concatenate([angles_by_view[v] for v in views]),
                            np.concatenate([truth[v] for v in views]), LIMB_ANGLE_NAMES,
                            constant)
    return {"mean": {"names": list(LIMB_ANGLE_NAMES), **mean}, "pooled": pooled}


def cross_view_heading_rms(trial: Trial, frames, headings_by_view: dict) -> float:
    """Cross-view heading RMS (degrees) of headings (T,) per view at the same video frames (T,):
    over view pairs (i, j), wrap((h_i - h_j) - (az_j - az_i)), as cross_view_measures."""
    frames = np.asarray(frames, dtype=np.int64)
    az = {v: camera_azimuth_deg(trial, v, frames) for v in headings_by_view}
    return _rms([wrap_deg((headings_by_view[i] - headings_by_view[j]) - (az[j] - az[i]))
                 for i, j in combinations(sorted(headings_by_view), 2)])


def peer_view_measures(trial: Trial, view: str, results: dict, frames=None) -> dict:
    """MediaPipe's results in one view (sequences.mediapipe_peer.read_results) against the
    reference: its subject's frames (among ``frames`` (T,), default all with a reference) with
    "frames", "limbs" (angle_measures), "heading" (heading_measures), and "series": (frames
    (T',), limb angles (T', 8), headings (T',)) for pooling, popped before writing JSON."""
    wanted = video_frames(trial) if frames is None else np.asarray(frames, dtype=np.int64)
    rows = np.flatnonzero(np.isin(results["frames"], wanted))
    at = results["frames"][rows]
    boxes = mediapipe_peer.keypoint_boxes(project_reference(view, at, trial))
    keep = mediapipe_peer.subject_frames(results["image"][rows], boxes)
    rows, at = rows[keep], at[keep]
    world = results["world"][rows]
    angles, heading = mediapipe_peer.limb_angles(world), mediapipe_peer.heading_deg(world)
    return {"frames": int(len(at)),
            "limbs": angle_measures(angles, reference_limb_angles(trial, at), LIMB_ANGLE_NAMES),
            "heading": heading_measures(heading, reference_heading_deg(trial, view, at)),
            "series": (at, angles, heading)}
