"""Fixed-lag smoothing (``track --lag``): the outputs written while tracking get each pose
``lag`` frames late, smoothed by its track's own smoother (FrontBackTracker.smoothed) over a
window of its latest poses and drawn at the root path smoothed over it. Frames are smoothed in
blocks (a run per frame would cost about 0.5 ms per frame of window): when ``2 lag`` frames
wait, the oldest ``lag`` are smoothed from ``margin`` frames before the block (to start the
filters); they go out one per frame pushed, a steady pace a live view can play (docs/tuning.md).
streamed_kind and drawn_at, re-exported here, live in tracker.tracks and its root_path.
"""
from __future__ import annotations

import itertools
from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from tracker.tracks import streamed_kind  # noqa: F401
from tracker.tracks.root_path import drawn_at
from tracker.video.silhouettes import PersonMask

if TYPE_CHECKING:
    from tracker.pipeline import PoseTracker, TrackedPose

#: Frames before a block that start its window's filters, seconds (longer gained nothing).
MARGIN_S = 1.0
#: The longest lag ``track --lag`` takes, seconds: the frames held back grow with it.
MAX_LAG_S = 10.0
#: Video frames held back (for the live view, which shows them 256 px wide) are kept at most
#: this wide, their people with them: a 0.5 s lag at 60 fps holds 59 frames, 25 MB each at 4K.
HELD_FRAME_WIDTH_PX = 640


@dataclass
class _Waiting:
    """A tracked frame held back (its image shrunk: _held), and per pose its track's pose
    number (0 for the track's first pose)."""

    frame: tuple              # (frame_index, time_s, image or None, poses, people)
    numbers: list[int]


class FixedLagSmoother:
    """Holds tracked frames back and gives them out with each pose's ``filtered`` replaced
    by the fixed-lag smoothed pose (55,) and its ``joints_m`` (18, 3) metres redrawn from it.

    tracker: the PoseTracker, with TrackerSettings(keep_history=True). lag_frames: >= 1;
    margin_frames: >= 0 (None: MARGIN_S at the tracker's fps). Frames (frame_index, time_s,
    image, poses, people) go in with :meth:`push` and come out in order on :attr:`ready` (a
    deque the caller empties); :meth:`flush` puts the rest there. A block leaves the queue
    only once smoothed, so a Ctrl-C inside the smoother loses nothing."""

    def __init__(self, tracker: PoseTracker, lag_frames: int, margin_frames: int | None = None):
        if not tracker.settings.keep_history:
            raise ValueError("fixed-lag smoothing needs TrackerSettings(keep_history=True)")
        if not (int(lag_frames) == lag_frames and lag_frames >= 1):
            raise ValueError(f"lag_frames={lag_frames} must be a whole number >= 1")
        if margin_frames is None:
            margin_frames = int(round(MARGIN_S * tracker.fps))
        if not (int(margin_frames) == margin_frames and margin_frames >= 0):
            raise ValueError(f"margin_frames={margin_frames} must be a whole number >= 0")
        self.tracker = tracker
        self.lag, self.margin = int(lag_frames), int(margin_frames)
        self.ready: deque[tuple] = deque()           # due: for the caller to take
        self._smoothed: deque[tuple] = deque()       # smoothed, not due yet
        self._waiting: deque[_Waiting] = deque()     # not smoothed yet
        self._poses_seen: dict[int, int] = {}        # track id -> its poses pushed so far

    @classmethod
    def from_seconds(cls, tracker: PoseTracker, lag_s: float) -> FixedLagSmoother:
        """A smoother whose lag is ``lag_s`` seconds of video (rounded to whole frames, >= 1)."""
        if not (np.isfinite(lag_s) and 0 < lag_s <= MAX_LAG_S):
            raise ValueError(f"lag {lag_s} s must be above 0 and at most {MAX_LAG_S:g} s")
        return cls(tracker, max(1, int(round(lag_s * tracker.fps))))

    @property
    def waiting(self) -> int:
        """How many frames are held back, not yet smoothed."""
        return len(self._waiting)

    def push(self, frame: tuple) -> None:
        """Take the next tracked frame (frame_index, time_s, image, poses, people); the frame
        now due, if any, is put on :attr:`ready`."""
        numbers = []
        for pose in frame[3]:
            number = self._poses_seen.get(pose.track_id, 0)
            self._poses_seen[pose.track_id] = number + 1
            numbers.append(number)
        self._waiting.append(_Waiting(_held(frame), numbers))
        if not self._smoothed and len(self._waiting) >= 2 * self.lag:
            self._smooth(self.lag)
        if self._smoothed:
            self.ready.append(self._smoothed.popleft())

    def flush(self) -> None:
        """Put every frame still held back on :attr:`ready`, smoothed over all that was pushed."""
        if self._waiting:
            self._smooth(len(self._waiting))
        self.ready.extend(self._smoothed)
        self._smoothed.clear()

    def _smooth(self, count: int) -> None:
        """Smooth the oldest ``count`` frames held back onto the smoothed queue."""
        block = list(itertools.islice(self._waiting, count))
        # Each track's poses in the block, one smoother run per track.
        numbers: dict[int, list[int]] = {}
        for waiting in block:
            for pose, number in zip(waiting.frame[3], waiting.numbers):
                numbers.setdefault(pose.track_id, []).append(number)
        smoothed: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
        for track_id, wanted in numbers.items():
            start = max(0, wanted[0] - self.margin)
            stop = self._poses_seen[track_id]
            window = self.tracker.smoothed_track(track_id, start, stop)
            if len(window) != stop - start:
                raise RuntimeError(f"track {track_id} holds {len(window)} poses from pose "
                                   f"{start}, the smoother was given {stop - start}")
            roots = self.tracker.smoothed_root_path(track_id, start, stop)
            for number in wanted:
                smoothed[track_id, number] = (window[number - start], roots[number - start])
        poses = [(pose, *smoothed[pose.track_id, number]) for waiting in block
                 for pose, number in zip(waiting.frame[3], waiting.numbers)]
        redrawn = iter(drawn_at(poses))
        out = []
        for waiting in block:
            index, time_s, image, frame_poses, people = waiting.frame
            out.append((index, time_s, image, [next(redrawn) for _ in frame_poses], people))
        for _ in block:
            self._waiting.popleft()
        self._smoothed.extend(out)


def replay(tracker: PoseTracker, frames: list[tuple[int, list[TrackedPose]]],
           lag_s: float) -> list[TrackedPose]:
    """The poses a run with ``track_video(..., lag_s=lag_s)`` would have given the outputs,
    from a finished run without a lag (keep_history=True) and its every frame as
    (frame_index, its poses), in order: the filtered and the lagged poses from one run."""
    smoother = FixedLagSmoother.from_seconds(tracker, lag_s)
    for index, poses in frames:
        smoother.push((index, 0.0, None, poses, {}))
    smoother.flush()
    return [pose for frame in smoother.ready for pose in frame[3]]


def _held(frame: tuple) -> tuple:
    """A tracked frame as held back: an image wider than HELD_FRAME_WIDTH_PX shrunk to that
    width, its people (track id -> PersonMask) with it."""
    index, time_s, image, poses, people = frame
    if image is None or image.shape[1] <= HELD_FRAME_WIDTH_PX:
        return frame
    scale = HELD_FRAME_WIDTH_PX / image.shape[1]
    small = cv2.resize(image, (HELD_FRAME_WIDTH_PX, max(1, round(image.shape[0] * scale))),
                       interpolation=cv2.INTER_AREA)
    return index, time_s, small, poses, {track_id: _shrunk(person, scale)
                                         for track_id, person in people.items()}


def _shrunk(person: PersonMask, scale: float) -> PersonMask:
    """A person's mask and box scaled by ``scale`` (< 1)."""
    x, y, w, h = person.bbox
    size = (max(1, round(w * scale)), max(1, round(h * scale)))
    mask = cv2.resize(person.mask.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST) > 0
    return PersonMask(mask, (round(x * scale), round(y * scale), size[0], size[1]),
                      (person.centroid[0] * scale, person.centroid[1] * scale), int(mask.sum()))
