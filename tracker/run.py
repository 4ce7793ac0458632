"""THE tracking loop (``track``'s, the evaluation's, the benchmark's): open the video, learn
its background, track every frame, feed the sinks (from Python: README, "From Python")."""
from __future__ import annotations

import contextlib
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from regressor.errors import SilhouettePoseError
from tracker import STOP_SIGNALS
from tracker.tracks import streamed_kind
from tracker.tracks.root_path import drawn_at
from tracker.frame_worker import BATCH_FRAMES, FrameWorker, can_fork, described_chunks
from tracker.pipeline import PoseTracker, timed
from tracker.video.silhouettes import median_background
from tracker.outputs import PoseRecorder, Sink, close_sinks
from tracker.video.decode import VideoSource, open_video

if TYPE_CHECKING:
    from tracker.tracks.fixed_lag import FixedLagSmoother


class OutputError(SilhouettePoseError, RuntimeError):
    """Some outputs could not be finished; the message lists them."""


class BackgroundMismatchError(SilhouettePoseError, ValueError):
    """A clean plate (track --background) that is not of the video's scene."""


@dataclass
class WrittenPoses:
    """One track's poses handed to the outputs: how many, and how many were unfamiliar."""

    poses: int = 0
    unfamiliar: int = 0


@dataclass
class TrackRun:
    """What a run did: frames handed to the outputs, wall time (s), whether a stop interrupted
    it, the tracker, the poses the outputs hold by track, whether smoothed tracks were fed."""

    frames: int
    elapsed_s: float
    interrupted: bool
    tracker: PoseTracker
    written: dict[int, WrittenPoses] = field(default_factory=dict)
    smoothed: bool = False

    @property
    def fps(self) -> float:
        """Frames processed per second of wall time."""
        return self.frames / self.elapsed_s if self.elapsed_s > 0 else 0.0

    def stop_if_interrupted(self) -> TrackRun:
        """Raise KeyboardInterrupt if a Ctrl-C ended the run early, else return it."""
        if self.interrupted:
            raise KeyboardInterrupt
        return self


def track_video(source: VideoSource | str | Path, tracker: PoseTracker | None = None,
                sinks: Sequence[Sink] = (), progress=None,
                smoothed_sinks: Sequence[Sink] = (), background: np.ndarray | None = None,
                workers: int = 1, lag_s: float = 0.0, write_empty: bool = True) -> TrackRun:
    """Track every frame of ``source`` (an opened video or a path) into ``sinks``: each pose,
    end_frame() after each frame, and to those with write_frame the frame (BGR uint8, read-only)
    and its people by track id. tracker: None: the shipped model. progress:
    update(people_in_view), close(). smoothed_sinks: fed each track RTS-smoothed at the end
    (after a Ctrl-C as streamed). A failing sink is fed no more; all close on return, also on
    Ctrl-C, stop signals held; OutputError names the failures. background: a clean plate (BGR
    uint8, the video's size), else learned. workers: 2 describes people in a forked process
    (same results). lag_s: each frame about 2 lag_s late, smoothed (tracks.fixed_lag).
    write_empty: False abandons the sinks if no pose was written."""
    if workers not in (1, 2):
        raise ValueError(f"workers={workers} must be 1 or 2")
    if not isinstance(source, VideoSource):
        source = open_video(source)
    if tracker is None:
        from regressor.pose_model import load_pose_model
        tracker = PoseTracker(load_pose_model(), source.fps)
    if smoothed_sinks and not tracker.settings.keep_history:
        raise ValueError("smoothed_sinks need a tracker with TrackerSettings(keep_history=True)")
    run = _Run(tracker, sinks, smoothed_sinks, progress, lag_s)
    started, interrupted = time.perf_counter(), False
    try:
        _prime(source, tracker, background, two_processes=_worker_wanted(run, workers))
        run.stages["background"] += time.perf_counter() - started
        run.track(_frames_in(run, source, tracker, workers))
        if run.worker is not None:
            for stage in ("decode", "silhouettes", "descriptor"):
                run.stages[stage] += run.worker.stage_seconds.get(stage, 0.0)
            source.frames_read, source.truncated = run.worker.frames_read, run.worker.truncated
    except KeyboardInterrupt:
        interrupted = True
    finally:
        interrupted, smoothed, problems = run.close(interrupted, write_empty)
    if problems:
        raise OutputError("could not finish outputs: " + "; ".join(problems))
    return TrackRun(run.frames, time.perf_counter() - started, interrupted, tracker,
                    run.written, smoothed)


def _frames_in(run: _Run, source: VideoSource, tracker: PoseTracker, workers: int
               ) -> Iterator[tuple]:
    """The tracked frames, from a worker process if asked for and possible, else from here."""
    if _worker_wanted(run, workers):
        run.worker = FrameWorker(source, tracker)          # a copy of the primed tracker
        return _from_worker(run.worker, tracker)
    batch = 1 if run.watching else BATCH_FRAMES         # as the worker sends them: same results
    return (tracked for chunk in described_chunks(source, tracker, batch)
            for tracked in _tracked(tracker, chunk))


def _worker_wanted(run: _Run, workers: int) -> bool:
    """Whether a second process may share the work: asked for, nothing shown live, a platform
    that forks, no segmenter graph made (a process forked after one crashes)."""
    segmenter = sys.modules.get("tracker.video.segmenter")
    return workers > 1 and not run.watching and can_fork() and not (
        segmenter is not None and segmenter.made_a_graph())


class _Run:
    """One run's outputs (``watching``: those showing the video), frames due, and counts."""

    def __init__(self, tracker: PoseTracker, sinks, smoothed_sinks, progress, lag_s: float):
        self.tracker, self.progress, self.lag_s = tracker, progress, lag_s
        self.sinks, self.smoothed_sinks = list(sinks), list(smoothed_sinks)
        self.lagged = None
        if lag_s:
            from tracker.tracks.fixed_lag import FixedLagSmoother    # only --lag needs it
            self.lagged = FixedLagSmoother.from_seconds(tracker, lag_s)
        self.recorder = PoseRecorder() if smoothed_sinks else None
        self.streaming = self.sinks + ([self.recorder] if self.recorder else [])
        self.watching = [sink for sink in self.streaming if hasattr(sink, "write_frame")]
        self.files = [sink for sink in self.streaming if sink not in self.watching]
        self.frames = 0
        self.written: dict[int, WrittenPoses] = {}
        self.stages = tracker.stage_seconds
        self.worker: FrameWorker | None = None
        # Taken off inside the signals-held block that writes them: no stop falls between.
        self.due: deque = deque() if self.lagged is None else self.lagged.ready

    def track(self, frames_in: Iterator[tuple]) -> None:
        """Hand each tracked frame to the outputs (lag: smoothed); KeyboardInterrupt on a stop."""
        for tracked in frames_in:
            if self.lagged is None:
                self.due.append(tracked)
            elif _smoother_step(self.stages, self.lagged.push, tracked if self.watching
                                else (*tracked[:2], None, tracked[3], {})):  # poses only
                raise KeyboardInterrupt
            while self.due:
                self.emit()
        if self.lagged is not None and _smoother_step(self.stages, self.lagged.flush):
            raise KeyboardInterrupt
        while self.due:
            self.emit()

    def emit(self, stopped: bool = False) -> None:
        """Hand the next due frame to the outputs, stop signals held (KeyboardInterrupt after
        it if one came). stopped: after a stop: to the files only, no progress, no raise."""
        with timed(self.stages, "outputs"), _signals_held() as held:
            index, time_s, frame, poses, people = self.due.popleft()
            showing, fed = ([], self.files) if stopped else (self.watching, self.streaming)
            for sink in fed:
                for pose in poses:
                    sink.write(pose)
            # Counted with the writes: a sink may stop the run at end_frame.
            self.frames += 1
            for pose in poses:
                counts = self.written.setdefault(pose.track_id, WrittenPoses())
                counts.poses += 1
                counts.unfamiliar += pose.unfamiliar
            for sink in showing:
                sink.write_frame(index, time_s, frame, people)
            for sink in fed + self.smoothed_sinks:   # frames with nobody count too
                sink.end_frame(index)
        if self.progress is not None and not stopped:
            self.progress.update(len(poses))
        if held and not stopped:
            raise KeyboardInterrupt

    def close(self, interrupted: bool, write_empty: bool) -> tuple[bool, bool, list[str]]:
        """Finish every output, stop signals held (one just before restarts the closing).
        Returns (interrupted, smoothed tracks written, problem lines)."""
        closed, smoothed, flushed, problems = False, False, False, []
        while not closed:
            try:
                with _signals_held() as held:
                    if interrupted:
                        # A stop shows nothing more: the live view drops what it holds.
                        for sink in self.watching:
                            if hasattr(sink, "discard"):
                                sink.discard()
                    if self.worker is not None:
                        self.worker.close()
                    fed = []
                    try:
                        if interrupted and not flushed:
                            # The frames held back for a lag go out first.
                            flushed = True
                            fed = _write_held(self.lagged, self.due, self.emit, self.stages)
                        if self.progress is not None:
                            self.progress.close()
                        fed += self._feed_smoothed_sinks(interrupted)
                        smoothed = self.recorder is not None and not interrupted
                    finally:
                        empty = not write_empty and not self.written
                        problems = fed + close_sinks(self.sinks + self.smoothed_sinks,
                                                     abandon=empty)
                        closed = True
                interrupted = interrupted or bool(held)
            except KeyboardInterrupt:
                interrupted = True
        return interrupted, smoothed, problems

    def _feed_smoothed_sinks(self, interrupted: bool) -> list[str]:
        """Feed the smoothed sinks each track RTS-smoothed (after a stop: as streamed); problems."""
        if self.recorder is None:
            return []
        if interrupted:
            for sink in self.smoothed_sinks:
                if hasattr(sink, "pose_kind"):
                    sink.pose_kind = streamed_kind(self.lag_s)
            return _feed(self.recorder.poses, self.smoothed_sinks)
        # Drawn at the tracker's smoothed roots, not the streamed poses' (--lag moved those).
        records, tracker = self.recorder.by_track(), self.tracker
        redrawn = {track_id: drawn_at(list(zip(poses, tracker.smoothed_track(track_id),
                                               tracker.smoothed_root_path(track_id))))
                   for track_id, poses in records.items()}
        order = sorted((p.frame_index, tid, i) for tid, ps in records.items()
                       for i, p in enumerate(ps))
        return _feed((redrawn[track_id][i] for _, track_id, i in order), self.smoothed_sinks)


def _smoother_step(stages, step, *args) -> bool:
    """A fixed-lag smoother's push or flush, timed, stop signals held; whether one came."""
    with timed(stages, "fixed-lag smoothing"), _signals_held() as held:
        step(*args)
    return bool(held)


def _write_held(lagged: FixedLagSmoother | None, due: deque, emit, stages) -> list[str]:
    """After a stop: the frames held back to the files; a problem line if an output failed."""
    try:
        if lagged is not None:
            _smoother_step(stages, lagged.flush)
        while due:
            emit(stopped=True)
    except KeyboardInterrupt:
        pass
    except Exception as exc:
        return [f"the frames held back for --lag: {type(exc).__name__}: {exc}"]
    return []


def _from_worker(worker: FrameWorker, tracker: PoseTracker) -> Iterator[tuple]:
    """The worker's frames tracked here (no image), a message at a time."""
    stages = tracker.stage_seconds
    clock = time.perf_counter()
    for chunk in worker.chunks():
        stages["waiting"] += time.perf_counter() - clock
        yield from _tracked(tracker, [(i, t, None, p, d) for i, t, p, d in chunk])
        clock = time.perf_counter()


def _tracked(tracker: PoseTracker, chunk: list[tuple]) -> Iterator[tuple]:
    """(frame_index, time_s, image, poses, people by track id) of consecutive frames
    (frame_index, time_s, image, people, descriptions) tracked at once."""
    results = tracker.track_frames([(i, t, p, d) for i, t, _, p, d in chunk])
    for (index, time_s, image, _, _), (poses, people) in zip(chunk, results, strict=True):
        yield index, time_s, image, poses, people


def _prime(source: VideoSource, tracker: PoseTracker, background: np.ndarray | None,
           two_processes: bool = False) -> None:
    """Teach the tracker the empty scene: the clean plate ``background``, else the median of
    frames spread over the video at the extractor's working size (and those frames); with
    ``two_processes`` two threads measure the noise floor's candidates."""
    if background is not None:
        from tracker.clean_plate import check_plate
        check_plate(source, background)
        tracker.prime(background)
        return
    median, frames = sampled_background(source, tracker)
    full = (source.width, source.height)
    tracker.prime(median, frame_size=None if median.shape[1::-1] == full else full)
    learn_zone = getattr(tracker.extractor, "learn_zone", None)
    if learn_zone is not None:
        learn_zone(frames, median, 2 if two_processes else 1)


def sampled_background(source: VideoSource, tracker: PoseTracker
                       ) -> tuple[np.ndarray, list[np.ndarray]]:
    """(the median of frames spread over the video, those frames), BGR uint8 at working size."""
    full = (source.width, source.height)
    subtractor = getattr(tracker.extractor, "subtractor", None)
    size = subtractor.working_size(*full) if hasattr(subtractor, "working_size") else full
    frames = source.sample_frames(tracker.settings.background_samples, size=size)
    if not frames:
        from tracker.video.unopenable import nothing_decodes     # a file that decodes nothing
        raise nothing_decodes(source)
    # Black or white frames (before a fade-in) are no picture of the scene.
    scenes = [f for f in frames if not _blank(f)]
    frames = scenes or frames
    return median_background(frames), frames


def _blank(frame: np.ndarray) -> bool:
    """Whether a frame (BGR uint8 (h, w, 3)) is black or white all over: its grey levels'
    spread under 3, their mean under 16 or over 240."""
    grey = frame[::4, ::4].mean(axis=2)
    return float(grey.std()) < 3.0 and not 16.0 <= float(grey.mean()) <= 240.0


@contextlib.contextmanager
def _signals_held() -> Iterator[list[int]]:
    """Hold back the stop signals inside the block (main thread only); yields those received."""
    held: list[int] = []
    previous = {}
    if threading.current_thread() is threading.main_thread():
        with _stop_signals_blocked():
            for number in STOP_SIGNALS:
                handler = signal.getsignal(number)
                if handler is not None and handler != signal.SIG_IGN:
                    previous[number] = signal.signal(number, lambda n, _: held.append(n))
    try:
        yield held
    finally:
        with _stop_signals_blocked():
            for number, handler in previous.items():
                signal.signal(number, handler)


@contextlib.contextmanager
def _stop_signals_blocked() -> Iterator[None]:
    """Block the stop signals while handlers are swapped; one that came is delivered on leaving."""
    before = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)


def _feed(poses, sinks: Sequence[Sink]) -> list[str]:
    """Write every pose to every sink, a failed one no more; one problem line per failure."""
    live, problems = list(sinks), []
    for pose in poses:
        for sink in list(live):
            try:
                sink.write(pose)
            except Exception as exc:
                from tracker.outputs.failures import problem_line
                live.remove(sink)
                problems.append(problem_line(sink, exc))
    return problems
