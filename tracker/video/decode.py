"""Video decoding: a file becomes a stream of (index, time, BGR frame) with checked metadata.
A file that cannot be read is a one-line :class:`VideoError`. Damaged frames are skipped, a
stream cut short ends cleanly, frames keep their container times, a file still being written is
read to its live end; each says so in one warning (tracker.video.stream_report; details:
docs/code_notes/video.md)."""
from __future__ import annotations

import copy
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

import cv2
import numpy as np

from regressor.errors import SilhouettePoseError
from tracker.video.area_shrink import shrink

MIN_SIDE_PX = 16
# Longer than any camera or 8K video; beyond this a file is almost certainly damaged metadata.
MAX_SIDE_PX = 16384
MAX_FPS = 1000.0
#: Horizontal field of view (degrees) assumed for a video's camera (a typical phone or webcam).
ASSUMED_FOV_DEG = 60.0
#: Background samples at most this many frames apart are read straight through rather than by
#: seeking (x264's default key-frame interval is 250 frames).
SEQUENTIAL_SPACING = 250
#: Undecodable frames in a row (seconds of video, at least UNREADABLE_RUN_MIN frames) after
#: which a stream counts as ended; shorter runs are damaged frames, skipped.
UNREADABLE_RUN_S = 2.0
UNREADABLE_RUN_MIN = 30
#: Frame intervals further than this fraction from 1/fps make the timing irregular; a
#: container's millisecond rounding (33 or 34 ms at 30 fps) stays well inside.
IRREGULAR_INTERVAL = 0.25


def focal_length_px(frame_width_px: int, fov_deg: float = ASSUMED_FOV_DEG) -> float:
    """Pinhole focal length in px for this horizontal field of view: (W / 2) / tan(fov / 2)."""
    return 0.5 * frame_width_px / math.tan(math.radians(fov_deg) / 2.0)


def colourless(image: np.ndarray, max_chroma_std: float = 1.5) -> bool:
    """True when a BGR uint8 (H, W, 3) image carries no colour (grey, or a constant tint): its
    Cr and Cb spreads (levels) are 0.0 on such videos, 10-19 on the sample and Pose2Sim's."""
    chroma = cv2.cvtColor(image, cv2.COLOR_BGR2YCrCb)[..., 1:].reshape(-1, 2)
    return bool(np.all(chroma.std(axis=0) < max_chroma_std))


class VideoError(SilhouettePoseError, ValueError):
    """A video file that cannot be used; the message is one line and names the file."""


class VideoFrame(NamedTuple):
    """One decoded frame: ``index`` from 0 at the file's start, ``time_s`` its time in the video
    (s), ``image`` BGR uint8 (H, W, 3)."""

    index: int
    time_s: float
    image: np.ndarray


class FrameTimes:
    """Each frame's time (s): the container's while its times increase, else the last good
    time plus (index - its index) / fps. ``problem``: why the container's times were given up
    (None while used); ``intervals``: (shortest, longest) s per frame so far."""

    def __init__(self, fps: float, from_container: bool = True):
        self.fps = float(fps)
        self.from_container = from_container
        self.problem: str | None = None
        self.last: tuple[int, float] | None = None          # (index, time_s) of the last frame
        self.intervals = (math.inf, 0.0)

    def __call__(self, index: int, container_ms: float) -> float:
        """The time of frame ``index``, whose container time is ``container_ms``."""
        time_s = container_ms / 1000.0
        # After a seek, a container without times reports 0 ms for a frame past the first.
        unset = self.last is None and index > 0 and time_s <= 0.0
        if self.from_container and (unset or not (math.isfinite(time_s) and time_s >= 0.0 and (
                self.last is None or time_s > self.last[1]))):
            self.from_container = False
            self.problem = ("gives no frame times" if self.last is None else
                            f"gives frame {index} a time not after frame {self.last[0]}'s")
        if not self.from_container:
            last_index, last_time = self.last or (0, 0.0)
            time_s = last_time + (index - last_index) / self.fps
        if self.last is not None:
            step = (time_s - self.last[1]) / (index - self.last[0])
            self.intervals = (min(self.intervals[0], step), max(self.intervals[1], step))
        self.last = (index, time_s)
        return time_s

    def irregular(self) -> bool:
        """Whether some frame interval is more than IRREGULAR_INTERVAL off 1 / fps."""
        shortest, longest = self.intervals
        return shortest < (1.0 - IRREGULAR_INTERVAL) / self.fps or \
            longest > (1.0 + IRREGULAR_INTERVAL) / self.fps


def _file_state(path: Path) -> tuple[int, int] | None:
    """(size in bytes, modification time in ns) of ``path``; None once it is gone."""
    try:
        stat = os.stat(path)
    except OSError:
        return None
    return stat.st_size, stat.st_mtime_ns


class VideoSource:
    """A checked video file; iterate (again and again) to get :class:`VideoFrame`. ``fps``:
    the container's or the stated frames/s; ``frame_count``: frames announced (None when
    unknown; with a variable rate, duration times fps); ``width``/``height``: px yielded;
    ``start_index``/``end_index``: frames yielded, end exclusive (None: to the end);
    ``start_s``/``end_s``: the time range (s) asked for; ``container_times``: False to space
    frames evenly at fps. After an iteration: ``frames_read``, ``frames_skipped`` (undecodable
    inside the stream), ``truncated`` (stopped before end_index), ``grew``, ``read_until_s``
    (the last frame's time, None before any). ``decoder_threads``: threads decoding for
    iteration (None: OpenCV's choice, one per core)."""

    def __init__(self, path: Path, fps: float, frame_count: int | None, size: tuple[int, int],
                 start_index: int, end_index: int | None, end_s: float | None = None,
                 container_times: bool = True, start_s: float = 0.0):
        self.path, self.fps, self.frame_count = path, fps, frame_count
        self.width, self.height = size
        self.start_index, self.end_index = start_index, end_index
        self.start_s, self.end_s = start_s, end_s
        self.container_times = container_times
        self.frames_read, self.frames_skipped, self.truncated, self.grew = 0, 0, False, False
        self.read_until_s: float | None = None
        self.decoder_threads: int | None = None

    def __iter__(self) -> Iterator[VideoFrame]:
        threads = self.decoder_threads       # unset: the one-argument call (as tests stub it)
        capture = _open_capture(self.path) if threads is None else \
            _open_capture(self.path, threads)
        opened = _file_state(self.path)
        self.frames_read, self.frames_skipped, self.truncated, self.grew = 0, 0, False, False
        self.read_until_s = None
        times = FrameTimes(self.fps, self.container_times)
        first_skipped = None
        held = None         # (the last frame decoded, the times before it), yielded after the next
        give_up = self.unreadable_run()
        rewound = False
        try:
            index = _seek(capture, self.start_index, give_up)
            # With an end time and the container's frame times the end time stops the stream.
            end = (self.frame_count if self.end_s is not None and self.container_times
                   else self.end_index) or math.inf       # None: unknown, read to the end
            failed = 0                  # undecodable frames in a row, just before index
            while index < end:
                ok, image = capture.read()
                decoded = ok and image is not None
                if held is None and not rewound and index > 0 and self.container_times:
                    from tracker.video.seeking import seek_missed      # after a seek only
                    if seek_missed(self, decoded, capture):     # read from frame 0: times decide
                        capture.set(cv2.CAP_PROP_POS_FRAMES, 0)
                        index, failed, rewound = 0, 0, True
                        times = FrameTimes(self.fps, self.container_times)
                        continue
                if not decoded:
                    if _file_state(self.path) != opened:    # the live end: stop there,
                        if held is not None:                    # the last frame unused
                            times = held[1]
                        self.grew, held, failed = True, None, 0
                        break
                    failed += 1
                    index += 1        # a failed read consumes its frame (FFmpeg's backend)
                    if failed >= give_up:
                        break
                    continue
                before = copy.copy(times)
                time_s = times(index, capture.get(cv2.CAP_PROP_POS_MSEC))
                if time_s + 1.0 / self.fps <= self.start_s + 1e-6:
                    index, failed = index + 1, 0    # a seek by frame number landed early
                    continue
                if self.end_s is not None and time_s >= self.end_s - 1e-6:
                    failed = 0
                    break
                if failed:
                    first_skipped = index - failed if first_skipped is None else first_skipped
                    self.frames_skipped += failed
                    failed = 0
                if held is not None:
                    yield held[0]
                    self.frames_read, self.read_until_s = self.frames_read + 1, held[0].time_s
                held = VideoFrame(index, time_s, self._prepare(image)), before
                index += 1
            if held is not None:
                yield held[0]
                self.frames_read, self.read_until_s = self.frames_read + 1, held[0].time_s
        finally:
            capture.release()
        now = _file_state(self.path)
        if failed or self.frames_skipped or times.problem is not None or now != opened or \
                self.grew or (times.from_container and times.irregular()):
            from tracker.video.stream_report import report      # only when there is news
            report(self, times, first_skipped, index - failed if failed else None, opened, now)

    def unreadable_run(self) -> int:
        """Undecodable frames in a row after which the stream counts as ended."""
        return max(UNREADABLE_RUN_MIN, math.ceil(UNREADABLE_RUN_S * self.fps))

    def _prepare(self, image: np.ndarray, size: tuple[int, int] | None = None) -> np.ndarray:
        """A decoded image -> BGR uint8 at ``size`` (width, height; default this source's)."""
        image = _as_bgr(image)
        size = size or (self.width, self.height)
        if size != (image.shape[1], image.shape[0]):
            image = shrink(image, size)
        return image

    def sample_frames(self, count: int, size: tuple[int, int] | None = None) -> list[np.ndarray]:
        """Up to ``count`` frames (BGR uint8 (H, W, 3), at ``size`` (width, height) px if given)
        spread evenly over the range, undecodable ones passed over; a stream of unknown length is
        read to its end (its first frames alone could show a person standing in the background)."""
        if self.end_index is None:
            from tracker.video.even_sample import sample_through
            return sample_through(self, count, size)
        images = self._sample_by_index(count, size)
        if not images and self.container_times and self.start_index > 0:
            # A variable rate can put the start time at another frame: sample by time instead.
            from tracker.video.even_sample import sample_by_time
            return sample_by_time(self, count, size)
        return images

    def _sample_by_index(self, count: int, size: tuple[int, int] | None) -> list[np.ndarray]:
        """sample_frames by frame number at the announced rate: samples up to SEQUENTIAL_SPACING
        apart in one pass (grab() all, retrieve() those kept), sparser ones by seeking."""
        indices = np.linspace(self.start_index, self.end_index - 1, max(count, 1))
        indices = np.unique(indices.round().astype(int))
        if (indices[-1] - indices[0]) / max(len(indices) - 1, 1) > SEQUENTIAL_SPACING:
            from tracker.video.seeking import sample_by_seeking     # a long video only
            return sample_by_seeking(self, indices, size)
        capture = _open_capture(self.path)
        images = []
        give_up = self.unreadable_run()
        try:
            if _seek(capture, int(indices[0]), give_up) != indices[0]:
                return images
            wanted = set(indices.tolist())
            failed = 0
            for index in range(int(indices[0]), int(indices[-1]) + 1):
                if not capture.grab():
                    failed += 1
                    if failed >= give_up:
                        break
                    continue
                failed = 0
                if index in wanted:
                    ok, image = capture.retrieve()
                    if ok and image is not None:
                        images.append(self._prepare(image, size))
        finally:
            capture.release()
        return images


def _open_capture(path: Path, threads: int | None = None) -> cv2.VideoCapture:
    """An opened capture of ``path`` (``threads`` decoding where the backend takes the
    setting: FFmpeg's are bit-exact whatever their number), else VideoError naming why."""
    if threads is not None:
        capture = cv2.VideoCapture(str(path), cv2.CAP_ANY, [cv2.CAP_PROP_N_THREADS, threads])
        if capture.isOpened():
            return capture
        capture.release()
    capture = cv2.VideoCapture(str(path), cv2.CAP_ANY)
    if not capture.isOpened():
        capture.release()
        from tracker.video.unopenable import why_unopenable     # only for a refused file
        raise VideoError(f"{path}: {why_unopenable(path)}")
    return capture


def _seek(capture: cv2.VideoCapture, start_index: int, give_up: int) -> int:
    """Position ``capture`` so the next read returns frame ``start_index``; returns that index
    (an earlier one where ``give_up`` undecodable frames in a row end the stream)."""
    if start_index == 0:
        return 0
    from tracker.video.seeking import seek          # a start past the first frame only
    return seek(capture, start_index, give_up)


def _as_bgr(image: np.ndarray) -> np.ndarray:
    """Any decoded frame (gray (H,W) or (H,W,1), BGR, BGRA) -> BGR uint8 (H,W,3)."""
    if image.dtype != np.uint8:
        image = cv2.convertScaleAbs(image, alpha=255.0 / max(float(image.max()), 1.0))
    if image.ndim == 2 or image.shape[2] == 1:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    if image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
    return image


def open_video(path: str | Path, start_s: float = 0.0, end_s: float | None = None,
               fps: float | None = None) -> VideoSource:
    """Open and check a video file (decoding its first frame); returns a :class:`VideoSource`.
    ``start_s``/``end_s``: seconds from the file's start (end exclusive; None = to the end);
    ``fps``: frames/s to assume instead of the container's (frames then evenly spaced). A file,
    size, rate or time range that cannot be used raises :class:`VideoError`."""
    path = Path(path)
    if not path.exists():
        raise VideoError(f"{path}: no such file")
    if not path.is_file():
        raise VideoError(f"{path}: is not a file")
    capture = _open_capture(path)
    try:
        rate = float(capture.get(cv2.CAP_PROP_FPS)) if fps is None else float(fps)
        count = capture.get(cv2.CAP_PROP_FRAME_COUNT)
        ok, first = capture.read()
    finally:
        capture.release()
    if not ok or first is None:
        raise VideoError(f"{path}: contains no decodable video frames")
    height, width = first.shape[:2]
    if min(width, height) < MIN_SIDE_PX:
        raise VideoError(f"{path}: resolution {width}x{height} is too small "
                         f"(each side must be at least {MIN_SIDE_PX} px)")
    if max(width, height) > MAX_SIDE_PX:
        raise VideoError(f"{path}: resolution {width}x{height} is too large "
                         f"(each side must be at most {MAX_SIDE_PX} px)")
    if not (math.isfinite(rate) and 0.0 < rate <= MAX_FPS):
        raise VideoError(f"{path}: frame rate {rate:g} frames/s is unusable (missing or damaged "
                         f"metadata?); state the real one (track --fps)")
    frame_count = int(count) if math.isfinite(count) and count >= 1 else None
    if not (math.isfinite(start_s) and start_s >= 0) or \
            (end_s is not None and not end_s > start_s):
        raise VideoError(f"{path}: bad time range start_s={start_s}, end_s={end_s}")
    # Frame numbers of absurd times are capped, not overflowed (1e308 s * fps is infinite).
    start_index = int(math.floor(min(start_s * rate, 2.0 ** 62) + 1e-9))
    end_index = frame_count if end_s is None else \
        min(int(math.ceil(min(end_s * rate, 2.0 ** 62) - 1e-9)), frame_count or 2 ** 62)
    if frame_count is not None and start_index >= frame_count:
        raise VideoError(f"{path}: start_s={start_s} is past the end "
                         f"({frame_count} frames at {rate:g} fps)")
    if end_index is not None and end_index <= start_index:
        raise VideoError(f"{path}: no frames in the chosen time range ({start_s:g} s to "
                         f"{end_s:g} s at {rate:g} fps)")
    return VideoSource(path, rate, frame_count, (width, height), start_index, end_index,
                       end_s=end_s, container_times=fps is None, start_s=start_s)
