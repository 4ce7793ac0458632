"""The frame worker (tracker/frame_worker.py): a second process that finds and describes the
people, with the same poses as one process, its errors passed on, and nothing left running."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from regressor.pose_model import load_pose_model
from sequences.video import Actor, write_video
from tests.test_track_cli import _assert_one_line_error, _track, _walker
from tests.test_track_safety import cut_off_avi
from tracker import PoseRecorder, PoseTracker, TrackerSettings, track_video
from tracker.frame_worker import FrameWorker, can_fork
from tracker.run import _prime
from tracker.video.decode import VideoError, VideoSource, open_video

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.skipif(not can_fork(), reason="the frame worker needs fork")


@pytest.fixture(scope="module")
def walk(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("walk") / "walk.mp4"
    write_video(path, [Actor(_walker(45))], size=(240, 320), noise_sigma=2.0, seed=5)
    return path


@pytest.fixture(scope="module")
def model():
    return load_pose_model()


def _poses(video: Path, model, workers: int) -> tuple[np.ndarray, object]:
    source = open_video(video)
    recorder = PoseRecorder()
    tracker = PoseTracker(model, source.fps, TrackerSettings(keep_history=False))
    run = track_video(source, tracker, [recorder], workers=workers)
    rows = [np.concatenate([p.raw, p.filtered, p.joints_m.ravel(), [p.frame_index, p.track_id,
                                                                     p.ambiguous]])
            for p in recorder.poses]
    return np.array(rows), run


@pytest.mark.slow
def test_two_processes_give_exactly_the_poses_of_one(walk, model):
    # With one BLAS thread, as track runs (tracker.cli.run) and its worker: with numpy 1.26's
    # OpenBLAS (the [segment] extra's) several threads sum in another order (1e-13 apart).
    from threadpoolctl import threadpool_limits
    with threadpool_limits(1):
        one, run_one = _poses(walk, model, workers=1)
        two, run_two = _poses(walk, model, workers=2)
    assert len(one) >= 30                                  # the walker is tracked
    np.testing.assert_array_equal(two, one)
    assert run_two.frames == run_one.frames == 45
    # the worker's stages are reported with the main process's, and the wait for it
    stages = run_two.tracker.stage_seconds
    for stage in ("background", "decode", "silhouettes", "descriptor", "regression", "filter",
                  "waiting"):          # background: primed here, the worker starts from it
        assert stages[stage] > 0, stage


@pytest.mark.slow
def test_frames_tracked_in_batches_give_the_poses_of_frames_tracked_one_by_one(walk, model):
    """PoseTracker.track_frames (what track_video runs, 8 frames at a time) against
    one frame at a time: the same tracks, front/back decisions and skeletons; poses
    equal to the batched sums' rounding."""
    source = open_video(walk)
    trackers = [PoseTracker(model, source.fps, TrackerSettings()) for _ in range(2)]
    for tracker in trackers:
        _prime(source, tracker, None)
    frames = [(index, time_s, trackers[0].find_people(frame)) for index, time_s, frame
              in open_video(walk)]
    one_by_one = [trackers[0].track_frames([(i, t, people, None)])[0][0]
                  for i, t, people in frames]
    batched = []
    for start in range(0, len(frames), 8):
        chunk = [(i, t, people, None) for i, t, people in frames[start:start + 8]]
        for poses, people in trackers[1].track_frames(chunk):
            batched.append(poses)
            assert sorted(people) == [p.track_id for p in poses]
    assert [len(p) for p in batched] == [len(p) for p in one_by_one]
    pairs = [(a, b) for x, y in zip(one_by_one, batched) for a, b in zip(x, y)]
    assert len(pairs) >= 30
    for a, b in pairs:
        assert (a.frame_index, a.track_id, a.ambiguous) == (b.frame_index, b.track_id,
                                                           b.ambiguous)
        np.testing.assert_allclose(b.raw, a.raw, atol=1e-3)
        np.testing.assert_allclose(b.filtered, a.filtered, atol=1e-3)
        np.testing.assert_allclose(b.joints_m, a.joints_m, atol=1e-5)
        assert b.joints_m.shape == (18, 3)


@pytest.mark.slow
def test_one_process_again_after_a_worker_and_a_worker_after_one(walk, model):
    """OpenCV's thread pool, used by one run, must not hang the next run's forked worker."""
    first, _ = _poses(walk, model, workers=2)
    _poses(walk, model, workers=1)
    again, _ = _poses(walk, model, workers=2)
    np.testing.assert_array_equal(again, first)


class _BrokenAtFrame(VideoSource):
    """A video that fails to decode at frame ``bad`` (as a damaged file would)."""

    bad = 10

    def __iter__(self):
        for frame in super().__iter__():
            if frame[0] == self.bad:
                raise VideoError(f"{self.path.name}: frame {self.bad} cannot be decoded")
            yield frame


@pytest.mark.slow
def test_an_error_in_the_worker_is_raised_in_the_main_process_as_it_is(walk, model):
    for workers in (2, 1):                   # one process: the same, though frames go in 8s
        source = open_video(walk)
        source.__class__ = _BrokenAtFrame
        recorder = PoseRecorder()
        tracker = PoseTracker(model, source.fps, TrackerSettings(keep_history=False))
        with pytest.raises(VideoError, match="frame 10 cannot be decoded"):
            track_video(source, tracker, [recorder], workers=workers)
        # the frames before it were tracked and handed to the sinks
        assert max(p.frame_index for p in recorder.poses) == 9, workers


def test_close_ends_a_worker_still_running(walk, model):
    source = open_video(walk)
    tracker = PoseTracker(model, source.fps, TrackerSettings(keep_history=False))
    _prime(source, tracker, None)
    worker = FrameWorker(source, tracker, batch=1)
    next(worker.chunks())                    # it is working, and blocks once the pipe is full
    worker.close()
    assert not worker._process.is_alive()


_ORPHAN_SCRIPT = """
import sys, time
from regressor.pose_model import load_pose_model
from tracker import PoseTracker, TrackerSettings
from tracker.frame_worker import FrameWorker
from tracker.run import _prime
from tracker.video.decode import open_video
source = open_video(sys.argv[1])
tracker = PoseTracker(load_pose_model(), source.fps, TrackerSettings())
_prime(source, tracker, None)
worker = FrameWorker(source, tracker, batch=1)
print(worker._process.pid, flush=True)
time.sleep(60)                               # never reads: the worker fills the pipe and waits
"""


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"      # a zombie has ended
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
@pytest.mark.slow
def test_a_worker_whose_main_process_is_killed_ends_too(walk):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    main = subprocess.Popen([sys.executable, "-c", _ORPHAN_SCRIPT, str(walk)], env=env,
                            stdout=subprocess.PIPE, text=True)
    try:
        worker_pid = int(main.stdout.readline())
        time.sleep(1.0)                      # the 45 frames take ~0.5 s: it is blocked
        assert _alive(worker_pid)
        main.send_signal(signal.SIGKILL)     # no clean-up of any kind in the main process
        main.wait(timeout=10)
        deadline = time.monotonic() + 10
        while _alive(worker_pid) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not _alive(worker_pid), "the worker outlived its main process"
    finally:
        main.kill()


def test_workers_other_than_one_or_two_are_refused(walk, tmp_path):
    with pytest.raises(ValueError, match="workers=3"):
        track_video(walk, workers=3)
    _assert_one_line_error(_track(walk, "--workers", "3", "--json", tmp_path / "s.json"),
                           "--workers")
    assert not (tmp_path / "s.json").exists()


@pytest.mark.slow
def test_track_with_one_or_two_workers_writes_the_same_json(walk, tmp_path):
    import json
    for workers in (1, 2):
        result = _track(walk, "--workers", str(workers), "--json", tmp_path / f"{workers}.json",
                        "--quiet")
        assert result.returncode == 0, result.stderr
    one, two = (json.loads((tmp_path / f"{w}.json").read_text()) for w in (1, 2))
    for summary in (one, two):
        for timing in ("fps", "wall_time_s"):
            summary.pop(timing)
    assert one == two


def test_the_workers_warnings_are_issued_in_the_main_process(tmp_path):
    """A video cut short warns in the worker, which reads it; the user must still see it."""
    from tracker.video.stream_report import VideoTruncatedWarning
    source = open_video(cut_off_avi(tmp_path))
    with pytest.warns(VideoTruncatedWarning, match="decoding stopped"):
        run = track_video(source, workers=2)
    assert source.truncated and 0 < source.frames_read == run.frames < 40


def test_the_worker_decodes_on_one_thread_and_one_process_as_opencv_chooses(walk, model,
                                                                            tmp_path,
                                                                            monkeypatch):
    """The main process's core is busy while the worker runs: a second decoding thread there
    only contends (FFmpeg's decoding is bit-exact whatever its threads)."""
    import tracker.video.decode as decode
    log = tmp_path / "threads.txt"
    real = decode._open_capture

    def logged(path, threads=None):
        with open(log, "a") as f:
            f.write(f"{os.getpid()} {threads}\n")
        return real(path, threads)
    monkeypatch.setattr(decode, "_open_capture", logged)
    source = open_video(walk)
    tracker = PoseTracker(model, source.fps, TrackerSettings(keep_history=False))
    _prime(source, tracker, None)
    log.unlink()
    worker = FrameWorker(source, tracker)
    try:
        assert sum(len(chunk) for chunk in worker.chunks()) == 45
    finally:
        worker.close()
    assert log.read_text().split() == [str(worker._process.pid), "1"]
    assert source.decoder_threads is None                   # the main process's copy
    one = [frame.image for frame in source]
    source.decoder_threads = 1
    assert all(np.array_equal(a, b.image) for a, b in zip(one, source, strict=True))


def test_a_ctrl_c_as_the_worker_starts_prints_nothing_and_stops_nothing(walk, model, capfd,
                                                                        monkeypatch, tmp_path):
    """A Ctrl-C reaches every process of the terminal's group, the worker's too before it has
    set its own handlers (here a long start): it waits for them, and they ignore it."""
    import tracker.frame_worker as frame_worker
    real, started = frame_worker._work, tmp_path / "started"

    def slow_start(*args):
        started.touch()
        time.sleep(0.5)
        real(*args)
    monkeypatch.setattr(frame_worker, "_work", slow_start)
    source = open_video(walk)
    tracker = PoseTracker(model, source.fps, TrackerSettings(keep_history=False))
    _prime(source, tracker, None)
    worker = FrameWorker(source, tracker)
    try:
        while not started.exists():
            time.sleep(0.001)
        os.kill(worker._process.pid, signal.SIGINT)
        assert sum(len(chunk) for chunk in worker.chunks()) == 45
    finally:
        worker.close()
    assert "Traceback" not in capfd.readouterr().err
