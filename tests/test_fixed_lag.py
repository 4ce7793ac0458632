"""Fixed-lag smoothing (tracker.tracks.fixed_lag): which frames go out when, smoothed over which
window; and on a rendered walk through track_video, that it follows the body better than the
filter and, with a lag longer than the video, gives exactly the whole-track smoothing."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from regressor.pose_model import load_pose_model
from sequences.video import Actor, load_truth, write_video
from tests.synthetic import gait_walk
from tracker.tracks.fixed_lag import MAX_LAG_S, FixedLagSmoother
from tracker.pipeline import TrackedPose
from tracker.outputs.geometry import pose_joints_m


class _Tracker:
    """The part of a PoseTracker the smoother uses. smoothed_track(track, start, stop) gives
    poses whose entries 2, 3, 4 are (start, stop, pose number) and records each call."""

    def __init__(self, fps=30.0, keep_history=True):
        self.fps = fps
        self.settings = SimpleNamespace(keep_history=keep_history)
        self.calls = []

    def smoothed_track(self, track_id, start=0, stop=None):
        self.calls.append((track_id, start, stop))
        out = np.zeros((stop - start, 55))
        out[:, 0] = 1.0                                  # heading 0: cos 1, sin 0
        out[:, 2], out[:, 3] = start, stop
        out[:, 4] = np.arange(start, stop)
        out[:, 5] = track_id
        return out

    def smoothed_root_path(self, track_id, start=0, stop=None):
        return np.tile([0.0, 1.0, 3.0], (stop - start, 1))   # where _pose puts every root


def _pose(frame, track_id, root=(0.0, 1.0, 3.0)):
    vector = np.zeros(55)
    vector[0] = 1.0
    joints = pose_joints_m(vector[None], root_position_m=np.array([root]))[0]
    return TrackedPose(frame, frame / 30.0, track_id, vector.copy(), vector.copy(), False,
                       joints)


def _frame(index, track_ids):
    return (index, index / 30.0, None, [_pose(index, t) for t in track_ids], {})


def _run(smoother, frames):
    """Push every frame, then flush; returns [(push number, released frame)]."""
    out = []
    for number, frame in enumerate(frames):
        smoother.push(frame)
        while smoother.ready:
            out.append((number, smoother.ready.popleft()))
    smoother.flush()
    while smoother.ready:
        out.append((len(frames), smoother.ready.popleft()))
    return out


def test_frames_go_out_in_order_once_each_one_per_push_twice_lag_less_one_late():
    tracker = _Tracker()
    smoother = FixedLagSmoother(tracker, lag_frames=4, margin_frames=3)
    out = _run(smoother, [_frame(i, [7]) for i in range(23)])
    assert [f[0] for _, f in out] == list(range(23))
    pushed = [number for number, _ in out]
    assert pushed[:16] == list(range(7, 23))            # one per push once 7 are held
    assert pushed[16:] == [23] * 7                      # the rest at the flush
    assert smoother.waiting == 0 and not smoother.ready
    # Blocks of 4, each smoothed once from 3 frames before it to the newest pose pushed.
    assert tracker.calls[:3] == [(7, 0, 8), (7, 1, 12), (7, 5, 16)]
    for _, (index, _, _, (pose,), _) in out:
        start, stop, number = pose.filtered[2:5]
        # The flush's block holds up to 2 lag - 1 frames.
        assert number == index and start <= index < stop and index - start <= 3 + 7


def test_each_pose_gets_its_own_tracks_smoothing_and_joints_drawn_from_it_at_its_root():
    tracker = _Tracker()
    smoother = FixedLagSmoother(tracker, lag_frames=2, margin_frames=0)
    tracks = [[1], [1, 2], [2], [], [2], [1, 2], [1]]       # 1 leaves for two frames
    out = _run(smoother, [_frame(i, t) for i, t in enumerate(tracks)])
    assert [[p.track_id for p in f[3]] for _, f in out] == tracks
    numbers = {1: 0, 2: 0}
    for _, (_, _, _, poses, _) in out:
        for pose in poses:
            assert pose.filtered[5] == pose.track_id
            assert pose.filtered[4] == numbers[pose.track_id]   # the track's own pose number
            numbers[pose.track_id] += 1
            expected = pose_joints_m(pose.filtered[None],
                                     root_position_m=np.array([[0.0, 1.0, 3.0]]))[0]
            np.testing.assert_allclose(pose.joints_m, expected)
            assert not np.allclose(pose.filtered, pose.raw)        # raw stays as tracked


def test_a_lag_longer_than_the_video_smooths_every_track_whole_at_the_end():
    tracker = _Tracker()
    smoother = FixedLagSmoother(tracker, lag_frames=50, margin_frames=5)
    out = _run(smoother, [_frame(i, [3]) for i in range(20)])
    assert all(pushed == 20 for pushed, _ in out)        # all at the flush
    assert tracker.calls == [(3, 0, 20)]


def test_a_stop_inside_the_smoother_loses_no_frame():
    """A Ctrl-C (KeyboardInterrupt) while a block is smoothed leaves the block held back; the
    flush that follows gives every frame, in order."""
    class Stopping(_Tracker):
        def smoothed_track(self, track_id, start=0, stop=None):
            if len(self.calls) == 1:
                self.calls.append("stopped")
                raise KeyboardInterrupt
            return super().smoothed_track(track_id, start, stop)

    smoother = FixedLagSmoother(Stopping(), lag_frames=3, margin_frames=0)
    frames, out = [_frame(i, [1]) for i in range(20)], []
    with pytest.raises(KeyboardInterrupt):
        for frame in frames:
            smoother.push(frame)
            while smoother.ready:
                out.append(smoother.ready.popleft())
    # Stopped at frame 8's push, the second block (frames 3-5) in the smoother: still held.
    assert [f[0] for f in out] == [0, 1, 2] and smoother.waiting == 6
    smoother.flush()
    out += list(smoother.ready)
    assert [f[0] for f in out] == list(range(9))


def test_refusals():
    with pytest.raises(ValueError, match="keep_history"):
        FixedLagSmoother(_Tracker(keep_history=False), 4)
    for lag in (0, -1, 2.5):
        with pytest.raises(ValueError, match="lag_frames"):
            FixedLagSmoother(_Tracker(), lag)
    with pytest.raises(ValueError, match="margin_frames"):
        FixedLagSmoother(_Tracker(), 4, margin_frames=-1)
    for seconds in (0.0, -0.5, float("nan"), float("inf"), MAX_LAG_S + 1):
        with pytest.raises(ValueError, match="lag"):
            FixedLagSmoother.from_seconds(_Tracker(), seconds)
    assert FixedLagSmoother.from_seconds(_Tracker(fps=30.0), 0.5).lag == 15
    assert FixedLagSmoother.from_seconds(_Tracker(fps=30.0), 0.001).lag == 1
    assert FixedLagSmoother.from_seconds(_Tracker(fps=120.0), 0.5).margin == 120


def test_the_cli_limit_is_the_smoothers():
    from tracker import cli
    assert cli.MAX_LAG_S == MAX_LAG_S


# ------------------------------------------------------------------ on a rendered walk


def _walk(T=90):
    """A walk along +X, the legs and arms swinging at 1 Hz and the knees bending (unlike
    test_track_cli's walker, whose knees stay straight)."""
    return gait_walk(T, 90.0)


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    path = tmp_path_factory.mktemp("lag") / "walk.mp4"
    write_video(path, [Actor(_walk())], size=(240, 320), noise_sigma=2.0, seed=5)
    return path


def _tracked(video, model, lag_s, workers=1):
    from tracker import PoseTracker, track_video
    from tracker.pipeline import TrackerSettings
    from tracker.outputs import PoseRecorder
    tracker = PoseTracker(model, 30.0, TrackerSettings(max_people=1, keep_history=True))
    recorder = PoseRecorder()
    run = track_video(video, tracker, [recorder], workers=workers, lag_s=lag_s)
    return tracker, recorder.poses, run


@pytest.mark.slow
def test_through_track_video_the_lagged_poses_follow_the_walk_better(walk):
    model = load_pose_model()
    truth = load_truth(walk)["pose"][:, 0]
    _, filtered, _ = _tracked(walk, model, 0.0)
    tracker, lagged, run = _tracked(walk, model, 0.5)
    assert [p.frame_index for p in lagged] == [p.frame_index for p in filtered]
    assert run.frames == len(load_truth(walk)["pose"])
    assert tracker.stage_seconds["fixed-lag smoothing"] > 0
    index = np.array([p.frame_index for p in lagged])

    def error(poses):
        diff = np.array([p.filtered for p in poses])[:, 2:] - truth[index, 2:]
        return np.abs((diff + 180) % 360 - 180).mean()

    def jitter(poses):
        p = np.array([q.filtered for q in poses])[:, 2:]
        return np.abs((np.diff(p, 2, axis=0) + 180) % 360 - 180).mean()
    assert error(lagged) < error(filtered)
    assert jitter(lagged) < 0.8 * jitter(filtered)
    # The raw poses are the tracker's, untouched.
    np.testing.assert_array_equal([p.raw for p in lagged], [p.raw for p in filtered])


@pytest.mark.slow
def test_a_lag_longer_than_the_video_is_the_whole_track_smoothed(walk):
    tracker, poses, _ = _tracked(walk, load_pose_model(), MAX_LAG_S)
    whole = tracker.smoothed_track(poses[0].track_id)
    np.testing.assert_allclose([p.filtered for p in poses], whole, atol=1e-9)


@pytest.mark.slow
def test_one_or_two_processes_give_the_same_lagged_poses(walk):
    model = load_pose_model()
    _, one, _ = _tracked(walk, model, 0.2, workers=1)
    _, two, _ = _tracked(walk, model, 0.2, workers=2)
    np.testing.assert_allclose([p.filtered for p in one], [p.filtered for p in two], atol=1e-4)


@pytest.mark.slow
def test_a_ctrl_c_still_writes_the_frames_held_back(walk):
    """A stop between frames: the frames the smoother holds back go out too (smoothed over
    what was tracked), in order, each once; a sink fed at the end is told they are the
    fixed-lag smoothed poses."""
    import os
    import signal

    from tracker import PoseTracker, track_video
    from tracker.pipeline import TrackerSettings
    from tracker.outputs import PoseRecorder

    class CtrlC(PoseRecorder):
        def write(self, pose):
            if len(self.poses) == 30:
                os.kill(os.getpid(), signal.SIGINT)       # acts after this frame's writes
            super().write(pose)

    class Told(PoseRecorder):
        pose_kind = "smoothed"

    sink, told = CtrlC(), Told()
    tracker = PoseTracker(load_pose_model(), 30.0, TrackerSettings(max_people=1,
                                                                   keep_history=True))
    run = track_video(walk, tracker, [sink], smoothed_sinks=[told], lag_s=0.3)   # 9 frames
    assert run.interrupted and not run.smoothed
    frames = [p.frame_index for p in sink.poses]
    assert frames == list(range(frames[0], frames[-1] + 1))    # none lost, none twice
    assert len(frames) >= 31 + 9
    assert len(frames) < len(load_truth(walk)["pose"])
    assert told.pose_kind == "fixed-lag smoothed" and len(told.poses) == len(frames)


@pytest.mark.slow
def test_a_replay_of_a_run_without_lag_gives_the_lagged_runs_poses(walk):
    """tracker.tracks.fixed_lag.replay (what the evaluation scripts use: one run gives the filtered
    and the lagged poses) equals a run with the lag, pose for pose."""
    from lab.evaluation import track_longest
    from tracker.pipeline import TrackerSettings
    model = load_pose_model()
    tracked = track_longest(walk, model, TrackerSettings(), lag_s=0.5)
    _, live, _ = _tracked(walk, model, 0.5, workers=2)
    np.testing.assert_array_equal(tracked[0], [p.frame_index for p in live])
    np.testing.assert_allclose(tracked[8], [p.filtered for p in live], atol=1e-9)
    assert not np.allclose(tracked[8], tracked[2])          # not the filtered poses


def test_video_frames_held_back_are_kept_small_with_their_people():
    from tracker.tracks.fixed_lag import HELD_FRAME_WIDTH_PX
    from tracker.video.silhouettes import PersonMask
    x = np.linspace(0, 255, 1920)[None, :, None]
    image = np.broadcast_to(x, (1080, 1920, 3)).astype(np.uint8)       # a smooth ramp
    mask = np.zeros((600, 300), bool)
    mask[100:500, 50:250] = True
    person = PersonMask(mask, (900, 300, 300, 600), (1050.0, 600.0), int(mask.sum()))
    small = np.zeros((120, 160, 3), np.uint8)
    small_person = PersonMask(np.ones((40, 20), bool), (10, 10, 20, 40), (20.0, 30.0), 800)
    frames = [(i, i / 30, image if i % 2 else small, [_pose(i, 1)],
               {1: person if i % 2 else small_person}) for i in range(8)]
    smoother = FixedLagSmoother(_Tracker(), lag_frames=3, margin_frames=0)
    smoother.push(frames[0])
    smoother.push(frames[1])
    assert [w.frame[2].shape for w in smoother._waiting] == [(120, 160, 3),
                                                            (360, HELD_FRAME_WIDTH_PX, 3)]
    out = _run(smoother, frames[2:])
    assert [f[0] for _, f in out] == list(range(8))
    for _, (index, _, given, _, people) in out:
        if index % 2:
            assert given.shape == (360, HELD_FRAME_WIDTH_PX, 3)
            assert np.abs(given[:, ::64].astype(int) - image[::3, ::192][:360]).mean() < 2.0
            shrunk = people[1]
            assert shrunk.bbox == (300, 100, 100, 200) and shrunk.mask.shape == (200, 100)
            assert shrunk.centroid == pytest.approx((350.0, 200.0))
            assert shrunk.area == int(shrunk.mask.sum()) == pytest.approx(80000 / 9, rel=0.02)
        else:
            assert given is small and people[1] is small_person    # small frames as they are




@pytest.mark.slow
def test_after_a_stop_the_frames_held_back_go_to_the_files_not_the_live_view(walk):
    """A Ctrl-C with a lag: the frames held back are written to the files, but not shown:
    the live view would play them at the video's speed, to nobody, while further stops are
    held back (a review measured a 7 s exit at --lag 5)."""
    from tracker import PoseTracker, track_video
    from tracker.pipeline import TrackerSettings
    from tracker.outputs import PoseRecorder

    class Watching(PoseRecorder):
        def __init__(self):
            super().__init__()
            self.shown = []

        def write_frame(self, frame_index, time_s, frame, people):
            self.shown.append(frame_index)

        def discard(self):              # what it holds back is dropped before it closes
            self.shown.append("discarded")

        def close(self):
            self.shown.append("closed")
            super().close()

    class StopAt(PoseRecorder):
        def end_frame(self, frame_index):
            super().end_frame(frame_index)
            if frame_index == 10:
                raise KeyboardInterrupt

    watching, files = Watching(), PoseRecorder()
    tracker = PoseTracker(load_pose_model(), 30.0, TrackerSettings(max_people=1,
                                                                   keep_history=True))
    run = track_video(walk, tracker, [watching, files, StopAt()], lag_s=0.3)   # 9 frames
    assert run.interrupted
    assert watching.shown == list(range(11)) + ["discarded", "closed"]
    written = [index for index, _ in files.frames()]
    assert written == list(range(2 * 9 - 1 + 11))       # all given to the smoother
    assert [index for index, _ in watching.frames()] == list(range(11))
