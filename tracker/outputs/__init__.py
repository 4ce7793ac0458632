"""Outputs of the tracker, sinks taking the calls of :class:`Sink`; optional: write_frame() and
discard() (MeshcatView), ``pose_kind`` (set by tracker.run.track_video), ``option`` (e.g.
"--json", for failures.problem_line) and ``abandon()`` (files: close_sinks)."""
from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from tracker.pipeline import TrackedPose


class Sink(Protocol):
    """Where tracked poses go: write() one person in one frame, end_frame() after every frame
    (with people in it or not), close() to finish the output (idempotent; also on Ctrl-C)."""

    def write(self, pose: TrackedPose) -> None: ...
    def end_frame(self, frame_index: int) -> None: ...
    def close(self) -> None: ...


class PoseRecorder:
    """A sink that keeps every pose in ``poses`` (TrackedPose, in order)."""

    def __init__(self):
        self.poses: list[TrackedPose] = []
        self._frame_ends: list[tuple[int, int]] = []   # (frame index, poses up to its end)

    def write(self, pose: TrackedPose) -> None:
        self.poses.append(pose)

    def end_frame(self, frame_index: int) -> None:
        self._frame_ends.append((frame_index, len(self.poses)))

    def frames(self) -> list[tuple[int, list[TrackedPose]]]:
        """(frame_index, its poses) of every frame ended so far, in order (fixed_lag.replay's)."""
        starts = [0] + [stop for _, stop in self._frame_ends]
        return [(index, self.poses[start:stop])
                for (index, stop), start in zip(self._frame_ends, starts)]

    def close(self) -> None:
        """Nothing to finish."""

    def by_track(self) -> dict[int, list[TrackedPose]]:
        """Track id -> its poses in frame order."""
        tracks: dict[int, list[TrackedPose]] = {}
        for pose in self.poses:
            tracks.setdefault(pose.track_id, []).append(pose)
        return tracks


def open_sinks(factories: Iterable[Callable[[], Sink]]) -> list[Sink]:
    """Call each factory in turn; if one fails (a lock held, Ctrl-C), abandon the sinks already
    opened (close_sinks(abandon=True): files keep what they held) and re-raise."""
    opened: list[Sink] = []
    try:
        for make in factories:
            opened.append(make())
    except BaseException:
        close_sinks(opened, abandon=True)
        raise
    return opened


def close_sinks(sinks: Iterable[Sink], abandon: bool = False) -> list[str]:
    """Close every sink, even when some fail; one line per failure (problem_line). abandon: the
    run tracked nobody: sinks with ``abandon()`` (files) stop without writing, the others close."""
    problems = []
    for sink in sinks:
        try:
            (sink.abandon if abandon and hasattr(sink, "abandon") else sink.close)()
        except Exception as exc:
            from tracker.outputs.failures import problem_line      # only on a failure
            problems.append(problem_line(sink, exc))
    return problems
