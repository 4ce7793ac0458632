"""MCAP recording of tracked poses for Foxglove (JSON messages and schemas; README, Outputs):
``/pose``, ``/skeleton`` (foxglove.SceneUpdate: bodies and pelvis trails, Z-up metres), with
smoothing ``/smoothed/pose`` and ``/smoothed/skeleton`` written at the end; video times. Small
chunks, closed every ``flush_every_frames`` frames, survive a kill (mcap_repair); the file is
``PATH.partial`` (files.OutputFile) until close() (or interpreter exit) renames it onto PATH."""
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
from tracker.outputs.files import ClosedOnExit, OutputFile
from tracker.outputs.geometry import (BONE_INDEX, BONE_SIDE, JOINT_SIDE, SinkInputError,
                                      body_colours, check_centroid, check_joints, check_pose,
                                      checked_probability, checked_time, heading_deg,
                                      is_unfamiliar, known_novelty, pose_joints_m, pose_label,
                                      track_colour, y_up_to_z_up)

if TYPE_CHECKING:
    from tracker.pipeline import TrackedPose

#: Drawing sizes in metres.
BONE_THICKNESS_M, JOINT_DIAMETER_M, HEAD_DIAMETER_M, TRAIL_THICKNESS_M = 0.07, 0.1, 0.22, 0.06
AMBIGUOUS_ALPHA = 0.5       # opacity of bodies in ambiguous frames
#: A track's trail (pelvis path) covers this many seconds and is redrawn every TRAIL_EVERY frames.
TRAIL_S, TRAIL_EVERY = 8.0, 10
#: Seconds a body (a trail) stays drawn unless drawn again: one who left does not stay (code_notes).
SKELETON_LIFETIME_S, TRAIL_LIFETIME_S = 1.0, 3.0
_DECIMALS = 6  # JSON rounding: 1e-6 degrees or units is far below any estimate's accuracy
_GEOMETRY_DECIMALS = 3   # 1 mm and 1e-3 of a quaternion: below what a drawing shows
_NO_TURN = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}    # the identity quaternion


@functools.cache
def _schemas() -> dict[str, bytes]:
    """The channels' JSON schemas by name, as written: mcap_schemas.json (every field required,
    as we always set it), each ``PoseValues`` object given the 55 pose-vector names."""
    names = pose_vector_names()

    def fill(node: dict) -> dict:
        if node.get("title") == "PoseValues":
            node.update(properties={name: {"type": "number"} for name in names},
                        required=list(names))
        return node
    text = Path(__file__).with_name("mcap_schemas.json").read_text("utf-8")
    return {name: _to_bytes(schema) for name, schema in json.loads(text, object_hook=fill).items()}


def _timestamp(time_ns: int) -> dict:
    """A foxglove time or duration {sec, nsec} of ``time_ns`` nanoseconds."""
    return {"sec": time_ns // 1_000_000_000, "nsec": time_ns % 1_000_000_000}


def _estimate(vector: np.ndarray, names: list[str]) -> dict:
    return {"heading_deg": heading_deg(vector),
            "heading_norm": round(math.hypot(vector[0], vector[1]), _DECIMALS),
            "pose": dict(zip(names, np.round(vector, _DECIMALS).tolist()))}


def _colour_dicts(rgb: np.ndarray, alpha) -> list[dict]:
    """(N, 3) RGB and (N,) or scalar alpha -> foxglove.Color dicts."""
    rgba = np.column_stack([rgb, np.broadcast_to(alpha, (len(rgb),))])
    return [{"r": r, "g": g, "b": b, "a": a} for r, g, b, a in np.round(rgba, 3).tolist()]


def _placed(x: float, y: float, z: float, orientation: dict = _NO_TURN) -> dict:
    """A foxglove.Pose at (x, y, z) metres turned by the quaternion ``orientation``."""
    return {"position": {"x": x, "y": y, "z": z}, "orientation": orientation}


@functools.lru_cache(maxsize=128)
def _body_style(track_id: int, ambiguous: bool, unfamiliar: bool) -> tuple[list, list, dict, str]:
    """Per bone and sphere (18 joints, head) colour dicts, the label's colour and text (shared)."""
    colours = body_colours(track_id)
    alpha = AMBIGUOUS_ALPHA if ambiguous else 1.0
    r, g, b = track_colour(track_id)
    return (_colour_dicts(colours[BONE_SIDE], alpha),
            _colour_dicts(colours[np.r_[JOINT_SIDE, 0]], alpha),
            {"r": r, "g": g, "b": b, "a": 1.0}, pose_label(track_id, ambiguous, unfamiliar))


def _entity(kind: str, track_id: int, time_ns: int, lifetime_s: float, metadata: list,
            empty: str, **primitives: list) -> dict:
    """A ``foxglove.SceneEntity`` ``<kind>-<track_id>`` in the world frame: the primitive lists
    named in ``empty`` (space-separated) empty, then ``primitives``, in that order."""
    return {"timestamp": _timestamp(time_ns), "frame_id": "world", "id": f"{kind}-{track_id}",
            "lifetime": _timestamp(int(round(lifetime_s * 1e9))), "frame_locked": False,
            "metadata": [{"key": "track_id", "value": str(track_id)}] + metadata,
            **{name: [] for name in empty.split()}, **primitives}


#: Each bone's (start, end) joint rows (2, bones), and the spheres' sizes (18 joints, the
#: head), shared by every message (only read).
_BONE_ENDS = np.ascontiguousarray(BONE_INDEX.T)
_SPHERE_SIZES = tuple({"x": d, "y": d, "z": d}
                      for d in [JOINT_DIAMETER_M] * len(JOINT_SIDE) + [HEAD_DIAMETER_M])


def skeleton_entity(track_id: int, time_ns: int, joints3d: np.ndarray, ambiguous: bool,
                    unfamiliar: bool) -> dict:
    """A ``foxglove.SceneEntity`` ``track-<id>``: the body of joints3d (18, 3) metres, Y-up, as
    the live view draws it (bone cylinders, joint spheres, head, label; ambiguous translucent)."""
    joints = y_up_to_z_up(joints3d)
    bone_colours, sphere_colours, label_colour, text = _body_style(track_id, ambiguous, unfamiliar)
    starts, ends = joints[_BONE_ENDS]
    vectors = ends - starts
    lengths = np.sqrt(np.einsum("ij,ij->i", vectors, vectors))
    keep = np.flatnonzero(lengths > 1e-6)
    centres = (starts + ends) / 2
    if len(keep) < len(lengths):        # a bone of no length is not drawn
        vectors, lengths, centres = vectors[keep], lengths[keep], centres[keep]
    neck_to_head = joints[3] - joints[2]
    head = joints[3] + HEAD_DIAMETER_M / 2 * neck_to_head / max(
        math.sqrt(neck_to_head.dot(neck_to_head)), 1e-9)        # np.linalg.norm's sum
    label = [head[0], head[1], joints[:, 2].max() + 0.35]
    dx, dy, dz = (vectors / lengths[:, None]).T
    bones = np.empty((len(lengths), 8))     # rows: centre x y z, quaternion, length
    bones[:, :3], bones[:, 7] = centres, lengths
    # Quaternions (x, y, z, w) turning +Z (a foxglove cylinder's axis) onto the bones' axes.
    q = bones[:, 3:7]
    np.negative(dy, out=q[:, 0])
    q[:, 1], q[:, 2] = dx, 0.0
    np.add(dz, 1.0, out=q[:, 3])
    down = q[:, 3] < 1e-9
    if down.any():
        q[down] = [1.0, 0.0, 0.0, 0.0]      # pointing down -Z: half a turn about X
    q /= np.sqrt(np.add.reduce(q * q, axis=1, keepdims=True))   # np.linalg.norm's sum
    bones = np.round(bones, _GEOMETRY_DECIMALS, out=bones).tolist()
    points = np.empty((len(joints) + 2, 3))     # the joints, the head, the label
    points[:-2], points[-2], points[-1] = joints, head, label
    points = np.round(points, _GEOMETRY_DECIMALS, out=points).tolist()
    thick = BONE_THICKNESS_M
    cylinders = [{"pose": {"position": {"x": x, "y": y, "z": z},
                           "orientation": {"x": qx, "y": qy, "z": qz, "w": qw}},
                  "size": {"x": thick, "y": thick, "z": length},
                  "bottom_scale": 1.0, "top_scale": 1.0, "color": bone_colours[k]}
                 for (x, y, z, qx, qy, qz, qw, length), k in zip(bones, keep.tolist())]
    spheres = [{"pose": {"position": {"x": x, "y": y, "z": z}, "orientation": _NO_TURN},
                "size": size, "color": colour}
               for (x, y, z), size, colour in zip(points, _SPHERE_SIZES, sphere_colours)]
    flags = [{"key": "ambiguous", "value": "true" if ambiguous else "false"},
             {"key": "unfamiliar", "value": "true" if unfamiliar else "false"}]
    texts = [{"pose": _placed(*points[-1]), "billboard": True, "font_size": 0.15,
              "scale_invariant": False, "color": label_colour, "text": text}]
    return _entity("track", track_id, time_ns, SKELETON_LIFETIME_S, flags,
                   "arrows cubes lines triangles models", spheres=spheres, cylinders=cylinders,
                   texts=texts)


def trail_entity(track_id: int, time_ns: int, path_m: np.ndarray, ages: np.ndarray) -> dict:
    """A ``foxglove.SceneEntity`` ``trail-<id>``: the pelvis path path_m (N, 2) Z-up metres on the
    ground, in the track colour fading with ages (N,) in [0, 1] (0 newest, 1 oldest: clear)."""
    points = np.round(np.column_stack([path_m, np.full(len(path_m), 0.005)]), _DECIMALS)
    rgb = np.tile(track_colour(track_id), (len(points), 1))
    line = {"type": 0, "pose": _placed(0.0, 0.0, 0.0), "thickness": TRAIL_THICKNESS_M,
            "scale_invariant": False,
            "points": [{"x": x, "y": y, "z": z} for x, y, z in points.tolist()],
            "color": {"r": rgb[0, 0], "g": rgb[0, 1], "b": rgb[0, 2], "a": 1.0},
            "colors": _colour_dicts(rgb, 1.0 - np.clip(ages, 0.0, 1.0)), "indices": []}
    return _entity("trail", track_id, time_ns, TRAIL_LIFETIME_S, [],
                   "arrows cubes spheres cylinders triangles models texts", lines=[line])


def _to_bytes(message: dict) -> bytes:
    """A schema or record as compact JSON; NaN and infinities refused."""
    return json.dumps(message, allow_nan=False, separators=(",", ":")).encode("utf-8")


def _frame_bytes(message: dict) -> bytes:
    """:func:`_to_bytes`' JSON by orjson, faster; numbers checked finite before (code_notes)."""
    return orjson.dumps(message, option=orjson.OPT_SERIALIZE_NUMPY)


def _finish(state: dict) -> None:
    """Write summary and footer and rename, once; on failure keep the partial for recover_mcap."""
    if state["done"]:
        return
    state["done"] = True
    try:
        state["writer"].finish()
    except BaseException:
        state["stream"].discard(keep=True)
        raise
    state["stream"].commit()


class _SceneStream:
    """A skeleton topic's frame being collected: channel id (None: not registered yet), frame
    (None: none yet), its time in ns, the tracks' entities so far, the tracks drawn last."""

    def __init__(self, channel: int | None):
        self.channel = channel
        self.frame: int | None = None
        self.frame_ns = 0
        self.entities: dict[int, dict] = {}
        self.shown: set[int] = set()


class McapSink(ClosedOnExit):
    """Record tracked poses and skeletons into the MCAP file ``path`` (module docstring).
    metadata: name -> {key: value} records (values that are not strings stored as JSON).
    chunk_size: uncompressed bytes per chunk; flush_every_frames: frames per chunk at most."""

    def __init__(self, path: str | Path, metadata: Mapping[str, Mapping[str, object]] | None = None,
                 chunk_size: int = 64 * 1024, flush_every_frames: int = 10):
        if flush_every_frames < 1 or chunk_size < 1:
            raise SinkInputError("chunk_size and flush_every_frames must be positive")
        self.path = Path(path)
        self._names = pose_vector_names()
        self._flush_every = int(flush_every_frames)
        stream = OutputFile(self.path)
        writer = Writer(stream, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._state = {"writer": writer, "stream": stream, "done": False}
        try:
            writer.start(profile="", library="silhouette-pose tracker")
            for name, values in (metadata or {}).items():   # str -> str: others as JSON
                if not isinstance(values, Mapping):
                    raise SinkInputError(f"metadata {str(name)!r} must be a mapping, got "
                                         f"{type(values).__name__}")
                writer.add_metadata(str(name), {str(k): v if isinstance(v, str) else json.dumps(v)
                                                for k, v in values.items()})
            pose_schema = self._schema("silhouette_pose.TrackedPose")
            self._scene_schema = self._schema("foxglove.SceneUpdate")
            self._pose_channel = writer.register_channel("/pose", "json", pose_schema)
            scene_channel = writer.register_channel("/skeleton", "json", self._scene_schema)
        except BaseException:
            self._state["done"] = True
            stream.discard()
            raise
        # Runs at interpreter exit (e.g. after an uncaught exception) if close() was not called.
        self._finalizer = weakref.finalize(self, _finish, self._state)
        self._scenes = _SceneStream(scene_channel)    # /skeleton's frame being collected
        self._frames_since_flush = 0
        self._trails: dict[int, deque] = {}   # track id -> (time s, x, y) of its root
        self._smoothed = _SceneStream(None)   # channels registered by the first write_smoothed
        self._smoothed_pose_channel: int | None = None

    def _schema(self, name: str) -> int:
        """Register the JSON schema ``name`` (_schemas); its id."""
        return self._state["writer"].register_schema(name, "jsonschema", _schemas()[name])

    @property
    def closed(self) -> bool:
        """True once the footer has been written (or writing it failed)."""
        return self._state["done"]

    def _checked(self, pose: TrackedPose, scenes: _SceneStream, *poses: str) -> tuple:
        """(frame index, track id, time s, novelty or None, joints, the named pose vectors) of
        ``pose`` checked, and that it may come next on ``scenes``; SinkInputError else."""
        if self.closed:
            raise SinkInputError(f"MCAP sink {self.path.name} is closed")
        vectors = [check_pose(f"{name}55", pose.filtered if name == "smoothed"
                              else getattr(pose, name)) for name in poses]
        joints = check_joints(pose.joints_m)
        time_s = checked_time(pose.time_s)
        novelty = known_novelty(getattr(pose, "novelty", None))
        frame_index, track_id = int(pose.frame_index), int(pose.track_id)
        if frame_index < 0 or track_id < 0:
            raise SinkInputError(f"frame_index and track_id must be >= 0, got {frame_index}, "
                                 f"{track_id}")
        if scenes.frame is not None and frame_index < scenes.frame:
            raise SinkInputError(f"frame_index went backwards: {frame_index} after {scenes.frame}")
        if frame_index == scenes.frame and track_id in scenes.entities:
            raise SinkInputError(f"track {track_id} written twice in frame {frame_index}")
        return frame_index, track_id, time_s, novelty, joints, *vectors

    def write(self, pose: TrackedPose) -> None:
        """Record one track in one frame (frames in order); SinkInputError if bad, closed or
        after write_smoothed."""
        if self._smoothed.channel is not None and not self.closed:
            raise SinkInputError("poses streamed after the smoothed tracks: the stream is over")
        scenes = self._scenes
        frame_index, track_id, time_s, novelty, joints, raw, filtered = self._checked(
            pose, scenes, "raw", "filtered")
        time_ns = int(round(time_s * 1e9))
        message = {"timestamp": _timestamp(time_ns), "frame_index": frame_index,
                   "time_s": time_s, "track_id": track_id, "ambiguous": bool(pose.ambiguous),
                   "raw": _estimate(raw, self._names), "filtered": _estimate(filtered, self._names)}
        if pose.centroid_px is not None:
            message["centroid_px"] = check_centroid(pose.centroid_px).tolist()
        if novelty is not None:
            message["novelty"] = round(novelty, 4)
        if getattr(pose, "runner_up", None) is not None:
            message["runner_up"] = _estimate(check_pose("runner_up55", pose.runner_up),
                                             self._names)
            message["runner_up_probability"] = round(checked_probability(
                "runner_up_probability", pose.runner_up_probability), 4)
        # Everything is checked: only now does the sink's state change.
        if frame_index != scenes.frame:
            self._write_update(scenes)
            scenes.frame, scenes.frame_ns = frame_index, time_ns
        self._add(self._pose_channel, time_ns, message)
        scenes.entities[track_id] = skeleton_entity(track_id, time_ns, joints,
                                                    bool(pose.ambiguous), is_unfamiliar(novelty))
        trail = self._trails.setdefault(track_id, deque())
        trail.append((time_s, joints[0, 0], -joints[0, 2]))     # the root on the Z-up ground
        while trail[0][0] < time_s - TRAIL_S:
            trail.popleft()

    def end_frame(self, frame_index: int) -> None:
        """Nothing: a frame's scene update is written on the next frame's first pose or close."""

    def smoothed_channel(self) -> SmoothedChannel:
        """A sink for ``track_video``'s smoothed_sinks writing into this file's smoothed topics."""
        return SmoothedChannel(self)

    def write_smoothed(self, pose: TrackedPose) -> None:
        """Record one track's smoothed pose (pose.filtered) in one frame, drawn at the root of
        pose.joints_m; frames in order, after every streamed pose. SinkInputError if bad/closed."""
        scenes = self._smoothed
        frame_index, track_id, time_s, novelty, joints, smoothed = self._checked(
            pose, scenes, "smoothed")
        if scenes.channel is None:
            self._write_update(self._scenes)   # the streamed frames' last scene goes first
            self._scenes.frame = None    # and the stream is over (write() refuses more)
            writer = self._state["writer"]
            self._smoothed_pose_channel = writer.register_channel(
                "/smoothed/pose", "json", self._schema("silhouette_pose.SmoothedPose"))
            scenes.channel = writer.register_channel("/smoothed/skeleton", "json",
                                                     self._scene_schema)
        time_ns = int(round(time_s * 1e9))
        joints = pose_joints_m(smoothed[None], root_position_m=joints[:1])[0]
        if frame_index != scenes.frame:
            self._write_update(scenes)
            scenes.frame, scenes.frame_ns = frame_index, time_ns
        self._add(self._smoothed_pose_channel, time_ns, {
            "timestamp": _timestamp(time_ns), "frame_index": frame_index,
            "time_s": time_s, "track_id": track_id, "smoothed": _estimate(smoothed, self._names)})
        scenes.entities[track_id] = skeleton_entity(track_id, time_ns, joints,
                                                    bool(pose.ambiguous), is_unfamiliar(novelty))

    def _add(self, channel: int, time_ns: int, message: dict) -> None:
        self._state["writer"].add_message(channel, log_time=time_ns,
                                          data=_frame_bytes(message), publish_time=time_ns)

    def _write_update(self, scenes: _SceneStream) -> None:
        """Write the SceneUpdate of a skeleton topic's frame, if any: bodies, tracks gone deleted;
        on /skeleton also trails every TRAIL_EVERY frames, the chunk closed every flush_every."""
        if scenes.frame is None:
            return
        streamed = scenes is self._scenes
        kinds = ("track", "trail") if streamed else ("track",)
        trails = []
        for t in sorted(scenes.entities) if streamed and scenes.frame % TRAIL_EVERY == 0 else ():
            if len(self._trails[t]) >= 2:
                samples = np.array(self._trails[t])[::-1][::3][::-1]   # every 3rd, newest kept
                ages = (samples[-1, 0] - samples[:, 0]) / TRAIL_S
                trails.append(trail_entity(t, scenes.frame_ns, samples[:, 1:], ages))
        stamp = _timestamp(scenes.frame_ns)
        gone = sorted(scenes.shown - set(scenes.entities))
        self._add(scenes.channel, scenes.frame_ns, {
            "deletions": [{"timestamp": stamp, "type": 0, "id": f"{kind}-{t}"}
                          for t in gone for kind in kinds],
            "entities": [scenes.entities[t] for t in sorted(scenes.entities)] + trails})
        scenes.shown, scenes.entities = set(scenes.entities), {}
        if streamed:
            for t in gone:
                self._trails.pop(t, None)
            self._frames_since_flush += 1
            if self._frames_since_flush >= self._flush_every:
                self._state["writer"].flush()  # closes the chunk: it is now safe from a crash
                self._frames_since_flush = 0

    def close(self) -> None:
        """Write the last frame's scene, the summary and the footer; idempotent."""
        if self.closed:
            return
        try:
            self._write_update(self._scenes)
            self._write_update(self._smoothed)
        finally:
            self._finalizer.detach()
            _finish(self._state)

    def abandon(self) -> None:
        """Stop without a recording (a run that tracked nobody), the path keeping what it held;
        idempotent. One streamed in place (--out -) is finished, empty, to stay readable."""
        if self._state["stream"].in_place:
            self.close()
        elif not self.closed:
            self._state["done"] = True
            self._finalizer.detach()
            self._state["stream"].discard()


class SmoothedChannel:
    """The Sink ``track_video`` feeds smoothed tracks, for an McapSink's smoothed topics; after
    a Ctrl-C (pose_kind "filtered") it writes nothing: the filtered poses are in the file."""

    def __init__(self, sink: McapSink):
        self.sink = sink
        self.pose_kind = "smoothed"

    def write(self, pose: TrackedPose) -> None:
        if self.pose_kind == "smoothed":
            self.sink.write_smoothed(pose)

    def end_frame(self, frame_index: int) -> None:
        """Nothing: smoothed frames arrive at the end, in order."""

    def close(self) -> None:
        """Nothing: the McapSink closes with the other sinks."""
