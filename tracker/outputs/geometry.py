"""Stick-skeleton geometry and input checks shared by the output sinks.

Joint positions are (18, 3) metres in ``sequences.skeleton.POSE_JOINTS`` order, Y up, the subject
at heading 0 facing +Z (the camera, looking along -Z; image x along +X). Viewers are Z-up
(:func:`y_up_to_z_up`).
"""
from __future__ import annotations

import colorsys
import math

import numpy as np

from regressor.errors import SilhouettePoseError
from regressor.pose_model import UNFAMILIAR_NOVELTY
from sequences.pose_vector import joint_positions
from sequences.skeleton import BONES_FOR_DRAWING, CMU_UNIT_M, POSE_JOINTS

from tracker.video.decode import focal_length_px

N_JOINTS = len(POSE_JOINTS)

#: (B, 2) int indices into the 18 pose joints of each drawn bone (parent, child).
BONE_INDEX: np.ndarray = np.array(
    [[POSE_JOINTS.index(parent), POSE_JOINTS.index(child)] for parent, child in BONES_FOR_DRAWING],
    dtype=np.int64,
)
BONE_INDEX.flags.writeable = False

#: Track colours (RGB in [0, 1]): saturated and distinct from each other and from the grey
#: and white backgrounds of the viewers. Track id i gets entry i mod len.
TRACK_PALETTE: np.ndarray = np.array([   # red, blue, green, orange, purple, teal, pink, olive
    [0.90, 0.10, 0.10], [0.10, 0.45, 0.95], [0.05, 0.70, 0.20], [0.95, 0.55, 0.00],
    [0.60, 0.20, 0.85], [0.00, 0.70, 0.75], [0.85, 0.15, 0.60], [0.55, 0.45, 0.10],
])
TRACK_PALETTE.flags.writeable = False

#: Body sides: every pose joint and drawn bone is on the centre line, the left or the right.
CENTRE, LEFT, RIGHT = 0, 1, 2
#: (18,) int side of each pose joint; (B,) side of each drawn bone (that of its child joint).
JOINT_SIDE: np.ndarray = np.array([LEFT if name.startswith("Left") else
                                   RIGHT if name.startswith("Right") else CENTRE
                                   for name in POSE_JOINTS], dtype=np.int64)
BONE_SIDE: np.ndarray = JOINT_SIDE[BONE_INDEX[:, 1]]
JOINT_SIDE.flags.writeable = False
BONE_SIDE.flags.writeable = False

#: Hue turn (degrees) from a track's colour to its LEFT (+) and RIGHT (-) side colours.
SIDE_HUE_TURN_DEG = 40.0


class SinkInputError(SilhouettePoseError, ValueError):
    """A sink was given data of the wrong shape, type or value (message names the argument)."""


def track_colour(track_id: int) -> tuple[float, float, float]:
    """Colour (r, g, b) in [0, 1] of track ``track_id`` (palette entry ``track_id mod 8``)."""
    r, g, b = TRACK_PALETTE[int(track_id) % len(TRACK_PALETTE)]
    return float(r), float(g), float(b)


def body_colours(track_id: int) -> np.ndarray:
    """Colours (3, 3) RGB in [0, 1] of track ``track_id``'s body, rows indexed by side: CENTRE
    the track colour, LEFT and RIGHT its hue turned by +/- SIDE_HUE_TURN_DEG. Hue survives
    shading and translucency, so the sides stay apart and a swap of sides shows at a glance."""
    colour = track_colour(track_id)
    h, s, v = colorsys.rgb_to_hsv(*colour)
    turn = SIDE_HUE_TURN_DEG / 360.0
    sides = [colorsys.hsv_to_rgb((h + t) % 1.0, s, v) for t in (turn, -turn)]
    return np.array([colour, *sides])


def pose_label(track_id: int, ambiguous: bool = False, unfamiliar: bool = False) -> str:
    """The text drawn above a body: "track N", with "(ambiguous)" for an ambiguous frame and
    "(unfamiliar)" for a silhouette unlike the training ones (TrackedPose.unfamiliar)."""
    flags = [name for name, on in (("ambiguous", ambiguous), ("unfamiliar", unfamiliar)) if on]
    return f"track {int(track_id)}" + (f" ({', '.join(flags)})" if flags else "")


def heading_deg(vector: np.ndarray) -> float:
    """The heading of a pose vector (55,) (entries 0, 1: cos, sin), degrees in (-180, 180]
    rounded to 1e-6 (far below any estimate's accuracy)."""
    return round(math.degrees(math.atan2(vector[1], vector[0])), 6)


def check_joints(joints3d: np.ndarray) -> np.ndarray:
    """Pose-joint positions as float64 (18, 3) metres; SinkInputError otherwise."""
    joints = np.asarray(joints3d, dtype=np.float64)
    if joints.shape != (N_JOINTS, 3):
        raise SinkInputError(f"joints3d must have shape ({N_JOINTS}, 3) metres, got {joints.shape}")
    if not np.all(np.isfinite(joints)):
        raise SinkInputError("joints3d contains NaN or infinite values")
    return joints


def check_pose(name: str, pose: np.ndarray) -> np.ndarray:
    """A 55-D pose vector called ``name`` as float64 (55,); SinkInputError naming it otherwise."""
    vector = np.asarray(pose, dtype=np.float64)
    if vector.shape != (55,):
        raise SinkInputError(f"{name} must be a 55-D pose vector, got shape {vector.shape}")
    if not np.all(np.isfinite(vector)):
        raise SinkInputError(f"{name} contains NaN or infinite values")
    return vector


def check_centroid(centroid_px) -> np.ndarray:
    """A silhouette centroid (x, y) pixels as float64 (2,); SinkInputError otherwise."""
    centroid = np.asarray(centroid_px, dtype=np.float64)
    if centroid.shape != (2,) or not np.all(np.isfinite(centroid)):
        raise SinkInputError(f"centroid_px must be two finite numbers, got {centroid_px!r}")
    return centroid


def known_novelty(value) -> float | None:
    """A pose's novelty (PoseEstimates.novelty, a ratio) as a float >= 0, or None when unknown
    (None, or NaN from a model without a heading index); SinkInputError for anything else."""
    if value is None:
        return None
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        raise SinkInputError(f"novelty must be one number, got {value!r}") from None
    if isinstance(value, (bool, np.bool_)):
        raise SinkInputError(f"novelty must be one number, got {value!r}")
    if math.isnan(number):
        return None
    if not (math.isfinite(number) and number >= 0):
        raise SinkInputError(f"novelty must be a finite number >= 0, got {value}")
    return number


def _is_number(value) -> bool:
    """One real number (an int or float of Python or numpy), not a bool."""
    return (not isinstance(value, (bool, np.bool_))
            and isinstance(value, (int, float, np.integer, np.floating)))


def checked_probability(name: str, value) -> float:
    """A probability called ``name`` as a float in [0, 1]; SinkInputError naming it otherwise."""
    if not _is_number(value) or not 0 <= value <= 1:   # exact for huge ints, False for NaN
        raise SinkInputError(f"{name} must be a number in [0, 1], got {value!r}")
    return float(value)


def checked_time(value) -> float:
    """A pose's video time (seconds) as a float >= 0; SinkInputError otherwise."""
    try:
        number = float(value) if _is_number(value) else math.nan
    except OverflowError:                                # an int beyond any float
        number = math.inf
    if not (math.isfinite(number) and number >= 0):
        raise SinkInputError(f"time_s must be a finite number >= 0, got {value!r}")
    return number


def is_unfamiliar(novelty: float | None) -> bool:
    """Whether a novelty says the silhouette is unlike the training ones: above
    UNFAMILIAR_NOVELTY; False when unknown (None or NaN). TrackedPose.unfamiliar's rule."""
    return novelty is not None and novelty > UNFAMILIAR_NOVELTY


def pose_joints_m(vectors: np.ndarray, template=None, root_position_m: np.ndarray | None = None
                  ) -> np.ndarray:
    """Pose-joint positions (T, 18, 3) in metres (Y up) from pose vectors (T, 55). template: as
    ``sequences.pose_vector.joint_positions``; root_position_m: (T, 3) metres, None = origin."""
    root = None if root_position_m is None else np.asarray(root_position_m, np.float64) / CMU_UNIT_M
    return joint_positions(vectors, template, root_position=root) * CMU_UNIT_M


def y_up_to_z_up(points: np.ndarray) -> np.ndarray:
    """Points (..., 3) turned from the Y-up motion-capture frame to a Z-up viewer frame: +90
    degrees about X, (x, y, z) -> (x, -z, y); the camera then looks along +Y."""
    p = np.asarray(points, dtype=np.float64)
    return np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)


def ground_position_from_image(
    centroid_px: np.ndarray,
    bbox_height_px: np.ndarray,
    frame_width_px: int,
    frame_height_px: int,
    person_height_m: float = 1.7,
    focal_px: float | None = None,
    hip_height_m: float = 0.95,
) -> np.ndarray:
    """Approximate root (hip) positions (..., 3) metres from the centroids (..., 2) pixels (x
    right, y down) and silhouette heights bbox_height_px (...,) pixels (> 0), for a pinhole
    camera at the origin looking along -Z with focal length f = focal_px (default: an assumed
    field of view, focal_length_px(W)): distance d = f * person_height_m / height, root at
    ((cx - W/2) d / f, hip_height_m, -d). SinkInputError for non-positive sizes."""
    centroid = np.asarray(centroid_px, dtype=np.float64)
    height = np.asarray(bbox_height_px, dtype=np.float64)
    if centroid.shape[-1:] != (2,):
        raise SinkInputError(f"centroid_px must have shape (..., 2), got {centroid.shape}")
    if frame_width_px <= 0 or frame_height_px <= 0:
        raise SinkInputError(f"frame size must be positive, got {frame_width_px}x{frame_height_px}")
    if not np.all(height > 0):
        raise SinkInputError("bbox_height_px must be positive")
    if focal_px is None:
        focal_px = focal_length_px(frame_width_px)
    distance = focal_px * person_height_m / height
    lateral = (centroid[..., 0] - 0.5 * frame_width_px) * distance / focal_px
    return np.stack([lateral, np.full_like(lateral, hip_height_m), -distance], axis=-1)
