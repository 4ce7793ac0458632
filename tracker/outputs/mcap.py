"""MCAP recording of tracked poses, openable as is in Foxglove.

Channels (JSON messages, JSON-schema schemas):
- ``/pose`` (schema ``silhouette_pose.TrackedPose``): one message per track per frame: frame
  index, time, track id, ambiguous flag, the centroid in pixels and the novelty (how unlike the
  training silhouettes the frame's is: PoseEstimates.novelty) when known, and for both the raw
  regressor output and the Kalman-filtered pose (with ``track --lag``, the pose fixed-lag
  smoothed instead: tracker.tracks.fixed_lag; the ``settings`` metadata says which): heading in
  degrees, heading norm and the 55 values keyed by ``sequences.pose_vector.pose_vector_names()``
  (Foxglove plots them by name, e.g. ``/pose.filtered.pose.LeftArm_z``).
- ``/skeleton`` (schema ``foxglove.SceneUpdate``): one message per frame, one entity per track
  (id ``track-<id>``, frame ``world``, Z-up, metres) drawn as the live view draws it: a cylinder
  per bone, a sphere per joint and a head ball in the side colours (geometry.body_colours),
  translucent in ambiguous frames, and a text label; every TRAIL_EVERY frames also each track's
  pelvis path over the last TRAIL_S seconds (id ``trail-<id>``), a line strip fading with age.
  Entities of tracks absent from the frame are deleted; each entity lives SKELETON_LIFETIME_S
  (trails TRAIL_LIFETIME_S) unless drawn again, so a body whose person left, or through frames
  with nobody in them (which get no message), goes away within a second.
- ``/smoothed/pose`` (schema ``silhouette_pose.SmoothedPose``) and ``/smoothed/skeleton``
  (``foxglove.SceneUpdate``, drawn as ``/skeleton`` without trails; its chunks close by size
  only, 64 KB by default): with ``track``'s --smooth (the default), each whole track
  RTS-smoothed as the JSON and BVH get it, written at the end of the run
  (:meth:`McapSink.smoothed_channel`); the smoothed output follows the body better (README,
  Accuracy) but exists only once the video is done. Absent after a Ctrl-C's quick exit and
  with --no-smooth.
- Metadata records (e.g. ``video``, ``model``, ``settings``) given to the constructor.
Log and publish times, and the messages' ``time_s`` and timestamps, are each frame's own time in
the video (the container's, so a variable frame rate keeps its real timing: tracker.video.decode), the
first two in nanoseconds.

Crash safety: messages go into small compressed chunks (``chunk_size`` bytes, and a chunk is
closed at least every ``flush_every_frames`` frames); every finished chunk is handed to the
operating system at once, so a killed process leaves a file whose finished chunks are intact
(read it back with ``tracker.outputs.mcap_repair.recover_mcap``). The file is written as
``PATH.partial`` (locked: one writer at a time) and renamed onto PATH once complete, so an
existing PATH is replaced only by a finished recording (tracker/outputs/files.py). ``close()``
writes the summary and footer and renames; it runs on leaving a ``with`` block (also on
exceptions and Ctrl-C) and, failing that, at interpreter exit. If the footer cannot be written
(disk full), the partial file stays for recover_mcap.
"""
from __future__ import annotations

import functools
import json
import math
import weakref
from collections import deque
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import orjson
from mcap.writer import CompressionType, Writer

from sequences.pose_vector import pose_vector_names
from tracker.outputs.files import OutputFile
from tracker.outputs.geometry import (
    BONE_INDEX,
    BONE_SIDE,
    JOINT_SIDE,
    SinkInputError,
    body_colours,
    checked_probability,
    checked_time,
    check_joints,
    check_pose,
    is_unfamiliar,
    known_novelty,
    pose_joints_m,
    pose_label,
    track_colour,
    y_up_to_z_up,
)

if TYPE_CHECKING:
    from tracker.pipeline import TrackedPose

POSE_TOPIC = "/pose"
SKELETON_TOPIC = "/skeleton"
SMOOTHED_POSE_TOPIC = "/smoothed/pose"
SMOOTHED_SKELETON_TOPIC = "/smoothed/skeleton"
POSE_SCHEMA_NAME = "silhouette_pose.TrackedPose"
SMOOTHED_SCHEMA_NAME = "silhouette_pose.SmoothedPose"
SCENE_SCHEMA_NAME = "foxglove.SceneUpdate"
WORLD_FRAME = "world"
#: Drawing sizes in metres.
BONE_THICKNESS_M = 0.07
JOINT_DIAMETER_M = 0.1
HEAD_DIAMETER_M = 0.22
TRAIL_THICKNESS_M = 0.06
#: Opacity of bodies in ambiguous frames.
AMBIGUOUS_ALPHA = 0.5
#: A track's trail (pelvis path) covers this many seconds and is redrawn every TRAIL_EVERY frames.
TRAIL_S = 8.0
TRAIL_EVERY = 10
#: Seconds a body (and a trail) stays drawn without being drawn again: each frame's update
#: renews it, so a person who leaves, or frames with nobody, do not leave it standing (it had
#: lived forever, deletions coming only with a later frame that had someone in it). Longer
#: than a frame of any video down to 1 frame/s (trails: TRAIL_EVERY frames down to 3.3).
SKELETON_LIFETIME_S, TRAIL_LIFETIME_S = 1.0, 3.0
_DECIMALS = 6  # JSON rounding: 1e-6 degrees or units is far below any estimate's accuracy


# ---------------------------------------------------------------- JSON schemas

def _object(title: str, properties: dict, description: str = "") -> dict:
    """A JSON-schema object whose properties are all required (our messages always set all)."""
    schema = {"title": title, "type": "object", "properties": properties,
              "required": list(properties)}
    if description:
        schema["description"] = description
    return schema


def _array(items: dict) -> dict:
    return {"type": "array", "items": items}


_NUMBER = {"type": "number"}
_STRING = {"type": "string"}
_BOOLEAN = {"type": "boolean"}


def _time(title: str = "time") -> dict:
    seconds = {"type": "integer"} if title == "duration" else {"type": "integer", "minimum": 0}
    return _object(title, {"sec": seconds,
                           "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}})


def _vector3(title: str = "foxglove.Vector3") -> dict:
    return _object(title, {"x": _NUMBER, "y": _NUMBER, "z": _NUMBER})


def _colour() -> dict:
    return _object("foxglove.Color", {"r": _NUMBER, "g": _NUMBER, "b": _NUMBER, "a": _NUMBER},
                   "RGBA, each in [0, 1]")


def _pose() -> dict:
    quaternion = _object("foxglove.Quaternion",
                         {"x": _NUMBER, "y": _NUMBER, "z": _NUMBER, "w": _NUMBER})
    return _object("foxglove.Pose", {"position": _vector3(), "orientation": quaternion})


def _enum(title: str, values: dict[str, int]) -> dict:
    return {"title": title, "oneOf": [{"title": k, "const": v} for k, v in values.items()]}


def scene_update_schema() -> dict:
    """The JSON schema of Foxglove's ``foxglove.SceneUpdate`` message (field names and types as
    in Foxglove's published schemas; every field is listed as required because we always set it).
    """
    point3 = _vector3("foxglove.Point3")
    index_list = _array({"type": "integer", "minimum": 0})
    # Bodies use cylinders, spheres and texts, trails lines; the other lists are always empty.
    empty = _array({"type": "object"})
    primitives = {
        "arrows": empty, "cubes": empty, "triangles": empty, "models": empty,
        "spheres": _object("foxglove.SpherePrimitive", {
            "pose": _pose(), "size": _vector3(), "color": _colour()}),
        "cylinders": _object("foxglove.CylinderPrimitive", {
            "pose": _pose(), "size": _vector3(), "bottom_scale": _NUMBER, "top_scale": _NUMBER,
            "color": _colour()}),
        "lines": _object("foxglove.LinePrimitive", {
            "type": _enum("foxglove.LineType", {"LINE_STRIP": 0, "LINE_LOOP": 1, "LINE_LIST": 2}),
            "pose": _pose(), "thickness": {"type": "number", "minimum": 0},
            "scale_invariant": _BOOLEAN, "points": _array(point3), "color": _colour(),
            "colors": _array(_colour()), "indices": index_list}),
        "texts": _object("foxglove.TextPrimitive", {
            "pose": _pose(), "billboard": _BOOLEAN, "font_size": _NUMBER,
            "scale_invariant": _BOOLEAN, "color": _colour(), "text": _STRING}),
    }
    entity = _object("foxglove.SceneEntity", {
        "timestamp": _time(), "frame_id": _STRING, "id": _STRING,
        "lifetime": _time("duration"), "frame_locked": _BOOLEAN,
        "metadata": _array(_object("foxglove.KeyValuePair", {"key": _STRING, "value": _STRING})),
        **{name: item if item is empty else _array(item) for name, item in primitives.items()},
    }, "A visual element in a 3D scene; replaces any prior entity with the same id")
    deletion = _object("foxglove.SceneEntityDeletion", {
        "timestamp": _time(),
        "type": _enum("foxglove.SceneEntityDeletionType", {"MATCHING_ID": 0, "ALL": 1}),
        "id": _STRING,
    })
    return _object(SCENE_SCHEMA_NAME, {"deletions": _array(deletion), "entities": _array(entity)},
                   "An update to the entities displayed in a 3D scene")


def _estimate_schema() -> dict:
    """JSON schema of one pose estimate (_estimate): heading, its norm, the 55 values."""
    values = _object("PoseValues", {name: _NUMBER for name in pose_vector_names()},
                     "The 55 pose-vector entries by name: heading cos/sin, then angles in degrees")
    return _object("PoseEstimate", {
        "heading_deg": {"type": "number", "description": "atan2(sin, cos), degrees in (-180, 180]"},
        "heading_norm": {"type": "number", "description": "norm of (cos, sin); low = ambiguous"},
        "pose": values,
    })


def tracked_pose_schema() -> dict:
    """JSON schema of the ``/pose`` messages (see the module docstring)."""
    estimate = _estimate_schema()
    schema = _object(POSE_SCHEMA_NAME, {
        "timestamp": _time(),
        "frame_index": {"type": "integer", "minimum": 0},
        "time_s": {"type": "number", "description": "video time of the frame, seconds"},
        "track_id": {"type": "integer", "minimum": 0},
        "ambiguous": {"type": "boolean",
                      "description": "raw heading norm below the filter's threshold"},
        "raw": estimate,
        "filtered": estimate,
    }, "One tracked person's pose in one video frame")
    schema["properties"]["runner_up"] = {
        **estimate, "description": "the next most probable front/back hypothesis, filtered, "
                                   "when it is close (tracker.tracks.hypotheses.CLOSE_PROBABILITY)"}
    schema["properties"]["runner_up_probability"] = {
        "type": "number", "minimum": 0, "maximum": 1,
        "description": "probability of runner_up (present with it)"}
    schema["properties"]["novelty"] = {
        "type": "number", "minimum": 0,
        "description": "how unlike the training silhouettes the frame's is (about 1 % of "
                       "training rows are above 1; far above it the pose is extrapolated); "
                       "absent when unknown"}
    schema["properties"]["centroid_px"] = {
        "type": "array", "items": _NUMBER, "minItems": 2, "maxItems": 2,
        "description": "silhouette centroid (x, y) in pixels, when known"}
    return schema


def smoothed_pose_schema() -> dict:
    """JSON schema of the ``/smoothed/pose`` messages (see the module docstring)."""
    return _object(SMOOTHED_SCHEMA_NAME, {
        "timestamp": _time(),
        "frame_index": {"type": "integer", "minimum": 0},
        "time_s": {"type": "number", "description": "video time of the frame, seconds"},
        "track_id": {"type": "integer", "minimum": 0},
        "smoothed": _estimate_schema(),
    }, "One tracked person's pose in one video frame, the whole track RTS-smoothed")


# ---------------------------------------------------------------- message builders

def _timestamp(time_ns: int) -> dict:
    return {"sec": time_ns // 1_000_000_000, "nsec": time_ns % 1_000_000_000}


def _estimate(vector: np.ndarray, names: list[str]) -> dict:
    rounded = np.round(vector, _DECIMALS)
    return {
        "heading_deg": round(math.degrees(math.atan2(vector[1], vector[0])), _DECIMALS),
        "heading_norm": round(math.hypot(vector[0], vector[1]), _DECIMALS),
        "pose": dict(zip(names, rounded.tolist())),
    }


def _identity_pose() -> dict:
    return {"position": {"x": 0.0, "y": 0.0, "z": 0.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}


def _point_dicts(points: np.ndarray) -> list[dict]:
    rounded = np.round(points, _DECIMALS).tolist()
    return [{"x": x, "y": y, "z": z} for x, y, z in rounded]


def _colour_dicts(rgb: np.ndarray, alpha) -> list[dict]:
    """(N, 3) RGB and (N,) or scalar alpha -> foxglove.Color dicts."""
    rgba = np.column_stack([rgb, np.broadcast_to(alpha, (len(rgb),))])
    return [{"r": r, "g": g, "b": b, "a": a} for r, g, b, a in np.round(rgba, 3).tolist()]


def _z_to(directions: np.ndarray) -> np.ndarray:
    """Quaternions (N, 4) (x, y, z, w) turning +Z onto the unit vectors ``directions`` (N, 3)
    (a foxglove cylinder's axis is its local Z)."""
    x, y, z = directions.T
    q = np.column_stack([-y, x, np.zeros_like(x), 1.0 + z])
    flip = q[:, 3] < 1e-9                     # pointing down -Z: half a turn about X
    q[flip] = [1.0, 0.0, 0.0, 0.0]
    return q / np.linalg.norm(q, axis=1, keepdims=True)


_NO_TURN = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
_GEOMETRY_DECIMALS = 3   # 1 mm and 1e-3 of a quaternion: below what a drawing shows


@functools.lru_cache(maxsize=128)
def _body_style(track_id: int, ambiguous: bool, unfamiliar: bool = False
                ) -> tuple[list, list, dict, str]:
    """Per bone and per sphere (18 joints, head) colour dicts, the label's colour and text
    (the same for every frame of a track; shared by its messages, which are only read)."""
    colours = body_colours(track_id)
    alpha = AMBIGUOUS_ALPHA if ambiguous else 1.0
    r, g, b = track_colour(track_id)
    return (_colour_dicts(colours[BONE_SIDE], alpha),
            _colour_dicts(colours[np.r_[JOINT_SIDE, 0]], alpha),
            {"r": r, "g": g, "b": b, "a": 1.0},
            pose_label(track_id, ambiguous, unfamiliar))


def _duration(seconds: float) -> dict:
    """A foxglove duration {sec, nsec} of whole seconds and nanoseconds."""
    nanoseconds = int(round(seconds * 1e9))
    return {"sec": nanoseconds // 1_000_000_000, "nsec": nanoseconds % 1_000_000_000}


def skeleton_entity(track_id: int, time_ns: int, joints3d: np.ndarray, ambiguous: bool,
                    unfamiliar: bool = False) -> dict:
    """A ``foxglove.SceneEntity`` drawing one track's body as the live view does.

    joints3d: (18, 3) metres, Y-up (converted here to the Z-up ``world`` frame). A cylinder per
    bone of non-zero length and a sphere per joint, in the side colours of
    geometry.body_colours (track colour on the centre line, its hue turned one way on the left
    and the other on the right), a head ball, and a text label above the head. Ambiguous
    frames are translucent and labelled "(ambiguous)"; frames whose silhouette is unlike the
    training ones (TrackedPose.unfamiliar) are labelled "(unfamiliar)".
    """
    joints = y_up_to_z_up(joints3d)
    bone_colours, sphere_colours, label_colour, text = _body_style(int(track_id), bool(ambiguous),
                                                                   bool(unfamiliar))
    starts, ends = joints[BONE_INDEX[:, 0]], joints[BONE_INDEX[:, 1]]
    vectors = ends - starts
    lengths = np.sqrt(np.einsum("ij,ij->i", vectors, vectors))
    keep = np.flatnonzero(lengths > 1e-6)
    axes = vectors[keep] / lengths[keep, None]
    neck_to_head = joints[3] - joints[2]
    head = joints[3] + HEAD_DIAMETER_M / 2 * neck_to_head / max(np.linalg.norm(neck_to_head), 1e-9)
    label = [head[0], head[1], joints[:, 2].max() + 0.35]
    n = len(keep)
    numbers = np.round(np.concatenate([((starts + ends) / 2)[keep].ravel(), _z_to(axes).ravel(),
                                       lengths[keep], joints.ravel(), head, label]),
                       _GEOMETRY_DECIMALS).tolist()
    mid, turn, length = numbers[:3 * n], numbers[3 * n:7 * n], numbers[7 * n:8 * n]
    points = numbers[8 * n:]
    thick, joint_d = BONE_THICKNESS_M, JOINT_DIAMETER_M
    cylinders = [{"pose": {"position": {"x": mid[3 * i], "y": mid[3 * i + 1], "z": mid[3 * i + 2]},
                           "orientation": {"x": turn[4 * i], "y": turn[4 * i + 1],
                                           "z": turn[4 * i + 2], "w": turn[4 * i + 3]}},
                  "size": {"x": thick, "y": thick, "z": length[i]},
                  "bottom_scale": 1.0, "top_scale": 1.0, "color": bone_colours[k]}
                 for i, k in enumerate(keep.tolist())]
    spheres = [{"pose": {"position": {"x": points[3 * i], "y": points[3 * i + 1],
                                      "z": points[3 * i + 2]}, "orientation": _NO_TURN},
                "size": {"x": d, "y": d, "z": d}, "color": sphere_colours[i]}
               for i, d in enumerate([joint_d] * len(joints) + [HEAD_DIAMETER_M])]
    x, y, z = points[-3:]
    return {
        "timestamp": _timestamp(time_ns),
        "frame_id": WORLD_FRAME,
        "id": f"track-{track_id}",
        "lifetime": _duration(SKELETON_LIFETIME_S),
        "frame_locked": False,
        "metadata": [{"key": "track_id", "value": str(track_id)},
                     {"key": "ambiguous", "value": str(bool(ambiguous)).lower()},
                     {"key": "unfamiliar", "value": str(bool(unfamiliar)).lower()}],
        "arrows": [], "cubes": [], "lines": [], "triangles": [], "models": [],
        "spheres": spheres,
        "cylinders": cylinders,
        "texts": [{"pose": {"position": {"x": x, "y": y, "z": z}, "orientation": _NO_TURN},
                   "billboard": True, "font_size": 0.15, "scale_invariant": False,
                   "color": label_colour, "text": text}],
    }


def trail_entity(track_id: int, time_ns: int, path_m: np.ndarray, ages: np.ndarray) -> dict:
    """A ``foxglove.SceneEntity`` (id ``trail-<id>``) drawing a track's pelvis path on the
    ground as a line strip in the track colour, fading out with age.

    path_m: (N, 2) ground positions, Z-up world metres; ages: (N,) in [0, 1], 0 = newest
    (opaque), 1 = oldest (transparent).
    """
    points = np.column_stack([path_m, np.full(len(path_m), 0.005)])
    rgb = np.tile(track_colour(track_id), (len(points), 1))
    return {
        "timestamp": _timestamp(time_ns), "frame_id": WORLD_FRAME, "id": f"trail-{track_id}",
        "lifetime": _duration(TRAIL_LIFETIME_S), "frame_locked": False,
        "metadata": [{"key": "track_id", "value": str(track_id)}],
        "arrows": [], "cubes": [], "spheres": [], "cylinders": [], "triangles": [],
        "models": [], "texts": [],
        "lines": [{"type": 0, "pose": _identity_pose(), "thickness": TRAIL_THICKNESS_M,
                   "scale_invariant": False, "points": _point_dicts(points),
                   "color": {"r": rgb[0, 0], "g": rgb[0, 1], "b": rgb[0, 2], "a": 1.0},
                   "colors": _colour_dicts(rgb, 1.0 - np.clip(ages, 0.0, 1.0)),
                   "indices": []}],
    }


def _to_bytes(message: dict) -> bytes:
    """A schema or record as compact JSON; NaN and infinities refused."""
    return json.dumps(message, allow_nan=False, separators=(",", ":")).encode("utf-8")


def _frame_bytes(message: dict) -> bytes:
    """A per-frame message as compact JSON, by orjson: the same JSON as :func:`_to_bytes`
    (read back equal, a test compares them; numbers may be spelled otherwise, 1e-5 for 1e-05)
    at a fifth of the cost (0.31 -> 0.07 ms a frame for the pose and scene
    messages of the bench video). orjson would write NaN as null instead of refusing it:
    every number here was checked finite before (check_pose, check_joints, checked_time,
    known_novelty, checked_probability)."""
    return orjson.dumps(message, option=orjson.OPT_SERIALIZE_NUMPY)


def _metadata_strings(name: str, values: Mapping[str, object]) -> dict[str, str]:
    """MCAP metadata is str -> str: strings stay, anything else is written as JSON."""
    if not isinstance(values, Mapping):
        raise SinkInputError(f"metadata {name!r} must be a mapping, got {type(values).__name__}")
    return {str(k): v if isinstance(v, str) else json.dumps(v) for k, v in values.items()}


# ---------------------------------------------------------------- the sink

def _finish(state: dict) -> None:
    """Write summary and footer and put the file in place, once (shared by close() and the
    finalizer). If that fails, the partial file is kept for recover_mcap."""
    if state["done"]:
        return
    state["done"] = True
    try:
        state["writer"].finish()
    except BaseException:
        state["stream"].discard(keep=True)
        raise
    state["stream"].commit()


class McapSink:
    """Record tracked poses and skeletons into an MCAP file (see the module docstring).

    path: output file (replaced once the recording is complete). metadata: name -> {key: value} records (values that are not
    strings are stored as JSON), e.g. {"video": {...}, "model": {...}, "settings": {...}}.
    chunk_size: uncompressed bytes per chunk. flush_every_frames: a chunk is also closed after
    this many frames, bounding what a crash can lose. compression: "zstd", "lz4" or "none".
    """

    def __init__(
        self,
        path: str | Path,
        metadata: Mapping[str, Mapping[str, object]] | None = None,
        chunk_size: int = 64 * 1024,
        flush_every_frames: int = 10,
        compression: str = "zstd",
    ):
        kinds = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
                 "none": CompressionType.NONE}
        if compression not in kinds:
            raise SinkInputError(f"compression must be one of {sorted(kinds)}, got {compression!r}")
        if flush_every_frames < 1 or chunk_size < 1:
            raise SinkInputError("chunk_size and flush_every_frames must be positive")
        self.path = Path(path)
        self._names = pose_vector_names()
        self._flush_every = int(flush_every_frames)
        # Written to PATH.partial under a lock, renamed onto PATH by close() (files.py).
        stream = OutputFile(self.path)
        writer = Writer(stream, chunk_size=chunk_size, compression=kinds[compression])
        self._state = {"writer": writer, "stream": stream, "done": False}
        try:
            self._start(writer, metadata)
        except BaseException:
            self._state["done"] = True
            stream.discard()
            raise
        # Runs at interpreter exit (e.g. after an uncaught exception) if close() was not called.
        self._finalizer = weakref.finalize(self, _finish, self._state)
        self._scenes = _SceneStream(self._scene_channel)    # /skeleton's frame being collected
        self._frames_since_flush = 0
        self._trails: dict[int, deque] = {}   # track id -> (time s, x, y) of its root
        self.messages_written = 0
        # /smoothed/skeleton's; its channels are registered by the first write_smoothed.
        self._smoothed = _SceneStream(None)
        self._smoothed_pose_channel: int | None = None

    def _start(self, writer: Writer, metadata) -> None:
        writer.start(profile="", library="silhouette-pose tracker")
        for name, values in (metadata or {}).items():
            writer.add_metadata(str(name), _metadata_strings(str(name), values))
        pose_schema = writer.register_schema(
            POSE_SCHEMA_NAME, "jsonschema", _to_bytes(tracked_pose_schema()))
        scene_schema = writer.register_schema(
            SCENE_SCHEMA_NAME, "jsonschema", _to_bytes(scene_update_schema()))
        self._pose_channel = writer.register_channel(POSE_TOPIC, "json", pose_schema)
        self._scene_channel = writer.register_channel(SKELETON_TOPIC, "json", scene_schema)
        self._scene_schema = scene_schema

    @property
    def closed(self) -> bool:
        """True once the footer has been written (or writing it failed)."""
        return self._state["done"]

    def write(self, pose: TrackedPose) -> None:
        """Record one track in one frame.

        pose.frame_index: video frame (>= 0, non-decreasing across calls); pose.time_s: video
        time in seconds (>= 0); raw, filtered: (55,) pose vectors; joints_m: (18, 3) metres,
        Y-up (drawn as given); centroid_px: optional (x, y) pixels. Raises SinkInputError on
        bad input or when the sink is closed.
        """
        frame_index, time_s, track_id = pose.frame_index, pose.time_s, pose.track_id
        ambiguous, centroid_px = pose.ambiguous, pose.centroid_px
        if self.closed:
            raise SinkInputError(f"MCAP sink {self.path.name} is closed")
        if self._smoothed.channel is not None:
            raise SinkInputError("poses streamed after the smoothed tracks: the stream is over")
        raw = check_pose("raw55", pose.raw)
        filtered = check_pose("filtered55", pose.filtered)
        joints = check_joints(pose.joints_m)
        time_s = checked_time(time_s)
        novelty = known_novelty(getattr(pose, "novelty", None))
        frame_index, track_id = int(frame_index), int(track_id)
        scenes = self._scenes
        scenes.check(frame_index, track_id)
        time_ns = int(round(time_s * 1e9))
        message = {
            "timestamp": _timestamp(time_ns), "frame_index": frame_index,
            "time_s": float(time_s), "track_id": track_id, "ambiguous": bool(ambiguous),
            "raw": _estimate(raw, self._names), "filtered": _estimate(filtered, self._names),
        }
        if centroid_px is not None:
            centroid = np.asarray(centroid_px, dtype=np.float64)
            if centroid.shape != (2,) or not np.all(np.isfinite(centroid)):
                raise SinkInputError(f"centroid_px must be two finite numbers, got "
                                     f"{centroid_px!r}")
            message["centroid_px"] = centroid.tolist()
        if novelty is not None:
            message["novelty"] = round(novelty, 4)
        if getattr(pose, "runner_up", None) is not None:
            message["runner_up"] = _estimate(check_pose("runner_up55", pose.runner_up),
                                             self._names)
            message["runner_up_probability"] = round(checked_probability(
                "runner_up_probability", pose.runner_up_probability), 4)
        # Everything is checked: only now does the sink's state change.
        if frame_index != scenes.frame:
            self._write_scene()
            scenes.frame, scenes.frame_ns = frame_index, time_ns
        self._add(self._pose_channel, time_ns, message)
        scenes.entities[track_id] = skeleton_entity(track_id, time_ns, joints, bool(ambiguous),
                                                    is_unfamiliar(novelty))
        trail = self._trails.setdefault(track_id, deque())
        trail.append((time_s, joints[0, 0], -joints[0, 2]))     # the root on the Z-up ground
        while trail[0][0] < time_s - TRAIL_S:
            trail.popleft()

    def end_frame(self, frame_index: int) -> None:
        """Nothing here: a frame's scene update is written when the next frame's first pose
        arrives, or on close."""

    def smoothed_channel(self) -> "SmoothedChannel":
        """A sink for ``track_video``'s smoothed_sinks that records what it is fed on
        ``/smoothed/pose`` and ``/smoothed/skeleton`` of this file (module docstring)."""
        return SmoothedChannel(self)

    def write_smoothed(self, pose: TrackedPose) -> None:
        """Record one track's smoothed pose in one frame: pose.filtered holds the smoothed
        pose (55,) (as tracker.run feeds smoothed sinks), drawn from its own angles with the
        root where pose.joints_m (18, 3) metres put it. Frames in non-decreasing order, after
        every streamed pose. Raises SinkInputError on bad input or when the sink is closed."""
        if self.closed:
            raise SinkInputError(f"MCAP sink {self.path.name} is closed")
        smoothed = check_pose("smoothed55", pose.filtered)
        root = check_joints(pose.joints_m)[:1]
        time_s = checked_time(pose.time_s)
        unfamiliar = is_unfamiliar(known_novelty(getattr(pose, "novelty", None)))
        frame_index, track_id = int(pose.frame_index), int(pose.track_id)
        scenes = self._smoothed
        scenes.check(frame_index, track_id)
        if scenes.channel is None:
            self._write_scene()          # the streamed frames' last scene goes first
            self._scenes.frame = None    # and the stream is over (write() refuses more)
            writer = self._state["writer"]
            self._smoothed_pose_channel = writer.register_channel(
                SMOOTHED_POSE_TOPIC, "json", writer.register_schema(
                    SMOOTHED_SCHEMA_NAME, "jsonschema", _to_bytes(smoothed_pose_schema())))
            scenes.channel = writer.register_channel(SMOOTHED_SKELETON_TOPIC, "json",
                                                     self._scene_schema)
        time_ns = int(round(time_s * 1e9))
        joints = pose_joints_m(smoothed[None], root_position_m=root)[0]
        if frame_index != scenes.frame:
            self._write_update(scenes, ("track",))
            scenes.frame, scenes.frame_ns = frame_index, time_ns
        self._add(self._smoothed_pose_channel, time_ns, {
            "timestamp": _timestamp(time_ns), "frame_index": frame_index,
            "time_s": float(time_s), "track_id": track_id,
            "smoothed": _estimate(smoothed, self._names)})
        scenes.entities[track_id] = skeleton_entity(track_id, time_ns, joints,
                                                    bool(pose.ambiguous), unfamiliar)

    def add_metadata(self, name: str, values: Mapping[str, object]) -> None:
        """Add a metadata record (e.g. results known only at the end)."""
        if self.closed:
            raise SinkInputError(f"MCAP sink {self.path.name} is closed")
        self._state["writer"].add_metadata(str(name), _metadata_strings(str(name), values))

    def _add(self, channel: int, time_ns: int, message: dict) -> None:
        self._state["writer"].add_message(channel, log_time=time_ns,
                                          data=_frame_bytes(message), publish_time=time_ns)
        self.messages_written += 1

    def _write_scene(self) -> None:
        """Write /skeleton's collected frame: its SceneUpdate with the trails every
        TRAIL_EVERY frames; tracks that left since the last one are deleted with their trails."""
        scenes = self._scenes
        if scenes.frame is None:
            return
        trails = ([self._trail(t) for t in sorted(scenes.entities) if len(self._trails[t]) >= 2]
                  if scenes.frame % TRAIL_EVERY == 0 else [])
        for track_id in self._write_update(scenes, ("track", "trail"), trails):
            self._trails.pop(track_id, None)
        self._frames_since_flush += 1
        writer = self._state["writer"]
        if self._frames_since_flush >= self._flush_every:
            writer.flush()  # closes the chunk: it is now safe from a crash
            self._frames_since_flush = 0

    def _write_update(self, scenes: "_SceneStream", kinds: tuple[str, ...],
                      extra: tuple | list = ()) -> list[int]:
        """Write the SceneUpdate of a skeleton topic's collected frame (none if no frame is):
        its tracks' entities, then ``extra``; the tracks drawn last time and not now deleted,
        each entity id ``<kind>-<track>`` of kinds. Starts the next frame's collection;
        returns the deleted tracks."""
        if scenes.frame is None:
            return []
        stamp = _timestamp(scenes.frame_ns)
        gone = sorted(scenes.shown - set(scenes.entities))
        self._add(scenes.channel, scenes.frame_ns, {
            "deletions": [{"timestamp": stamp, "type": 0, "id": f"{kind}-{t}"}
                          for t in gone for kind in kinds],
            "entities": [scenes.entities[t] for t in sorted(scenes.entities)] + list(extra)})
        scenes.shown, scenes.entities = set(scenes.entities), {}
        return gone

    def _trail(self, track_id: int) -> dict:
        samples = np.array(self._trails[track_id])[::-1][::3][::-1]   # every 3rd, newest kept
        ages = (samples[-1, 0] - samples[:, 0]) / TRAIL_S
        return trail_entity(track_id, self._scenes.frame_ns, samples[:, 1:], ages)

    def close(self) -> None:
        """Write the last frame's scene, the summary and the footer; idempotent."""
        if self.closed:
            return
        try:
            self._write_scene()
            self._write_update(self._smoothed, ("track",))
        finally:
            self._finalizer.detach()
            _finish(self._state)

    def abandon(self) -> None:
        """Stop without a recording (a run that tracked nobody): the partial file is removed
        and the path keeps what it held; idempotent. A recording streamed in place (--out -)
        has its header out already: it is finished, empty, so that it stays readable."""
        if self.closed:
            return
        if self._state["stream"].in_place:
            self.close()
            return
        self._state["done"] = True
        self._finalizer.detach()
        self._state["stream"].discard()

    def __enter__(self) -> "McapSink":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


class _SceneStream:
    """A skeleton topic's frame being collected: its channel id (None: not registered yet),
    the frame (None: none yet) and its time in ns, the tracks' entities so far, and the tracks
    its last update drew."""

    def __init__(self, channel: int | None):
        self.channel = channel
        self.frame: int | None = None
        self.frame_ns = 0
        self.entities: dict[int, dict] = {}
        self.shown: set[int] = set()

    def check(self, frame_index: int, track_id: int) -> None:
        """SinkInputError unless track track_id of frame frame_index may come next."""
        if frame_index < 0 or track_id < 0:
            raise SinkInputError(f"frame_index and track_id must be >= 0, got {frame_index}, "
                                 f"{track_id}")
        if self.frame is not None and frame_index < self.frame:
            raise SinkInputError(f"frame_index went backwards: {frame_index} after {self.frame}")
        if frame_index == self.frame and track_id in self.entities:
            raise SinkInputError(f"track {track_id} written twice in frame {frame_index}")


class SmoothedChannel:
    """The Sink that ``track_video`` feeds smoothed tracks (smoothed_sinks) and that writes
    them into an open McapSink (McapSink.write_smoothed). After a Ctrl-C's quick exit the run
    feeds the filtered poses instead and says so (pose_kind = "filtered"): those are in the
    file already, so they are not written again. Closing it closes nothing: the McapSink
    itself is closed with the other sinks, after the smoothed tracks."""

    def __init__(self, sink: McapSink):
        self.sink = sink
        self.pose_kind = "smoothed"

    def write(self, pose: TrackedPose) -> None:
        if self.pose_kind == "smoothed":
            self.sink.write_smoothed(pose)

    def end_frame(self, frame_index: int) -> None:
        """Nothing: smoothed frames arrive at the end, in order."""

    def close(self) -> None:
        """Nothing: see the class docstring."""
