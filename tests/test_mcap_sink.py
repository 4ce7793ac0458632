"""MCAP sink: readable with CRC checks, Foxglove schema names, crash safety and recovery."""
from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import NonSeekingReader, make_reader
from mcap.stream_reader import StreamReader

from sequences.pose_vector import pose_vector_names
from tracker.outputs.files import partial_path
from tracker.outputs.mcap_repair import McapRecoveryError, recover_mcap
from tracker.outputs.mcap import McapSink, SinkInputError
from sequences.skeleton import POSE_JOINTS
from tracker.outputs.geometry import CENTRE, LEFT, RIGHT, body_colours, pose_joints_m
from tracker import TrackedPose

ROOT = Path(__file__).resolve().parents[1]
FPS = 25.0


def _pose(rng: np.random.Generator) -> np.ndarray:
    vector = rng.normal(0.0, 20.0, 55)
    heading = rng.uniform(-math.pi, math.pi)
    vector[:2] = 0.8 * np.cos(heading), 0.8 * np.sin(heading)
    return vector


def _record(path: Path, frames: int = 20, **kwargs) -> dict[int, list[int]]:
    """Track 1 in every frame, track 2 in the first half only. Returns frames per track."""
    rng = np.random.default_rng(7)
    joints = pose_joints_m(np.r_[1.0, np.zeros(54)][None])[0]
    seen: dict[int, list[int]] = {1: [], 2: []}
    metadata = {"video": {"path": "walk.mp4", "fps": FPS}, "model": {"name": "default"},
                "settings": {"smoothing": "kalman"}}
    with McapSink(path, metadata=metadata, **kwargs) as sink:
        for frame in range(frames):
            for track in (1, 2) if frame < frames // 2 else (1,):
                raw = _pose(rng)
                sink.write(TrackedPose(frame, frame / FPS, track, raw, raw * 0.5, frame % 3 == 0,
                           joints + [track, 0.0, 0.0], centroid_px=(100.0 + frame, 50.0),
                           novelty=0.25 * frame if track == 1 else None))
                seen[track].append(frame)
    return seen


def _messages(path: Path):
    with open(path, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        return [(schema, channel, message) for schema, channel, message in reader.iter_messages()]


def _check_required(instance, schema: dict, where: str = "$") -> None:
    """Check the required properties and JSON types of ``instance`` against ``schema``."""
    types = {"object": dict, "array": list, "string": str, "boolean": bool,
             "integer": int, "number": (int, float)}
    kind = schema.get("type")
    if kind is not None:
        assert isinstance(instance, types[kind]), f"{where}: expected {kind}"
        if kind in ("integer", "number"):
            assert not isinstance(instance, bool), f"{where}: expected {kind}, got boolean"
    if "oneOf" in schema:
        assert instance in [option["const"] for option in schema["oneOf"]], where
    if isinstance(instance, dict):
        for name in schema.get("required", []):
            assert name in instance, f"{where}: missing required {name!r}"
        for name, sub in schema.get("properties", {}).items():
            if name in instance:
                _check_required(instance[name], sub, f"{where}.{name}")
    if isinstance(instance, list) and "items" in schema:
        for i, item in enumerate(instance):
            _check_required(item, schema["items"], f"{where}[{i}]")


def test_recording_reads_back_with_crc_validation_and_exact_counts(tmp_path):
    path = tmp_path / "run.mcap"
    seen = _record(path)
    messages = _messages(path)
    poses = [m for s, c, m in messages if c.topic == "/pose"]
    scenes = [m for s, c, m in messages if c.topic == "/skeleton"]
    assert len(poses) == sum(len(f) for f in seen.values())
    assert len(scenes) == 20  # one SceneUpdate per frame
    # The non-seeking reader also checks the data-section CRC and reads every record.
    with open(path, "rb") as stream:
        assert sum(1 for _ in NonSeekingReader(stream, validate_crcs=True).iter_messages()) \
            == len(messages)
    with open(path, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        summary = reader.get_summary()
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    assert summary.statistics.message_count == len(messages)
    assert summary.statistics.chunk_count >= 2  # small chunks, flushed every 10 frames
    assert set(metadata) == {"video", "model", "settings"}
    assert metadata["video"] == {"path": "walk.mp4", "fps": "25.0"}


def test_schemas_are_named_and_encoded_for_foxglove(tmp_path):
    path = tmp_path / "run.mcap"
    _record(path, frames=4)
    by_topic = {c.topic: (s, c) for s, c, m in _messages(path)}
    scene_schema, scene_channel = by_topic["/skeleton"]
    pose_schema, pose_channel = by_topic["/pose"]
    assert scene_schema.name == "foxglove.SceneUpdate"
    assert pose_schema.name == "silhouette_pose.TrackedPose"
    for schema, channel in by_topic.values():
        assert schema.encoding == "jsonschema"
        assert channel.message_encoding == "json"
    entity = json.loads(scene_schema.data)["properties"]["entities"]["items"]
    assert set(entity["properties"]) >= {
        "timestamp", "frame_id", "id", "lifetime", "frame_locked", "metadata", "arrows",
        "cubes", "spheres", "cylinders", "lines", "triangles", "texts", "models"}
    line = entity["properties"]["lines"]["items"]["properties"]
    assert set(line) == {"type", "pose", "thickness", "scale_invariant", "points", "color",
                         "colors", "indices"}


def test_the_schemas_file_is_package_data():
    """The schemas are read from tracker/outputs/mcap_schemas.json at run time: a package
    installed from a wheel must carry it, and every PoseValues object gets the 55 names."""
    import fnmatch
    import tomllib
    import tracker.outputs.mcap as mcap_module
    package_data = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-data"]
    assert any(fnmatch.fnmatch("outputs/mcap_schemas.json", pattern)
               for pattern in package_data.get("tracker", []))
    pose = json.loads(mcap_module._schemas()["silhouette_pose.TrackedPose"])
    for name in ("raw", "filtered", "runner_up"):
        assert pose["properties"][name]["properties"]["pose"]["required"] == pose_vector_names()


def test_messages_satisfy_their_schemas(tmp_path):
    path = tmp_path / "run.mcap"
    _record(path, frames=6)
    jsonschema = None
    try:
        import jsonschema
    except ImportError:
        pass
    for schema, channel, message in _messages(path):
        body, spec = json.loads(message.data), json.loads(schema.data)
        _check_required(body, spec)
        if jsonschema is not None:
            jsonschema.validate(body, spec)


def test_scene_draws_one_entity_per_track_and_deletes_tracks_that_left(tmp_path):
    path = tmp_path / "run.mcap"
    _record(path, frames=8)
    scenes = [json.loads(m.data) for s, c, m in _messages(path) if c.topic == "/skeleton"]
    assert [sorted(e["id"] for e in u["entities"]) for u in scenes] == \
        [["track-1", "track-2"]] * 4 + [["track-1"]] * 4
    assert [d["id"] for d in scenes[4]["deletions"]] == ["track-2", "trail-2"]
    assert all(not u["deletions"] for i, u in enumerate(scenes) if i != 4)
    entity = scenes[0]["entities"][0]
    assert entity["frame_id"] == "world"
    # Each body expires a second after it was last drawn: after the last frame with its person
    # (and through frames with nobody, which get no update) it does not stay on screen.
    assert entity["lifetime"] == {"sec": 1, "nsec": 0}
    assert len(entity["spheres"]) == 18 + 1                      # joints and a head ball
    assert len(entity["cylinders"]) == 17 - 3                   # bones of non-zero length
    colours = {json.dumps(e["spheres"][0]["color"]) for e in scenes[0]["entities"]}
    assert len(colours) == 2  # one colour per track


def test_bodies_have_side_colours_and_ambiguous_frames_are_translucent(tmp_path):
    path = tmp_path / "run.mcap"
    _record(path, frames=4)                     # frames 0 and 3 ambiguous
    scenes = [json.loads(m.data) for s, c, m in _messages(path) if c.topic == "/skeleton"]
    for frame, update in enumerate(scenes):
        entity = update["entities"][0]
        colours = body_colours(int(entity["id"].split("-")[1]))
        spheres = [(c["r"], c["g"], c["b"]) for c in (s["color"] for s in entity["spheres"])]
        for side, name in ((LEFT, "LeftHand"), (RIGHT, "RightHand"), (CENTRE, "Head")):
            np.testing.assert_allclose(spheres[POSE_JOINTS.index(name)], colours[side], atol=1e-3)
        alphas = {s["color"]["a"] for s in entity["spheres"] + entity["cylinders"]}
        assert alphas == ({0.5} if frame % 3 == 0 else {1.0})
        assert entity["texts"][0]["text"].endswith("(ambiguous)") == (frame % 3 == 0)


def test_trails_follow_the_pelvis_and_fade(tmp_path):
    path = tmp_path / "run.mcap"
    _record(path, frames=25)
    scenes = [json.loads(m.data) for s, c, m in _messages(path) if c.topic == "/skeleton"]
    with_trails = [i for i, u in enumerate(scenes)
                   if any(e["id"].startswith("trail-") for e in u["entities"])]
    assert with_trails == [10, 20]
    trail = next(e for e in scenes[20]["entities"] if e["id"] == "trail-1")["lines"][0]
    assert trail["type"] == 0 and len(trail["points"]) == 7      # every 3rd of frames 0..20
    alphas = [c["a"] for c in trail["colors"]]
    assert alphas == sorted(alphas) and alphas[-1] == 1.0 and alphas[0] < 1.0
    assert all(p["z"] < 0.01 for p in trail["points"])          # on the ground


def test_pose_message_holds_named_values_times_in_ns_and_headings(tmp_path):
    path = tmp_path / "run.mcap"
    rng = np.random.default_rng(3)
    raw, filtered = _pose(rng), _pose(rng)
    joints = pose_joints_m(np.r_[1.0, np.zeros(54)][None])[0]
    with McapSink(path) as sink:
        sink.write(TrackedPose(12, 0.48, 5, raw, filtered, True, joints))
    (_, _, message), = [m for m in _messages(path) if m[1].topic == "/pose"]
    body = json.loads(message.data)
    assert message.log_time == message.publish_time == 480_000_000
    assert body["timestamp"] == {"sec": 0, "nsec": 480_000_000}
    assert (body["frame_index"], body["track_id"], body["ambiguous"]) == (12, 5, True)
    names = pose_vector_names()
    np.testing.assert_allclose([body["raw"]["pose"][n] for n in names], raw, atol=1e-6)
    np.testing.assert_allclose([body["filtered"]["pose"][n] for n in names], filtered, atol=1e-6)
    assert body["raw"]["heading_deg"] == pytest.approx(math.degrees(math.atan2(raw[1], raw[0])),
                                                        abs=1e-5)
    assert body["raw"]["heading_norm"] == pytest.approx(0.8, abs=1e-6)


def test_exception_inside_with_block_still_writes_the_footer(tmp_path):
    path = tmp_path / "run.mcap"
    joints = np.zeros((18, 3))
    with pytest.raises(RuntimeError):
        with McapSink(path) as sink:
            sink.write(TrackedPose(0, 0.0, 1, np.r_[1.0, np.zeros(54)], np.r_[1.0, np.zeros(54)], False,
                       joints))
            raise RuntimeError("tracking failed")
    assert len(_messages(path)) == 2  # footer and summary present: the seeking reader works


def test_bad_input_and_use_after_close_raise_specific_errors(tmp_path):
    sink = McapSink(tmp_path / "run.mcap")
    good = np.r_[1.0, np.zeros(54)]
    with pytest.raises(SinkInputError, match="raw55"):
        sink.write(TrackedPose(0, 0.0, 1, np.zeros(54), good, False, np.zeros((18, 3))))
    with pytest.raises(SinkInputError, match="filtered55"):
        sink.write(TrackedPose(0, 0.0, 1, good, np.full(55, np.nan), False, np.zeros((18, 3))))
    with pytest.raises(SinkInputError, match="joints3d"):
        sink.write(TrackedPose(0, 0.0, 1, good, good, False, np.zeros((17, 3))))
    sink.write(TrackedPose(3, 0.1, 1, good, good, False, np.zeros((18, 3))))
    with pytest.raises(SinkInputError, match="backwards"):
        sink.write(TrackedPose(2, 0.1, 1, good, good, False, np.zeros((18, 3))))
    sink.close()
    sink.close()  # idempotent
    with pytest.raises(SinkInputError, match="closed"):
        sink.write(TrackedPose(4, 0.2, 1, good, good, False, np.zeros((18, 3))))


_SLOW_WRITER = textwrap.dedent("""
    import sys, time
    import numpy as np
    from tracker import TrackedPose
    from tracker.outputs.mcap import McapSink
    pose = np.r_[1.0, np.zeros(54)]
    with McapSink(sys.argv[1], flush_every_frames=int(sys.argv[2]),
                  chunk_size=int(sys.argv[3])) as sink:
        for frame in range(10_000):
            sink.write(TrackedPose(frame, frame / 25.0, 1, pose, pose, False, np.zeros((18, 3))))
            print(frame, flush=True)
            time.sleep(0.01)
""")


def _start_slow_writer(path: Path, flush_every: int, chunk_size: int = 65536) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.Popen([sys.executable, "-c", _SLOW_WRITER, str(path), str(flush_every),
                             str(chunk_size)],
                            stdout=subprocess.PIPE, text=True, env=env, cwd=ROOT)


def _wait_for_frame(proc: subprocess.Popen, frame: int) -> int:
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            raise AssertionError(f"writer exited early with code {proc.wait()}")
        if int(line) >= frame:
            return int(line)
    raise AssertionError("writer too slow")


def test_sigkill_leaves_every_flushed_frame_recoverable_and_the_old_file_intact(tmp_path):
    path, repaired = tmp_path / "killed.mcap", tmp_path / "repaired.mcap"
    path.write_bytes(b"the previous recording")
    flush_every = 4
    proc = _start_slow_writer(path, flush_every)
    last_printed = _wait_for_frame(proc, 25)
    proc.kill()
    proc.wait()
    assert path.read_bytes() == b"the previous recording"      # replaced only when complete
    # Frames 0 .. F*floor(k/F)-1 were in closed chunks when write(k) returned.
    durable = flush_every * (last_printed // flush_every)
    # The raw file has no footer: the streaming reader yields the whole chunks, then stops.
    with open(partial_path(path), "rb") as stream, pytest.raises(Exception):
        for _ in StreamReader(stream, validate_crcs=True).records:
            pass
    report = recover_mcap(partial_path(path), repaired)
    assert not report.complete
    frames = [json.loads(m.data)["frame_index"] for s, c, m in _messages(repaired)
              if c.topic == "/pose"]
    assert frames == list(range(len(frames)))  # an intact prefix, in order
    assert len(frames) >= durable
    assert report.messages == len(_messages(repaired))


def test_sigkill_keeps_chunks_closed_by_size(tmp_path):
    # Each message (> 1 KiB of JSON) overflows a 1 KiB chunk, so every message closes its chunk;
    # the sink must hand each chunk to the OS at once, not keep it in a userspace buffer.
    path, repaired = tmp_path / "killed.mcap", tmp_path / "repaired.mcap"
    proc = _start_slow_writer(path, flush_every=10_000, chunk_size=1024)
    last_printed = _wait_for_frame(proc, 15)
    proc.kill()
    proc.wait()
    recover_mcap(partial_path(path), repaired)
    frames = [json.loads(m.data)["frame_index"] for s, c, m in _messages(repaired)
              if c.topic == "/pose"]
    assert frames[: last_printed + 1] == list(range(last_printed + 1))


def test_recovering_a_complete_file_copies_everything(tmp_path):
    path, copy = tmp_path / "run.mcap", tmp_path / "copy.mcap"
    _record(path, frames=12)
    report = recover_mcap(path, copy)
    assert report.complete and report.stopped_by == ""
    assert report.metadata == 3
    original = [(c.topic, m.log_time, m.data) for s, c, m in _messages(path)]
    assert [(c.topic, m.log_time, m.data) for s, c, m in _messages(copy)] == original
    with pytest.raises(McapRecoveryError, match="different output"):
        recover_mcap(path, path)
    (tmp_path / "junk.mcap").write_bytes(b"not an mcap file at all")
    with pytest.raises(McapRecoveryError, match="bad magic"):
        recover_mcap(tmp_path / "junk.mcap", tmp_path / "out.mcap")


def test_ctrl_c_closes_the_file_with_its_footer(tmp_path):
    path = tmp_path / "interrupted.mcap"
    proc = _start_slow_writer(path, flush_every=100)
    _wait_for_frame(proc, 5)
    proc.send_signal(signal.SIGINT)
    proc.communicate(timeout=30)
    with open(path, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        statistics = reader.get_summary().statistics
    frames = [json.loads(m.data)["frame_index"] for s, c, m in _messages(path)
              if c.topic == "/pose"]
    assert statistics.message_count == len(_messages(path))
    assert len(frames) >= 6  # nothing buffered was lost, although no chunk had been flushed


def test_pose_messages_carry_the_novelty_when_known(tmp_path):
    path = tmp_path / "run.mcap"
    _record(path, frames=6)
    poses = [json.loads(m.data) for s, c, m in _messages(path) if c.topic == "/pose"]
    assert [p["novelty"] for p in poses if p["track_id"] == 1] == [0.25 * f for f in range(6)]
    assert all("novelty" not in p for p in poses if p["track_id"] == 2)
    (schema,) = {s.data for s, c, m in _messages(path) if c.topic == "/pose"}
    assert json.loads(schema)["properties"]["novelty"]["minimum"] == 0
    joints = pose_joints_m(np.r_[1.0, np.zeros(54)][None])[0]
    raw = np.r_[1.0, np.zeros(54)]
    with McapSink(tmp_path / "nan.mcap") as sink:       # NaN: a model without an index
        sink.write(TrackedPose(0, 0.0, 1, raw, raw, False, joints, novelty=float("nan")))
        for bad in (-0.5, float("inf")):
            with pytest.raises(SinkInputError, match="novelty"):
                sink.write(TrackedPose(1, 0.1, 1, raw, raw, False, joints, novelty=bad))
    (message,) = [json.loads(m.data) for s, c, m in _messages(tmp_path / "nan.mcap")
                  if c.topic == "/pose"]
    assert "novelty" not in message


def test_the_label_and_the_unfamiliar_rule():
    from tracker.outputs.geometry import pose_label
    assert [pose_label(3, a, u) for a, u in ((False, False), (True, False), (False, True),
                                             (True, True))] == \
        ["track 3", "track 3 (ambiguous)", "track 3 (unfamiliar)", "track 3 (ambiguous, unfamiliar)"]
    raw = np.r_[1.0, np.zeros(54)]
    assert [TrackedPose(0, 0.0, 1, raw, raw, False, np.zeros((18, 3)), novelty=n).unfamiliar
            for n in (None, float("nan"), 0.9, 1.0, 1.1)] == [False, False, False, False, True]


def test_skeleton_labels_and_metadata_follow_the_novelty(tmp_path):
    """Track 1's novelty in _record is 0.25 x frame: above 1 from frame 5 on."""
    path = tmp_path / "run.mcap"
    _record(path, frames=8)
    scenes = [json.loads(m.data) for s, c, m in _messages(path) if c.topic == "/skeleton"]
    for frame, update in enumerate(scenes):
        entity = next(e for e in update["entities"] if e["id"] == "track-1")
        unfamiliar = frame >= 5
        flags = [n for n, on in (("ambiguous", frame % 3 == 0), ("unfamiliar", unfamiliar)) if on]
        assert entity["texts"][0]["text"] == "track 1" + (f" ({', '.join(flags)})" if flags else "")
        assert {"key": "unfamiliar", "value": str(unfamiliar).lower()} in entity["metadata"]


def test_bad_input_is_refused_before_the_recording_changes(tmp_path):
    """A bad centroid, runner-up probability or novelty raises SinkInputError and writes
    nothing: the frame that follows is recorded as if the bad pose had never come."""
    raw = np.r_[1.0, np.zeros(54)]
    joints = pose_joints_m(raw[None])[0]
    with McapSink(tmp_path / "bad.mcap") as sink:
        sink.write(TrackedPose(0, 0.0, 1, raw, raw, False, joints))
        for bad in ({"centroid_px": (float("nan"), 1.0)}, {"centroid_px": (1.0,)},
                    {"runner_up": raw, "runner_up_probability": None},
                    {"runner_up": raw, "runner_up_probability": 1.5},
                    {"runner_up": raw, "runner_up_probability": "0.5"},
                    {"runner_up": raw, "runner_up_probability": float("nan")},
                    {"novelty": "high"}):
            with pytest.raises(SinkInputError):
                sink.write(TrackedPose(1, 0.1, 2, raw, raw, False, joints, **bad))
        sink.write(TrackedPose(1, 0.1, 2, raw, raw, False, joints))
    poses = [json.loads(m.data) for s, c, m in _messages(tmp_path / "bad.mcap")
             if c.topic == "/pose"]
    assert [(p["frame_index"], p["track_id"]) for p in poses] == [(0, 1), (1, 2)]
    scenes = [json.loads(m.data) for s, c, m in _messages(tmp_path / "bad.mcap")
              if c.topic == "/skeleton"]
    assert [[e["id"] for e in u["entities"]] for u in scenes] == [["track-1"], ["track-2"]]


def test_per_frame_messages_are_the_json_the_json_module_would_write(tmp_path, monkeypatch):
    """The per-frame messages go through orjson (speed); their content is what the json
    module writes (json.loads of both equal), numpy numbers included."""
    import tracker.outputs.mcap as mcap_module
    seen = []
    frame_bytes = mcap_module._frame_bytes

    def recording(message):
        seen.append(message)
        return frame_bytes(message)
    monkeypatch.setattr(mcap_module, "_frame_bytes", recording)
    _record(tmp_path / "r.mcap", frames=6)
    assert len(seen) >= 6 + 9           # pose messages and scene updates
    for message in seen + [{"x": np.float64(0.1), "y": np.arange(3), "z": [1e-5, 1e300]}]:
        assert json.loads(frame_bytes(message)) == json.loads(mcap_module._to_bytes(
            json.loads(json.dumps(message, default=lambda a: a.tolist()))))


def _record_with_smoothed(path: Path, frames: int = 6, kind: str = "smoothed"):
    """Tracks 1 (every frame) and 2 (first half) streamed, then fed to the smoothed channel as
    tracker.run does at the end: the same poses with `filtered` replaced by a 'smoothed' one
    and the root moved, in frame order. Returns the smoothed poses given, by (frame, track)."""
    rng = np.random.default_rng(3)
    joints = pose_joints_m(np.r_[1.0, np.zeros(54)][None])[0]
    given, streamed = {}, []
    with McapSink(path) as sink:
        for frame in range(frames):
            for track in (1, 2) if frame < frames // 2 else (1,):
                raw = _pose(rng)
                pose = TrackedPose(frame, frame / FPS, track, raw, raw * 0.5, False,
                                   joints + [track, 0.0, 0.1 * frame])
                sink.write(pose)
                streamed.append(pose)
        channel = sink.smoothed_channel()
        channel.pose_kind = kind
        for pose in streamed:
            smoothed = _pose(rng)
            given[(pose.frame_index, pose.track_id)] = (smoothed, pose.joints_m[0])
            channel.write(TrackedPose(pose.frame_index, pose.time_s, pose.track_id, pose.raw,
                                      smoothed, pose.frame_index % 2 == 0, pose.joints_m,
                                      novelty=2.0 if pose.frame_index == 1 else 0.5))
            channel.end_frame(pose.frame_index)
        channel.close()
        assert not sink.closed          # the channel closes nothing; the sink closes itself
    return given


def test_smoothed_tracks_are_recorded_on_their_own_topics(tmp_path):
    path = tmp_path / "run.mcap"
    given = _record_with_smoothed(path, frames=6)
    messages = _messages(path)
    by_topic: dict[str, list] = {}
    for schema, channel, message in messages:
        by_topic.setdefault(channel.topic, []).append((schema, json.loads(message.data)))
        _check_required(json.loads(message.data), json.loads(schema.data))
    assert {t: len(m) for t, m in by_topic.items()} == {
        "/pose": 9, "/skeleton": 6, "/smoothed/pose": 9, "/smoothed/skeleton": 6}
    assert by_topic["/smoothed/pose"][0][0].name == "silhouette_pose.SmoothedPose"
    assert by_topic["/smoothed/skeleton"][0][0].name == "foxglove.SceneUpdate"
    names = pose_vector_names()
    for _, body in by_topic["/smoothed/pose"]:
        smoothed, _ = given[(body["frame_index"], body["track_id"])]
        got = np.array([body["smoothed"]["pose"][n] for n in names])
        np.testing.assert_allclose(got, smoothed, atol=1e-6)
    # Each skeleton is drawn from the smoothed angles, its root where the track's was.
    scenes = [b for _, b in by_topic["/smoothed/skeleton"]]
    assert [sorted(e["id"] for e in u["entities"]) for u in scenes] == \
        [["track-1", "track-2"]] * 3 + [["track-1"]] * 3
    assert [d["id"] for d in scenes[3]["deletions"]] == ["track-2"]
    assert all(not u["deletions"] for i, u in enumerate(scenes) if i != 3)
    smoothed, root = given[(4, 1)]
    want = pose_joints_m(smoothed[None], root_position_m=root[None])[0]
    spheres = scenes[4]["entities"][0]["spheres"][:18]
    got = np.array([[s["pose"]["position"][k] for k in "xyz"] for s in spheres])
    np.testing.assert_allclose(got, want[:, [0, 2, 1]] * [1, -1, 1], atol=1e-3)
    # Ambiguous frames translucent, unfamiliar ones labelled, as on /skeleton.
    flags = [{m["key"]: m["value"] for m in u["entities"][0]["metadata"]} for u in scenes]
    assert [f["ambiguous"] for f in flags] == ["true", "false"] * 3
    assert [f["unfamiliar"] for f in flags] == ["false", "true"] + ["false"] * 4
        # The streamed scenes are untouched: no deletion of every track before the smoothed ones.
    assert [len(b["entities"]) for _, b in by_topic["/skeleton"]] == [2, 2, 2, 1, 1, 1]
    assert all(not b["deletions"] for _, b in by_topic["/skeleton"][4:])


def test_after_a_quick_exit_the_filtered_poses_are_not_recorded_again(tmp_path):
    path = tmp_path / "run.mcap"
    _record_with_smoothed(path, frames=4, kind="filtered")
    assert {c.topic for _, c, _ in _messages(path)} == {"/pose", "/skeleton"}


def test_smoothed_input_is_checked_and_the_stream_is_over(tmp_path):
    joints = pose_joints_m(np.r_[1.0, np.zeros(54)][None])[0]
    pose = TrackedPose(3, 0.12, 1, np.r_[1.0, np.zeros(54)], np.r_[1.0, np.zeros(54)], False,
                       joints)
    with McapSink(tmp_path / "run.mcap") as sink:
        sink.write(pose)
        with pytest.raises(SinkInputError, match="smoothed55"):
            sink.write_smoothed(TrackedPose(3, 0.12, 1, pose.raw, np.zeros(54), False, joints))
        sink.write_smoothed(pose)
        with pytest.raises(SinkInputError, match="twice in frame 3"):
            sink.write_smoothed(pose)
        with pytest.raises(SinkInputError, match="went backwards"):
            sink.write_smoothed(TrackedPose(2, 0.08, 1, pose.raw, pose.filtered, False, joints))
        with pytest.raises(SinkInputError, match="stream is over"):
            sink.write(TrackedPose(4, 0.16, 1, pose.raw, pose.filtered, False, joints))
    with pytest.raises(SinkInputError, match="closed"):
        sink.write_smoothed(pose)


@pytest.mark.parametrize("record, topic, frames", [
    (_record, "/skeleton", 25), (_record_with_smoothed, "/smoothed/skeleton", 6)])
def test_every_scene_update_validates_against_foxglove_official_schema(tmp_path, record, topic,
                                                                        frames):
    """Foxglove's own SceneUpdate schema (@foxglove/schemas 2.1.0, vendored under tests/data),
    on both skeleton topics."""
    jsonschema = pytest.importorskip("jsonschema")
    official = json.loads((ROOT / "tests" / "data" / "foxglove" / "SceneUpdate.json").read_text())
    path = tmp_path / "run.mcap"
    record(path, frames=frames)
    validator = jsonschema.Draft7Validator(official)
    scenes = [json.loads(m.data) for s, c, m in _messages(path) if c.topic == topic]
    assert len(scenes) == frames
    for update in scenes:
        errors = sorted(validator.iter_errors(update), key=str)
        assert not errors, errors[0]


def test_abandon_removes_the_partial_and_keeps_what_the_path_held(tmp_path):
    """A run that tracked nobody abandons its recording (tracker.outputs.close_sinks)."""
    path = tmp_path / "run.mcap"
    path.write_bytes(b"an earlier recording")
    sink = McapSink(path)
    assert partial_path(path).exists()
    sink.abandon()
    sink.abandon()                                   # idempotent
    assert sink.closed and path.read_bytes() == b"an earlier recording"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.mcap"]
    sink.close()                                     # nothing more is written
    assert path.read_bytes() == b"an earlier recording"
