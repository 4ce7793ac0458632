"""The smoothed outputs' root path: smoothed over the track, the bodies drawn at it."""
from __future__ import annotations

import numpy as np
import pytest

from regressor.pose_model import load_pose_model
from sequences.video import Actor, write_video
from tests.test_fixed_lag import _walk
from tracker.tracks.root_path import ROOT_SMOOTHING_S, RootHistory, smoothed_roots
from tracker.outputs.geometry import pose_joints_m


def test_a_steady_path_is_kept_and_its_jitter_removed():
    t = np.arange(120) / 30.0
    line = np.column_stack([1.2 * t, np.full_like(t, 0.95), -5.0 + 0.3 * t])     # m
    noisy = line + np.random.default_rng(0).normal(0.0, 0.04, line.shape)
    smooth = smoothed_roots(noisy, 30.0)
    inner = slice(15, -15)                         # beyond the Gaussian's reach of the ends
    np.testing.assert_allclose(smoothed_roots(line, 30.0), line, atol=1e-9)   # ends too
    assert (np.abs(smooth - line)[inner].mean() < 0.5 * np.abs(noisy - line)[inner].mean())
    np.testing.assert_array_equal(smoothed_roots(noisy, 30.0, sigma_s=0.0), noisy)
    with pytest.raises(ValueError, match="T, 3"):
        smoothed_roots(noisy[:, :2], 30.0)
    with pytest.raises(ValueError, match="fps"):
        smoothed_roots(noisy, 0.0)
    with pytest.raises(ValueError, match="increasing"):
        smoothed_roots(noisy, 30.0, frames=np.zeros(len(noisy)))


def test_a_gap_in_the_track_is_smoothed_over_time_not_over_poses():
    frames = np.r_[0:60, 72:120]                       # 12 frames missed
    t = frames / 30.0
    line = np.column_stack([1.4 * t, np.full_like(t, 0.95), -5.0 + 0.0 * t])   # m
    by_time = smoothed_roots(line, 30.0, frames=frames)
    by_pose = smoothed_roots(line, 30.0)
    assert np.abs(by_time - line).max() < 1e-9          # a straight path stays, gap and ends
    assert np.abs(by_pose - line).max() > 0.1           # the gap's 0.56 m smeared


def test_the_root_history_gives_copies_of_its_slices():
    history = RootHistory()
    for i in range(10):
        history.add(4, 2 * i, [i, 1.0, -i])
    roots, frames = history.get(4, 3, 6)
    np.testing.assert_array_equal(roots, [[3, 1, -3], [4, 1, -4], [5, 1, -5]])
    np.testing.assert_array_equal(frames, [6, 8, 10])
    roots[:] = 0
    history.add(4, 20, [10, 1.0, -10])                 # still growable: nothing holds it
    assert history.get(4)[0].shape == (11, 3) and history.get(4, 3, 6)[0][0, 0] == 3


@pytest.mark.slow
def test_the_smoothed_outputs_draw_their_bodies_on_the_smoothed_root_path(tmp_path):
    from tracker import PoseTracker, track_video
    from tracker.pipeline import TrackerSettings
    from tracker.outputs import PoseRecorder
    video = tmp_path / "walk.mp4"
    write_video(video, [Actor(_walk())], size=(240, 320), noise_sigma=2.0, seed=5)
    streamed, smoothed = PoseRecorder(), PoseRecorder()
    tracker = PoseTracker(load_pose_model(), 30.0,
                          TrackerSettings(max_people=1, keep_history=True))
    track_video(video, tracker, [streamed], smoothed_sinks=[smoothed])
    track_id = streamed.poses[0].track_id
    raw_roots = np.array([p.joints_m[0] for p in streamed.by_track()[track_id]])
    poses = smoothed.by_track()[track_id]
    roots = np.array([p.joints_m[0] for p in poses])
    frames = np.array([p.frame_index for p in poses])
    np.testing.assert_allclose(roots, smoothed_roots(raw_roots, 30.0, ROOT_SMOOTHING_S, frames))
    np.testing.assert_allclose([p.joints_m for p in poses],
                               pose_joints_m(np.array([p.filtered for p in poses]),
                                             root_position_m=roots))
    # The walker goes at a steady speed: the smoothed path wobbles far less.
    wobble = [np.linalg.norm(np.diff(r[:, [0, 2]], 2, axis=0), axis=1).mean()
              for r in (raw_roots, roots)]
    assert wobble[1] < 0.3 * wobble[0]
    # --lag 1 draws at the same root path: its windows reach past the weights' 0.8 s; at 0.5 s
    # the line is fitted to what the window has, close to it.
    from tracker.tracks.fixed_lag import replay
    lagged = [p for p in replay(tracker, streamed.frames(), 1.0) if p.track_id == track_id]
    np.testing.assert_allclose([p.joints_m[0] for p in lagged], roots, atol=1e-9)
    lagged = [p for p in replay(tracker, streamed.frames(), 0.5) if p.track_id == track_id]
    assert np.abs(np.array([p.joints_m[0] for p in lagged]) - roots).max() < 0.025
    assert not np.allclose([p.joints_m[0] for p in replay(tracker, streamed.frames(), 0.1)
                            if p.track_id == track_id], raw_roots)
    # A run with a lag records its streamed (lagged) poses, drawn at the lag's smoothed roots:
    # its smoothed outputs still smooth the tracker's own roots, once.
    lag_smoothed = PoseRecorder()
    track_video(video, PoseTracker(load_pose_model(), 30.0,
                                   TrackerSettings(max_people=1, keep_history=True)),
                [PoseRecorder()], smoothed_sinks=[lag_smoothed], lag_s=0.5)
    np.testing.assert_allclose([p.joints_m for p in lag_smoothed.poses],
                               [p.joints_m for p in smoothed.poses], atol=1e-9)
