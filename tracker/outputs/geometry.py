"""Stick-skeleton geometry and input checks of the output sinks. Joints: (18, 3) metres in
``sequences.skeleton.POSE_JOINTS`` order, Y up, heading 0 facing the camera (+Z)."""
from __future__ import annotations

import colorsys
import math

import numpy as np

from regressor.errors import SilhouettePoseError
from regressor.pose_model import UNFAMILIAR_NOVELTY
from sequences.pose_vector import joint_positions
from sequences.skeleton import BONES_FOR_DRAWING, CMU_UNIT_M, POSE_JOINTS

from tracker.video.decode import focal_length_px

#: (B, 2) int indices into the 18 pose joints of each drawn bone (parent, child).
BONE_INDEX: np.ndarray = np.array([[POSE_JOINTS.index(parent), POSE_JOINTS.index(child)]
                                   for parent, child in BONES_FOR_DRAWING], dtype=np.int64)

#: Track colours (RGB in [0, 1]): saturated, distinct from each other and from the viewers' grey
#: and white backgrounds. Track id i gets entry i mod len.
TRACK_PALETTE: np.ndarray = np.array([   # red, blue, green, orange, purple, teal, pink, olive
    [0.90, 0.10, 0.10], [0.10, 0.45, 0.95], [0.05, 0.70, 0.20], [0.95, 0.55, 0.00],
    [0.60, 0.20, 0.85], [0.00, 0.70, 0.75], [0.85, 0.15, 0.60], [0.55, 0.45, 0.10],
])

#: Body sides: every pose joint and drawn bone is on the centre line, the left or the right.
CENTRE, LEFT, RIGHT = 0, 1, 2
#: (18,) int side of each pose joint; (B,) side of each drawn bone (that of its child joint).
JOINT_SIDE: np.ndarray = np.array([LEFT if name.startswith("Left") else
                                   RIGHT if name.startswith("Right") else CENTRE
                                   for name in POSE_JOINTS], dtype=np.int64)
BONE_SIDE: np.ndarray = JOINT_SIDE[BONE_INDEX[:, 1]]
for _table in (BONE_INDEX, TRACK_PALETTE, JOINT_SIDE, BONE_SIDE):
    _table.flags.writeable = False

#: Hue turn (degrees) from a track's colour to its LEFT (+) and RIGHT (-) side colours.
SIDE_HUE_TURN_DEG = 40.0


class SinkInputError(SilhouettePoseError, ValueError):
    """A sink was given data of the wrong shape, type or value (message names the argument)."""


def track_colour(track_id: int) -> tuple[float, float, float]:
    """Colour (r, g, b) in [0, 1] of track ``track_id`` (palette entry ``track_id mod 8``)."""
    return tuple(TRACK_PALETTE[int(track_id) % len(TRACK_PALETTE)].tolist())


def body_colours(track_id: int) -> np.ndarray:
    """Colours (3, 3) RGB of track ``track_id``'s sides: CENTRE its colour, LEFT and RIGHT its hue
    turned by +/- SIDE_HUE_TURN_DEG (hue survives shading and translucency: swaps show)."""
    colour = track_colour(track_id)
    h, s, v = colorsys.rgb_to_hsv(*colour)
    turn = SIDE_HUE_TURN_DEG / 360.0
    sides = [colorsys.hsv_to_rgb((h + t) % 1.0, s, v) for t in (turn, -turn)]
    return np.array([colour, *sides])


def pose_label(track_id: int, ambiguous: bool = False, unfamiliar: bool = False) -> str:
    """The text above a body: "track N", with "(ambiguous)" and "(unfamiliar)" when flagged."""
    flags = [name for name, on in (("ambiguous", ambiguous), ("unfamiliar", unfamiliar)) if on]
    return f"track {int(track_id)}" + (f" ({', '.join(flags)})" if flags else "")


def heading_deg(vector: np.ndarray) -> float:
    """Heading of a pose vector (55,) (cos, sin first), degrees in (-180, 180] to 1e-6."""
    return round(math.degrees(math.atan2(vector[1], vector[0])), 6)


def _finite(name: str, value, shape: tuple, wrong_shape: str) -> np.ndarray:
    """``value`` as float64 of ``shape``; SinkInputError ``wrong_shape.format(shape found)``."""
    array = np.asarray(value, dtype=np.float64)
    if array.shape != shape:
        raise SinkInputError(wrong_shape.format(array.shape))
    if not np.all(np.isfinite(array)):
        raise SinkInputError(f"{name} contains NaN or infinite values")
    return array


def check_joints(joints3d: np.ndarray) -> np.ndarray:
    """Pose-joint positions as float64 (18, 3) metres; SinkInputError otherwise."""
    return _finite("joints3d", joints3d, (18, 3), "joints3d must have shape (18, 3) metres, got {}")


def check_pose(name: str, pose: np.ndarray) -> np.ndarray:
    """A 55-D pose vector called ``name`` as float64 (55,); SinkInputError naming it otherwise."""
    return _finite(name, pose, (55,), f"{name} must be a 55-D pose vector, got shape {{}}")


def check_centroid(centroid_px) -> np.ndarray:
    """A silhouette centroid (x, y) pixels as float64 (2,); SinkInputError otherwise."""
    return _finite("centroid_px", centroid_px, (2,),
                   "centroid_px must be two numbers (x, y) pixels, got shape {}")


def known_novelty(value) -> float | None:
    """A pose's novelty (PoseEstimates.novelty, a ratio) as a float >= 0, or None when unknown
    (None, or NaN from a model without a heading index); SinkInputError for anything else."""
    if value is None or (isinstance(value, (float, np.floating)) and math.isnan(value)):
        return None
    return _number(value, math.inf, "novelty must be a finite number >= 0")


def _number(value, high: float, must: str) -> float:
    """A real number (not a bool) in [0, high] as a float; SinkInputError "must, got value"."""
    try:
        real = isinstance(value, (int, float, np.integer, np.floating)) \
            and not isinstance(value, (bool, np.bool_))
        number = float(value) if real else math.nan
    except OverflowError:                                # an int beyond any float
        number = math.inf
    if not (0 <= number <= high and math.isfinite(number)):
        raise SinkInputError(f"{must}, got {value!r}")
    return number


def checked_probability(name: str, value) -> float:
    """A probability called ``name`` as a float in [0, 1]; SinkInputError naming it otherwise."""
    return _number(value, 1.0, f"{name} must be a number in [0, 1]")


def checked_time(value) -> float:
    """A pose's video time (seconds) as a float >= 0; SinkInputError otherwise."""
    return _number(value, math.inf, "time_s must be a finite number >= 0")


def is_unfamiliar(novelty: float | None) -> bool:
    """TrackedPose.unfamiliar's rule: novelty above UNFAMILIAR_NOVELTY (False when unknown)."""
    return novelty is not None and novelty > UNFAMILIAR_NOVELTY


def pose_joints_m(vectors: np.ndarray, template=None, root_position_m: np.ndarray | None = None
                  ) -> np.ndarray:
    """Pose-joint positions (T, 18, 3) in metres (Y up) from pose vectors (T, 55). template: as
    ``sequences.pose_vector.joint_positions``; root_position_m: (T, 3) metres, None = origin."""
    root = None if root_position_m is None else np.asarray(root_position_m, np.float64) / CMU_UNIT_M
    return joint_positions(vectors, template, root_position=root) * CMU_UNIT_M


def y_up_to_z_up(points: np.ndarray) -> np.ndarray:
    """Points (..., 3) Y-up turned to a Z-up viewer's frame: (x, y, z) -> (x, -z, y)."""
    p = np.asarray(points, dtype=np.float64)
    return np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)


def ground_position_from_image(centroid_px: np.ndarray, bbox_height_px: np.ndarray,
                               frame_width_px: int, frame_height_px: int,
                               person_height_m: float = 1.7, focal_px: float | None = None,
                               hip_height_m: float = 0.95) -> np.ndarray:
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
