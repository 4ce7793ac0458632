"""BVH sink: files read back by our reader with the same angles, root and joint positions."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sequences.bvh import read_bvh
from sequences.pose_conversions import motion_to_pose_vectors
from sequences.pose_vector import joint_positions
from sequences.skeleton import CMU_UNIT_M
from tracker.outputs.bvh import BVHSink
from tracker.outputs.geometry import SinkInputError, pose_joints_m
from tracker import TrackedPose

FPS = 25.0


def _poses(n: int, seed: int) -> np.ndarray:
    """Smooth random pose vectors (n, 55): angles within +-50 degrees, unit heading."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n)[:, None]
    vectors = 40.0 * np.sin(2 * math.pi * t * rng.uniform(0.5, 2, 55) + rng.uniform(0, 6, 55))
    heading = np.radians(rng.uniform(-180, 180) + 300.0 * t[:, 0])  # crosses +-180
    vectors[:, 0], vectors[:, 1] = np.cos(heading), np.sin(heading)
    return vectors


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + 180.0) % 360.0 - 180.0


def _write_tracks(directory, frames_by_track: dict[int, np.ndarray], **kwargs):
    """Write each track's poses at its frames with hips walking along X. Returns the inputs."""
    inputs = {}
    with BVHSink(directory, FPS, **kwargs) as sink:
        for track, frames in frames_by_track.items():
            vectors = _poses(len(frames), seed=track)
            hips = np.c_[0.02 * frames, np.full(len(frames), 0.95), -3.0 - 0.01 * frames]
            joints = pose_joints_m(vectors, root_position_m=hips)
            inputs[track] = (frames, vectors, joints)
        for frame in range(max(f.max() for f in frames_by_track.values()) + 1):
            for track, (frames, vectors, joints) in inputs.items():
                (hit,) = np.flatnonzero(frames == frame)[:1].tolist() or [None]
                if hit is not None:
                    sink.write(TrackedPose(frame, frame / FPS, track, vectors[hit] * 1.3, vectors[hit],
                               False, joints[hit]))
    return sink, inputs


def test_written_bvh_reads_back_with_the_same_angles_root_and_joints(tmp_path):
    sink, inputs = _write_tracks(tmp_path, {1: np.arange(0, 40), 4: np.arange(10, 30)})
    assert sorted(sink.paths) == [1, 4]
    for track, (frames, vectors, joints) in inputs.items():
        motion = read_bvh(sink.paths[track], fps=None, drop_tpose=False)
        assert motion.n_frames == len(frames)
        assert motion.fps == pytest.approx(FPS)
        np.testing.assert_allclose(motion.euler_deg, sink.motion(track).euler_deg, atol=1e-6)
        back = motion_to_pose_vectors(motion)
        np.testing.assert_allclose(np.degrees(np.arctan2(back[:, 1], back[:, 0])),
                                   np.degrees(np.arctan2(vectors[:, 1], vectors[:, 0])),
                                   atol=1e-5)
        np.testing.assert_allclose(_wrap(back[:, 2:] - vectors[:, 2:]), 0.0, atol=1e-5)
        np.testing.assert_allclose(motion.root_position * CMU_UNIT_M, joints[:, 0], atol=1e-6)
        positions = joint_positions(back, motion, root_position=motion.root_position)
        np.testing.assert_allclose(positions * CMU_UNIT_M, joints, atol=1e-5)


def test_missed_frames_hold_the_last_pose(tmp_path):
    frames = np.array([5, 6, 9, 10])
    sink, inputs = _write_tracks(tmp_path, {2: frames})
    motion = read_bvh(sink.paths[2], fps=None, drop_tpose=False)
    assert motion.n_frames == 6  # frames 5..10
    euler = motion.euler_deg
    np.testing.assert_array_equal(euler[2], euler[1])  # frames 7, 8 repeat frame 6
    np.testing.assert_array_equal(euler[3], euler[1])
    assert not np.allclose(euler[4], euler[1])
    np.testing.assert_allclose(motion.root_position[3] * CMU_UNIT_M, inputs[2][2][1, 0],
                               atol=1e-6)


def test_short_tracks_are_skipped_and_errors_are_specific(tmp_path):
    sink, _ = _write_tracks(tmp_path, {1: np.arange(10), 3: np.arange(2)}, min_frames=5)
    assert sorted(sink.paths) == [1]
    assert not (tmp_path / "track_3.bvh").exists()
    pose, joints = np.r_[1.0, np.zeros(54)], np.zeros((18, 3))
    sink = BVHSink(tmp_path / "new", FPS)
    sink.write(TrackedPose(3, 0.12, 1, pose, pose, False, joints))
    with pytest.raises(SinkInputError, match="does not follow"):
        sink.write(TrackedPose(3, 0.12, 1, pose, pose, False, joints))
    with pytest.raises(SinkInputError, match="filtered55"):
        sink.write(TrackedPose(4, 0.16, 1, pose, pose[:54], False, joints))
    sink.close()
    sink.close()
    with pytest.raises(SinkInputError, match="closed"):
        sink.write(TrackedPose(5, 0.2, 1, pose, pose, False, joints))
    with pytest.raises(SinkInputError, match="fps"):
        BVHSink(tmp_path, 0.0)


def test_a_cmu_file_can_be_the_template(tmp_path, cmu_bvh_dir):
    source = sorted(cmu_bvh_dir.rglob("*.bvh"))[0]
    template = read_bvh(source, fps=30.0)
    vectors = _poses(12, seed=9)
    with BVHSink(tmp_path, 30.0, template=template) as sink:
        for frame, vector in enumerate(vectors):
            sink.write(TrackedPose(frame, frame / 30.0, 1, vector, vector, False,
                       pose_joints_m(vector[None], template)[0]))
    motion = read_bvh(sink.paths[1], fps=None, drop_tpose=False)
    assert motion.names == template.names
    np.testing.assert_allclose(motion.offsets, template.offsets, atol=1e-6)
    back = motion_to_pose_vectors(motion)
    np.testing.assert_allclose(_wrap(back[:, 2:] - vectors[:, 2:]), 0.0, atol=1e-5)


def test_abandon_writes_no_file_and_frees_the_folder(tmp_path):
    """A run that tracked nobody abandons its BVH output (tracker.outputs.close_sinks)."""
    sink = BVHSink(tmp_path, fps=30.0, prefix="clip")
    sink.abandon()
    sink.abandon()                                   # idempotent
    assert sink.closed and not list(tmp_path.glob("*.bvh"))
    BVHSink(tmp_path, fps=30.0, prefix="clip").close()   # the lock is released
    BVHSink(tmp_path / "new" / "sub", fps=30.0).abandon()
    assert list(tmp_path.iterdir()) == []           # the folders it made are gone again


def test_a_variable_frame_rate_keeps_its_duration(tmp_path):
    """30 fps for 6 s, then 10 fps for 2 s: the BVH (one Frame Time) held one row per video
    frame, so its 200 frames lasted 6.67 s at 30 fps; it now covers the 8 s, each 10 fps pose
    held for three frames."""
    times = np.r_[np.arange(180) / 30.0, 6.0 + np.arange(20) / 10.0]
    vectors = _poses(len(times), seed=5)
    joints = pose_joints_m(vectors, root_position_m=np.c_[times, np.full(len(times), 0.95),
                                                          np.full(len(times), -3.0)])
    with BVHSink(tmp_path, 30.0) as sink:
        for frame, time_s in enumerate(times):
            sink.write(TrackedPose(frame, time_s, 0, vectors[frame], vectors[frame], False,
                                   joints[frame]))
    motion = read_bvh(sink.paths[0], fps=None, drop_tpose=False)
    assert motion.fps == pytest.approx(30.0)
    assert motion.n_frames == 7.9 * 30 + 1       # the last pose at 7.9 s
    expected = sink.motion(0).euler_deg
    np.testing.assert_allclose(motion.euler_deg, expected, atol=1e-6)
    rows = np.r_[np.arange(180), 180 + np.arange(58) // 3]      # video frame of each BVH frame
    np.testing.assert_allclose(motion.root_position * CMU_UNIT_M, joints[rows, 0], atol=1e-6)
    back = motion_to_pose_vectors(motion)
    np.testing.assert_allclose(_wrap(back[:, 2:] - vectors[rows, 2:]), 0.0, atol=1e-5)


def test_a_track_whose_file_name_would_be_too_long_gets_a_shortened_one(tmp_path):
    """A 249-byte prefix: PREFIX_0.bvh is 255 bytes, PREFIX_10.bvh 256 (it had failed after the
    whole run, leaving tracks 10 and up without a file)."""
    vectors = _poses(3, seed=7)
    joints = pose_joints_m(vectors)
    prefix = "a" * 249
    with BVHSink(tmp_path, 30.0, prefix=prefix, min_frames=1) as sink:
        for track in (0, 10):
            for frame in range(3):
                sink.write(TrackedPose(frame, frame / 30, track, vectors[frame], vectors[frame],
                                       False, joints[frame]))
    assert sink.paths[0].name == prefix + "_0.bvh"
    assert len(sink.paths[10].name.encode()) <= 255 and sink.paths[10].name.endswith("_10.bvh")
    assert read_bvh(sink.paths[10], fps=None, drop_tpose=False).n_frames == 3
