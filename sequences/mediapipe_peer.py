"""MediaPipe Pose as a peer on the Pose2Sim trials: run it on a view's video, read its results,
and turn its 3-D world landmarks into the measures' limb angles and heading.

MediaPipe is an optional extra (``pip install -e '.[peers]'``: mediapipe 0.10.14, whose legacy
``mp.solutions.pose`` with model_complexity=1 runs offline); nothing here imports it unless asked
to run it. Its results per view are (T, 33, 3) arrays, NaN where it found nobody:

- ``world``: pose_world_landmarks, metres, hip-centred, axes those of the camera (x right,
  y down, z away from the camera);
- ``image``: pose_landmarks in pixels (x, y) and MediaPipe's relative depth.

Picking the subject (another person is composited into the swings videos): MediaPipe follows one
person from frame to frame; when it starts, or when the person it follows has no mid-hip inside
the box of the reference's keypoints projected into the view (the same reference point that
picks our tracker's subject), it starts again on that frame with everything outside the box,
enlarged by BOX_MARGIN, painted grey. Frames where it still follows someone else are left out
when scoring (subject_frames).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .measures import LIMB_POINTS, limb_angles_from_points

#: MediaPipe's landmark index of each of measures.LIMB_POINTS.
MEDIAPIPE_INDEX: dict[str, int] = {
    "LShoulder": 11, "RShoulder": 12, "LElbow": 13, "RElbow": 14, "LWrist": 15, "RWrist": 16,
    "LHip": 23, "RHip": 24, "LKnee": 25, "RKnee": 26, "LAnkle": 27, "RAnkle": 28}
LANDMARKS = 33
BOX_MARGIN = 0.2                # the box of the reference keypoints, enlarged by this share
MODEL_COMPLEXITY = 1            # complexity 0 and 2 download their models at run time


class PeerError(ValueError):
    """MediaPipe is missing, or its results are missing or malformed."""


def _as_landmarks(world, name: str = "landmarks") -> np.ndarray:
    w = np.asarray(world, dtype=np.float64)
    if w.ndim != 3 or w.shape[1:] != (LANDMARKS, 3):
        raise PeerError(f"{name}: MediaPipe landmarks must have shape (T, {LANDMARKS}, 3), got "
                        f"{w.shape}")
    return w


def limb_angles(world) -> np.ndarray:
    """The 8 limb angles (T, 8) degrees (measures.LIMB_ANGLE_NAMES) of world landmarks
    (T, 33, 3); NaN rows where MediaPipe found nobody."""
    w = _as_landmarks(world)
    return limb_angles_from_points(w[:, [MEDIAPIPE_INDEX[n] for n in LIMB_POINTS]])


def heading_deg(world) -> np.ndarray:
    """Body heading (T,) degrees relative to the camera, in the project's convention (0 faces
    the camera, positive turns counter-clockwise seen from above), from world landmarks
    (T, 33, 3): the pelvis' facing (left hip - right hip) x up, as the reference's heading.
    The camera's axes are taken as level (its pitch and roll are ignored)."""
    w = _as_landmarks(world) * np.array([1.0, -1.0, -1.0])     # y up, camera towards +z
    across = w[:, MEDIAPIPE_INDEX["LHip"]] - w[:, MEDIAPIPE_INDEX["RHip"]]
    facing = np.cross(across, [0.0, 1.0, 0.0])
    return np.degrees(np.arctan2(facing[:, 0], facing[:, 2]))


def subject_frames(image, boxes) -> np.ndarray:
    """Which frames' landmarks are the subject's: image (T, 33, >=2) pixel landmarks, boxes
    (T, 4) (x0, y0, x1, y1) pixels of the reference keypoints in the view. Returns (T,) bool:
    MediaPipe found someone whose mid-hip lies inside the box."""
    im = np.asarray(image, dtype=np.float64)
    hip = im[:, [MEDIAPIPE_INDEX["LHip"], MEDIAPIPE_INDEX["RHip"]], :2].mean(axis=1)
    b = np.asarray(boxes, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        return ((hip[:, 0] >= b[:, 0]) & (hip[:, 0] <= b[:, 2]) & (hip[:, 1] >= b[:, 1])
                & (hip[:, 1] <= b[:, 3]))


def keypoint_boxes(keypoints_px) -> np.ndarray:
    """Boxes (T, 4) (x0, y0, x1, y1) pixels round keypoints (T, K, 2), enlarged by BOX_MARGIN
    of their size on every side."""
    k = np.asarray(keypoints_px, dtype=np.float64)
    lo, hi = k.min(axis=1), k.max(axis=1)
    pad = (hi - lo) * BOX_MARGIN
    return np.concatenate([lo - pad, hi + pad], axis=1)


def read_results(path: str | Path) -> dict:
    """A view's results as run_view wrote them (.npz of plain arrays): {"world", "image"}
    (T, 33, 3) and "frames" (T,) int video frame indices. PeerError naming the file if it is
    missing or malformed."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            out = {k: np.asarray(data[k]) for k in ("world", "image", "frames")}
    except (OSError, KeyError, ValueError) as exc:
        raise PeerError(f"{path}: cannot read MediaPipe results ({exc})") from exc
    for key in ("world", "image"):
        _as_landmarks(out[key], f"{path} {key}")
    if len(out["frames"]) != len(out["world"]):
        raise PeerError(f"{path}: {len(out['frames'])} frames for {len(out['world'])} rows")
    return out


def write_results(path: str | Path, results: dict) -> None:
    """Write run_view's results as an .npz of plain arrays (no pickle)."""
    np.savez(path, **{k: np.asarray(results[k]) for k in ("world", "image", "frames")})


def _grey_outside(frame: np.ndarray, box) -> np.ndarray:
    x0, y0, x1, y1 = (int(round(v)) for v in box)
    out = np.full_like(frame, 127)
    h, w = frame.shape[:2]
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    out[y0:y1, x0:x1] = frame[y0:y1, x0:x1]
    return out


def run_view(video: str | Path, boxes) -> dict:
    """Run MediaPipe Pose (model complexity 1, tracking mode) on a video, following the subject:
    boxes (T, 4) (x0, y0, x1, y1) pixels per video frame (keypoint_boxes of the reference);
    see the module's docstring. Returns {"world", "image"} (T, 33, 3), NaN where nobody was
    followed, and "frames" (T,). PeerError if mediapipe is not installed."""
    import cv2
    try:
        import mediapipe as mp
    except ImportError as exc:
        raise PeerError("mediapipe is not installed (pip install mediapipe==0.10.14, or "
                        "pip install -e '.[peers]')") from exc

    boxes = np.asarray(boxes, dtype=np.float64)
    world = np.full((len(boxes), LANDMARKS, 3), np.nan)
    image = np.full_like(world, np.nan)
    capture, pose = cv2.VideoCapture(str(video)), None
    for t in range(len(boxes)):
        ok, frame = capture.read()
        if not ok:
            break
        rgb = cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)
        found = None if pose is None else _process(pose, rgb)
        if found is None or not subject_frames(found[1][None], boxes[t][None])[0]:
            if pose is not None:
                pose.close()
            pose = mp.solutions.pose.Pose(static_image_mode=False,
                                          model_complexity=MODEL_COMPLEXITY,
                                          smooth_landmarks=True)
            found = _process(pose, _grey_outside(rgb, boxes[t]))
        if found is not None:
            world[t], image[t] = found
    capture.release()
    if pose is not None:
        pose.close()
    return {"world": world, "image": image, "frames": np.arange(len(boxes))}


def _process(pose, rgb: np.ndarray):
    """(world (33, 3), image (33, 3) pixels) of one RGB frame, or None if nobody."""
    result = pose.process(rgb)
    if result.pose_world_landmarks is None:
        return None
    h, w = rgb.shape[:2]
    world = np.array([[p.x, p.y, p.z] for p in result.pose_world_landmarks.landmark])
    image = np.array([[p.x * w, p.y * h, p.z * w] for p in result.pose_landmarks.landmark])
    return world, image
