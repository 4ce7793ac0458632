"""JSON summary: layout, values, speed, atomic replacement."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from tracker.outputs.json_summary import JsonSummarySink
from tracker.outputs.geometry import SinkInputError
from tracker import TrackedPose

JOINTS = np.zeros((18, 3))


class _Clock:
    """A clock the test advances by hand."""

    def __init__(self):
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _pose(heading_deg: float, norm: float, fill: float) -> np.ndarray:
    vector = np.full(55, fill)
    vector[0] = norm * math.cos(math.radians(heading_deg))
    vector[1] = norm * math.sin(math.radians(heading_deg))
    return vector


def test_summary_lists_tracks_with_filtered_values_and_speed(tmp_path):
    clock = _Clock()
    path = tmp_path / "summary.json"
    with JsonSummarySink(path, video_fps=25.0, clock=clock) as sink:
        for frame in range(10):
            sink.end_frame(frame)  # frames 0..9 processed, people only in 2..7
            if 2 <= frame <= 7:
                sink.write(TrackedPose(frame, frame / 25.0, 3, _pose(170.0 + 4 * frame, 0.3, 1.0),
                           _pose(175.0 + 4 * frame, 1.0, 2.0), frame == 4, JOINTS,
                           centroid_px=(10.0 * frame, 20.0)))
            if frame == 5:
                sink.write(TrackedPose(frame, 0.2, 1, _pose(0, 1, 0), _pose(0, 1, 0), False, JOINTS,
                           centroid_px=(1.0, 2.0)))
            clock.now += 0.5
    summary = json.loads(path.read_text())
    assert (summary["frames"], summary["video_fps"]) == (10, 25.0)
    assert summary["poses"] == "filtered"
    assert summary["fps"] == pytest.approx(10 / 5.0)
    assert [t["id"] for t in summary["tracks"]] == [1, 3]
    track = summary["tracks"][1]
    assert track["frames"] == list(range(2, 8))
    assert (track["first_frame"], track["last_frame"], track["n_frames"]) == (2, 7, 6)
    assert track["centroid_px"][0] == [20.0, 20.0]
    expected = [(175.0 + 4 * f + 180.0) % 360.0 - 180.0 for f in range(2, 8)]
    np.testing.assert_allclose(track["heading_deg"], expected, atol=1e-5)  # wraps past 180
    np.testing.assert_allclose(track["heading_norm"], 0.3, atol=1e-6)  # raw norm
    assert track["ambiguous"] == [f == 4 for f in range(2, 8)] and track["ambiguous_frames"] == 1
    assert track["heading_mean_deg"] == pytest.approx(193.0 - 360.0, abs=1e-4)
    assert np.array(track["pose"]).shape == (6, 55)
    np.testing.assert_allclose(np.array(track["pose"])[:, 2:], 2.0)


def test_write_needs_a_centroid_and_valid_vectors(tmp_path):
    sink = JsonSummarySink(tmp_path / "s.json", 25.0)
    good = _pose(0, 1, 0)
    with pytest.raises(SinkInputError, match="centroid_px"):
        sink.write(TrackedPose(0, 0.0, 1, good, good, False, JOINTS))
    with pytest.raises(SinkInputError, match="raw55"):
        sink.write(TrackedPose(0, 0.0, 1, np.full(55, np.inf), good, False, JOINTS, centroid_px=(1, 2)))
    sink.close()
    sink.close()
    with pytest.raises(SinkInputError, match="closed"):
        sink.write(TrackedPose(1, 0.0, 1, good, good, False, JOINTS, centroid_px=(1, 2)))
    assert json.loads((tmp_path / "s.json").read_text())["tracks"] == []


def test_summary_records_novelty_and_counts_unfamiliar_frames(tmp_path):
    """novelty per frame (None where unknown: none given, or NaN from a model without a
    heading index); unfamiliar_frames: those above UNFAMILIAR_NOVELTY (1)."""
    path = tmp_path / "summary.json"
    given = [0.4, 1.0, 1.7, None, float("nan"), 2.5, 1.00003]
    with JsonSummarySink(path, video_fps=25.0) as sink:
        for frame, novelty in enumerate(given):
            sink.write(TrackedPose(frame, frame / 25.0, 0, _pose(0, 1, 0), _pose(0, 1, 0), False,
                                   JOINTS, centroid_px=(1.0, 2.0), novelty=novelty))
        # a number given as text is refused, as a runner-up's probability is (geometry._number)
        for bad in (-0.1, float("inf"), "high", "1.5", [1.0, 2.0], True, 10 ** 400):
            with pytest.raises(SinkInputError, match="novelty"):
                sink.write(TrackedPose(9, 0.4, 0, _pose(0, 1, 0), _pose(0, 1, 0), False, JOINTS,
                                       centroid_px=(1.0, 2.0), novelty=bad))
        # a bad runner-up is refused before anything of the row is written
        for alt, probability in ((np.zeros(3), 0.5), (_pose(0, 1, 0), None),
                                 (_pose(0, 1, 0), 1.5), (_pose(0, 1, 0), -0.1),
                                 (_pose(0, 1, 0), "0.5"), (_pose(0, 1, 0), True),
                                 (_pose(0, 1, 0), float("nan"))):
            with pytest.raises(SinkInputError, match="runner_up"):
                sink.write(TrackedPose(9, 0.4, 0, _pose(0, 1, 0), _pose(0, 1, 0), False, JOINTS,
                                       centroid_px=(1.0, 2.0), runner_up=alt,
                                       runner_up_probability=probability))
    (track,) = json.loads(path.read_text())["tracks"]
    # rounded when written, counted by the value itself (1.00003 is above 1, as
    # TrackedPose.unfamiliar says)
    assert track["novelty"] == [0.4, 1.0, 1.7, None, None, 2.5, 1.0]
    assert track["unfamiliar_frames"] == 3 and track["n_frames"] == 7
    assert TrackedPose(0, 0.0, 0, _pose(0, 1, 0), _pose(0, 1, 0), False, JOINTS,
                       novelty=1.00003).unfamiliar
    assert all(len(track[k]) == 7 for k in ("frames", "time_s", "pose", "novelty"))


def test_both_sinks_take_and_refuse_the_same_runner_up_probabilities(tmp_path):
    """The JSON summary and the MCAP recording check a runner-up's probability by one rule
    (tracker.outputs.geometry.checked_probability): a number in [0, 1]."""
    from tracker.outputs.mcap import McapSink
    alt = _pose(0, 1, 0)
    for k, probability in enumerate((0.0, 0.5, 1, np.float32(0.25), 1.5, -0.1, "0.5", True,
                                     float("nan"), None, 10 ** 400)):
        verdicts = []
        for sink in (JsonSummarySink(tmp_path / f"s{k}.json", video_fps=25.0),
                     McapSink(tmp_path / f"s{k}.mcap")):
            with sink:
                try:
                    sink.write(TrackedPose(0, 0.0, 0, alt, alt, False, JOINTS,
                                           centroid_px=(1.0, 2.0), runner_up=alt,
                                           runner_up_probability=probability))
                    verdicts.append(True)
                except SinkInputError:
                    verdicts.append(False)
        assert verdicts[0] == verdicts[1], probability
        assert verdicts[0] == (k < 4), probability


def test_both_sinks_take_and_refuse_the_same_times(tmp_path):
    """The JSON summary and the MCAP recording check a pose's time by one rule
    (tracker.outputs.geometry.checked_time): a finite number >= 0. (The JSON summary took
    negative times and MCAP failed on a string with a TypeError.)"""
    from tracker.outputs.mcap import McapSink
    pose = _pose(0, 1, 0)
    for k, time_s in enumerate((0.0, 2, np.float32(0.5), 1e6, -0.1, float("nan"), float("inf"),
                                "0.5", True, None, 10 ** 400)):
        verdicts = []
        for sink in (JsonSummarySink(tmp_path / f"t{k}.json", video_fps=25.0),
                     McapSink(tmp_path / f"t{k}.mcap")):
            with sink:
                try:
                    sink.write(TrackedPose(0, time_s, 0, pose, pose, False, JOINTS,
                                           centroid_px=(1.0, 2.0)))
                    verdicts.append(True)
                except SinkInputError:
                    verdicts.append(False)
        assert verdicts[0] == verdicts[1], time_s
        assert verdicts[0] == (k < 4), time_s


def test_the_summary_says_whether_its_poses_are_smoothed(tmp_path):
    with JsonSummarySink(tmp_path / "s.json", 25.0, poses="smoothed") as sink:
        sink.end_frame(0)
    assert json.loads((tmp_path / "s.json").read_text())["poses"] == "smoothed"
    with pytest.raises(SinkInputError, match="poses must be one of"):
        JsonSummarySink(tmp_path / "t.json", 25.0, poses="raw")


def test_abandon_leaves_the_destination_as_it_was(tmp_path):
    """A run that tracked nobody abandons its outputs (tracker.outputs.close_sinks)."""
    path = tmp_path / "summary.json"
    path.write_text('{"an": "earlier run"}')
    sink = JsonSummarySink(path, video_fps=25.0)
    sink.end_frame(0)
    sink.abandon()
    sink.abandon()                                   # idempotent
    assert sink.closed and path.read_text() == '{"an": "earlier run"}'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]
