"""The smoothed outputs' root path: smoothed over the track, the bodies drawn at it."""
from __future__ import annotations

import numpy as np
import pytest

from regressor.pose_model import load_pose_model
from sequences.video import Actor, write_video
from tests.test_fixed_lag import _walk
from tracker.root_path import ROOT_SMOOTHING_S, smoothed_roots
from tracker.sinks.geometry import pose_joints_m


def test_a_steady_path_is_kept_and_its_jitter_removed():
    t = np.arange(120) / 30.0
    line = np.column_stack([1.2 * t, np.full_like(t, 0.95), -5.0 + 0.3 * t])     # m
    noisy = line + np.random.default_rng(0).normal(0.0, 0.04, line.shape)
    smooth = smoothed_roots(noisy, 30.0)
    inner = slice(15, -15)                         # beyond the Gaussian's reach of the ends
    np.testing.assert_allclose(smoothed_roots(line, 30.0)[inner], line[inner], atol=1e-9)
    assert (np.abs(smooth - line)[inner].mean() < 0.5 * np.abs(noisy - line)[inner].mean())
    np.testing.assert_array_equal(smoothed_roots(noisy, 30.0, sigma_s=0.0), noisy)
    with pytest.raises(ValueError, match="T, 3"):
        smoothed_roots(noisy[:, :2], 30.0)
    with pytest.raises(ValueError, match="fps"):
        smoothed_roots(noisy, 0.0)


def test_the_smoothed_outputs_draw_their_bodies_on_the_smoothed_root_path(tmp_path):
    from tracker import PoseTracker, track_video
    from tracker.pipeline import TrackerSettings
    from tracker.sinks import PoseRecorder
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
    np.testing.assert_allclose(roots, smoothed_roots(raw_roots, 30.0, ROOT_SMOOTHING_S))
    np.testing.assert_allclose([p.joints_m for p in poses],
                               pose_joints_m(np.array([p.filtered for p in poses]),
                                             root_position_m=roots))
    # The walker goes at a steady speed: the smoothed path wobbles far less.
    wobble = [np.linalg.norm(np.diff(r[:, [0, 2]], 2, axis=0), axis=1).mean()
              for r in (raw_roots, roots)]
    assert wobble[1] < 0.3 * wobble[0]
    # --lag 0.5 draws at the same root path: its windows reach past the Gaussian's 0.4 s.
    from tracker.fixed_lag import replay
    lagged = [p for p in replay(tracker, streamed.frames(), 0.5) if p.track_id == track_id]
    np.testing.assert_allclose([p.joints_m[0] for p in lagged], roots, atol=1e-9)
    assert not np.allclose([p.joints_m[0] for p in replay(tracker, streamed.frames(), 0.1)
                            if p.track_id == track_id], raw_roots)
