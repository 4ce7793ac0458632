"""Pose2Sim's balancing and swings trials: real 4-view videos with a 3-D reference
(../shared/data/pose2sim).

Reads the reference keypoints (.trc) and the calibration (Calib_qualisys.toml; swings uses
balancing's), and gives what an evaluation against them needs, per video frame: knee and elbow
flexion and the 8 limb angles (sequences.measures.LIMB_ANGLE_NAMES), the body heading
relative to each camera in this project's convention (sequences.pose_vector), and the reference
keypoints projected into each view.

Conventions (the data's README, checked by projecting the reference into the videos):
- The .trc is Y-up, metres: trc (X, Y, Z) = calibration world (Y, Z, X). Everything 3-D here
  stays in trc coordinates, which are right-handed with Y up, as the project's world frame.
- Calibration: per camera K (3, 3), OpenCV distortion (k1, k2, p1, p2), Rodrigues rotation and
  translation mapping calibration world to camera coordinates (metres), image size (width,
  height) pixels.
- Video frame i is .trc frame i + 1 (the trc's Frame# column starts at 1).
- Views are named as the videos: "cam01" .. "cam04" (the calibration's "cam_01" ..).
"""
from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from regressor.angles import wrap_deg

from .measures import LIMB_POINTS, flexion_from_points, limb_angles_from_points


#: The trial folder in the shared data, beside the repository (as the tests look for it).
DEFAULT_TRIAL = (Path(os.environ.get("SILHOUETTE_POSE_SHARED",
                                     Path(__file__).resolve().parents[2] / "shared"))
                 / "data" / "pose2sim" / "balancing")
VIEWS: tuple[str, ...] = ("cam01", "cam02", "cam03", "cam04")
TRC_FRAME_OFFSET = 1          # trc Frame# of video frame 0
REFERENCE_TRC = "pose-3d/S00_P00_T01_BalancingTrial_0-100_filt_butterworth.trc"
SWINGS_REFERENCE_TRC = "pose-3d/swings_mediapipe_triangulated.trc"
CALIBRATION = "calibration/Calib_qualisys.toml"
#: The trials by name: their folders in the shared data.
TRIALS: dict[str, Path] = {"balancing": DEFAULT_TRIAL, "swings": DEFAULT_TRIAL.parent / "swings"}
#: (proximal, middle, distal) reference keypoints of the four flexion angles, in
#: sequences.measures.FLEXION_NAMES order (L knee, R knee, L elbow, R elbow).
FLEXION_KEYPOINTS: tuple[tuple[str, str, str], ...] = (
    ("LHip", "LKnee", "LAnkle"), ("RHip", "RKnee", "RAnkle"),
    ("LShoulder", "LElbow", "LWrist"), ("RShoulder", "RElbow", "RWrist"),
)
#: The reference's keypoints drawn as a body, for measuring a silhouette against it
#: (lab.silhouette_evaluation.body_region): the torso quadrilateral, the head
#: keypoint, and the bones drawn as thick lines (feet included; Nose and the small toes
#: unused).
BODY_TORSO: tuple[str, ...] = ("RShoulder", "LShoulder", "LHip", "RHip")
BODY_HEAD = "Head"
BODY_BONES: tuple[tuple[str, str], ...] = (
    ("RHip", "RKnee"), ("RKnee", "RAnkle"), ("LHip", "LKnee"), ("LKnee", "LAnkle"),
    ("RAnkle", "RBigToe"), ("LAnkle", "LBigToe"), ("RAnkle", "RHeel"), ("LAnkle", "LHeel"),
    ("RShoulder", "RElbow"), ("RElbow", "RWrist"), ("LShoulder", "LElbow"), ("LElbow", "LWrist"),
    ("Neck", "Head"), ("RShoulder", "LShoulder"), ("RHip", "LHip"),
)
_TRC_HEADER_LINES = 5
_UNIT_TO_M = {"m": 1.0, "mm": 1e-3, "cm": 1e-2}
_WORLD_FROM_TRC = [2, 0, 1]   # world (X, Y, Z) = trc (Z, X, Y)
_TRC_FROM_WORLD = [1, 2, 0]   # trc (X, Y, Z) = world (Y, Z, X)


class Pose2SimError(ValueError):
    """A missing or malformed Pose2Sim file, or a view or frame the trial does not have."""


@dataclass(frozen=True)
class Reference:
    """The .trc reference. names: (K,) keypoint names; frames: (N,) trc Frame# (int);
    time_s: (N,); points: (N, K, 3) metres, trc coordinates (Y up)."""

    names: tuple[str, ...]
    frames: np.ndarray
    time_s: np.ndarray
    points: np.ndarray

    def keypoint(self, name: str) -> np.ndarray:
        """Positions (N, 3) metres of one keypoint."""
        if name not in self.names:
            raise Pose2SimError(f"the reference has no keypoint {name!r} (has {self.names})")
        return self.points[:, self.names.index(name)]


@dataclass(frozen=True)
class Camera:
    """One calibrated view: K (3, 3) px; distortion (4,) OpenCV (k1, k2, p1, p2); R (3, 3) and
    t (3,) metres, calibration world -> camera; size: (width, height) px."""

    name: str
    K: np.ndarray
    distortion: np.ndarray
    R: np.ndarray
    t: np.ndarray
    size: tuple[int, int]

    @property
    def centre_trc(self) -> np.ndarray:
        """Camera centre (3,) metres in trc coordinates."""
        return (-self.R.T @ self.t)[_TRC_FROM_WORLD]


# ---------------------------------------------------------------- reading

def _lines(path: Path, what: str) -> list[str]:
    try:
        return Path(path).read_text().splitlines()
    except OSError as exc:
        raise Pose2SimError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from exc


def read_trc(path: str | Path) -> Reference:
    """The keypoints of a .trc file (OpenSim's marker format, as Pose2Sim writes it), in metres.
    Raises Pose2SimError naming the file for a missing or malformed one."""
    path = Path(path)
    lines = _lines(path, "trc file")
    if len(lines) <= _TRC_HEADER_LINES or not lines[0].startswith("PathFileType"):
        raise Pose2SimError(f"{path}: not a .trc file (no PathFileType header)")
    settings = dict(zip(lines[1].split("\t"), lines[2].split("\t")))
    unit = settings.get("Units", "m").strip()
    if unit not in _UNIT_TO_M:
        raise Pose2SimError(f"{path}: unknown Units {unit!r} (expected m, cm or mm)")
    names = tuple(n.strip() for n in lines[3].split("\t")[2:] if n.strip())
    rows = [line for line in lines[_TRC_HEADER_LINES:] if line.strip()]
    try:
        data = np.loadtxt(rows, delimiter="\t", ndmin=2)
    except ValueError as exc:
        raise Pose2SimError(f"{path}: malformed data rows ({exc})") from exc
    if data.shape[1] != 2 + 3 * len(names) or not names:
        raise Pose2SimError(f"{path}: {data.shape[1]} data columns for {len(names)} keypoints "
                            f"(expected Frame#, Time and 3 per keypoint)")
    points = data[:, 2:].reshape(len(data), len(names), 3) * _UNIT_TO_M[unit]
    return Reference(names, data[:, 0].astype(np.int64), data[:, 1], points)


def _camera(section: dict, path: Path) -> Camera:
    try:
        K = np.asarray(section["matrix"], dtype=np.float64)
        dist = np.asarray(section["distortions"], dtype=np.float64)
        R = Rotation.from_rotvec(np.asarray(section["rotation"], dtype=np.float64)).as_matrix()
        t = np.asarray(section["translation"], dtype=np.float64)
        size = tuple(int(s) for s in section["size"])
    except (KeyError, TypeError, ValueError) as exc:
        raise Pose2SimError(f"{path}: camera {section.get('name', '?')!r} is incomplete or "
                            f"malformed ({exc})") from exc
    if K.shape != (3, 3) or dist.shape != (4,) or t.shape != (3,) or len(size) != 2:
        raise Pose2SimError(f"{path}: camera {section.get('name', '?')!r} needs a 3x3 matrix, "
                            f"4 distortions, 3 translations and a size")
    return Camera(str(section.get("name", "")), K, dist, R, t, (size[0], size[1]))


def read_calibration(path: str | Path) -> dict[str, Camera]:
    """Cameras of a Pose2Sim Calib_*.toml by view name ("cam_01" -> "cam01")."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            toml = tomllib.load(f)
    except OSError as exc:
        raise Pose2SimError(f"{path}: cannot read the calibration "
                            f"({exc.strerror or exc})") from exc
    except tomllib.TOMLDecodeError as exc:
        raise Pose2SimError(f"{path}: not a valid TOML calibration ({exc})") from exc
    cameras = {key.replace("_", ""): _camera(section, path) for key, section in toml.items()
               if isinstance(section, dict) and "matrix" in section}
    if not cameras:
        raise Pose2SimError(f"{path}: no cameras in the calibration")
    return cameras


@dataclass(frozen=True)
class Trial:
    """A trial: its folder, reference keypoints and cameras (by view name)."""

    root: Path
    reference: Reference
    cameras: dict[str, Camera]

    def camera(self, view: str) -> Camera:
        """The calibrated camera of a view ("cam01" ..)."""
        if view not in self.cameras:
            raise Pose2SimError(f"no view {view!r}; the calibration has {sorted(self.cameras)}")
        return self.cameras[view]

    def video(self, view: str) -> Path:
        """The mp4 of a view."""
        self.camera(view)
        return self.root / "videos" / f"{view}.mp4"

    def rows(self, video_frames) -> np.ndarray:
        """Reference rows (T,) int of video frame indices (T,) (video frame i = trc frame i+1)."""
        frames = np.asarray(video_frames, dtype=np.int64).reshape(-1)
        wanted = frames + TRC_FRAME_OFFSET
        rows = np.searchsorted(self.reference.frames, wanted)
        ok = (rows < len(self.reference.frames))
        ok[ok] = self.reference.frames[rows[ok]] == wanted[ok]
        if not ok.all():
            first = self.reference.frames[0] - TRC_FRAME_OFFSET
            last = self.reference.frames[-1] - TRC_FRAME_OFFSET
            raise Pose2SimError(f"video frame {int(frames[~ok][0])} has no reference (the "
                                f"reference covers video frames {first}..{last})")
        return rows

    def points(self, video_frames) -> np.ndarray:
        """Reference keypoints (T, K, 3) metres, trc coordinates, at video frames (T,)."""
        return self.reference.points[self.rows(video_frames)]


def trial_roots(spec: str | Path) -> dict[str, Path]:
    """The trial folders by name that ``spec`` names: "all" (every one of TRIALS), a name of
    TRIALS, or a folder (named by its last part)."""
    spec = str(spec)
    if spec == "all":
        return dict(TRIALS)
    if spec in TRIALS:
        return {spec: TRIALS[spec]}
    return {Path(spec).name: Path(spec)}


def reference_path(root: str | Path) -> Path:
    """The reference .trc of the trial in folder root: balancing's (REFERENCE_TRC), else
    swings' (SWINGS_REFERENCE_TRC) if that one exists."""
    root = Path(root)
    if not (root / REFERENCE_TRC).exists() and (root / SWINGS_REFERENCE_TRC).exists():
        return root / SWINGS_REFERENCE_TRC
    return root / REFERENCE_TRC


def calibration_path(root: str | Path) -> Path:
    """The calibration of the trial in folder root: its own (CALIBRATION), else that of the
    sibling balancing/ folder (the same cameras film both trials; swings has none)."""
    root = Path(root)
    shared = root.parent / "balancing" / CALIBRATION
    if not (root / CALIBRATION).exists() and shared.exists():
        return shared
    return root / CALIBRATION


def load_trial(root: str | Path = DEFAULT_TRIAL) -> Trial:
    """The trial in folder root (pose-3d/, calibration/, videos/ as in the data's README)."""
    root = Path(root)
    if not root.is_dir():
        raise Pose2SimError(f"{root}: Pose2Sim trial folder not found (needs ../shared/data/"
                            f"pose2sim/balancing beside the repository)")
    return Trial(root, read_trc(reference_path(root)), read_calibration(calibration_path(root)))


# ---------------------------------------------------------------- what the evaluation needs

def project_points(points_trc, camera: Camera) -> np.ndarray:
    """Pixel coordinates (..., 2) (x right, y down) of points (..., 3) metres in trc
    coordinates, with the camera's lens distortion (OpenCV model, k1 k2 p1 p2)."""
    p = np.asarray(points_trc, dtype=np.float64)[..., _WORLD_FROM_TRC]
    cam = p @ camera.R.T + camera.t
    if (cam[..., 2] <= 0).any():
        raise Pose2SimError(f"{camera.name}: a point lies behind the camera")
    x, y = cam[..., 0] / cam[..., 2], cam[..., 1] / cam[..., 2]
    k1, k2, p1, p2 = camera.distortion
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 * r2
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    K = camera.K
    return np.stack([K[0, 0] * xd + K[0, 1] * yd + K[0, 2], K[1, 1] * yd + K[1, 2]], axis=-1)


def project_reference(view: str, frames, trial: Trial | None = None) -> np.ndarray:
    """The reference keypoints (T, K, 2) in pixels of a view's video at video frames (T,).
    trial: a loaded Trial (default: load_trial() from the shared data).

    Pixels are those of the calibration's image (camera.size, 1088x1920). The cam01 and cam02
    videos are 1080 px wide: how their 8 px were cut is not known, so their x may be off by
    up to 8 px (the overlays look right)."""
    trial = load_trial() if trial is None else trial
    return project_points(trial.points(frames), trial.camera(view))


def reference_flexion(trial: Trial, frames) -> np.ndarray:
    """Reference knee and elbow flexion (T, 4) degrees (L knee, R knee, L elbow, R elbow;
    0 = straight) at video frames (T,), from the 3-D keypoints."""
    p = trial.points(frames)
    idx = np.array([[trial.reference.names.index(n) for n in trio]
                    for trio in FLEXION_KEYPOINTS])                     # (4, 3)
    return flexion_from_points(p[:, idx[:, 0]], p[:, idx[:, 1]], p[:, idx[:, 2]])


def reference_limb_angles(trial: Trial, frames) -> np.ndarray:
    """Reference limb angles (T, 8) degrees (sequences.measures.LIMB_ANGLE_NAMES: knee and
    elbow flexion, hip and shoulder against the trunk) at video frames (T,), from the 3-D
    keypoints."""
    return limb_angles_from_points(_keypoints(trial, frames, LIMB_POINTS))


def mid_hip_px(trial: Trial, view: str, frames) -> np.ndarray:
    """The reference's mid-hip (T, 2) in a view's pixels at video frames (T,)."""
    hips = _keypoints(trial, frames, ("LHip", "RHip")).mean(axis=1)
    return project_points(hips, trial.camera(view))


def _keypoints(trial: Trial, frames, names: tuple[str, ...]) -> np.ndarray:
    p = trial.points(frames)
    return p[:, [trial.reference.names.index(n) for n in names]]


def body_yaw_deg(trial: Trial, frames) -> np.ndarray:
    """The pelvis' yaw (T,) degrees about the vertical at video frames (T,), in the project's
    convention (pose_vector: the root's yaw): 0 faces trc +Z, positive turns counter-clockwise
    seen from above. Facing = (left hip - right hip) x up."""
    lh, rh = np.moveaxis(_keypoints(trial, frames, ("LHip", "RHip")), 1, 0)
    facing = np.cross(lh - rh, [0.0, 1.0, 0.0])
    return np.degrees(np.arctan2(facing[:, 0], facing[:, 2]))


def camera_azimuth_deg(trial: Trial, view: str, frames) -> np.ndarray:
    """Azimuth (T,) degrees of a view's camera seen from the subject (mid-hip) at video frames
    (T,), in the project's convention: the camera sits in direction Ry(az) (0, 0, 1)."""
    lh, rh = np.moveaxis(_keypoints(trial, frames, ("LHip", "RHip")), 1, 0)
    d = trial.camera(view).centre_trc - (lh + rh) / 2
    return np.degrees(np.arctan2(d[:, 0], d[:, 2]))


def reference_heading_deg(trial: Trial, view: str, frames) -> np.ndarray:
    """The reference body heading (T,) degrees in (-180, 180] relative to a view's camera at
    video frames (T,), as pose vectors give it: yaw - camera azimuth (0 = facing the camera)."""
    return wrap_deg(body_yaw_deg(trial, frames) - camera_azimuth_deg(trial, view, frames))


def camera_roll_deg(trial: Trial, view: str) -> float:
    """How far the scene's vertical leans clockwise in a view's image, degrees (the ``track
    --roll`` value): the image angle of a 0.5 m vertical segment standing on the subject's
    mid-hip, projected through the calibration (distortion included), averaged over the
    reference's frames. A camera rolled anticlockwise gives a positive value."""
    lh, rh = np.moveaxis(_keypoints(trial, video_frames(trial), ("LHip", "RHip")), 1, 0)
    hip = (lh + rh) / 2
    camera = trial.camera(view)
    d = project_points(hip + np.array([0.0, 0.5, 0.0]), camera) - project_points(hip, camera)
    return float(np.degrees(np.arctan2(d[:, 0], -d[:, 1])).mean())


class _CalibratedCamera:
    """A view's camera as sequences.render draws with it: project (with lens distortion)
    and size (height, width) px."""

    def __init__(self, camera: Camera, size_hw: tuple[int, int]):
        self.camera, self.size = camera, (int(size_hw[0]), int(size_hw[1]))

    def project(self, points_trc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = np.asarray(points_trc, dtype=np.float64)[..., _WORLD_FROM_TRC]
        depth = (p @ self.camera.R.T + self.camera.t)[..., 2]
        return project_points(points_trc, self.camera), depth


def render_view_masks(vertices_trc: np.ndarray, faces: np.ndarray, patch_start: np.ndarray,
                      camera: Camera, size_hw: tuple[int, int] | None = None) -> np.ndarray:
    """Silhouettes (T, H, W) bool of a posed body (vertices (T, V, 3) metres, trc coordinates;
    faces and patch_start as sequences.body.BodyModel has them) seen by a calibrated view,
    lens distortion included. size_hw: (height, width) px, default the calibration's image;
    a smaller one keeps its top-left part (the cam01/cam02 videos are 8 px narrower)."""
    from .render import silhouette_mask

    size_hw = (camera.size[1], camera.size[0]) if size_hw is None else size_hw
    view = _CalibratedCamera(camera, size_hw)
    return np.stack([silhouette_mask(v, faces, patch_start, view) for v in vertices_trc])


def video_frames(trial: Trial) -> np.ndarray:
    """Video frame indices (N,) that have a reference."""
    return trial.reference.frames - TRC_FRAME_OFFSET
