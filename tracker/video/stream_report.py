"""The one-line warnings after an iteration of a VideoSource that met a problem (skipped or
missing frames, unusable or variable frame times, a file changed while read); imported only then."""
from __future__ import annotations

import warnings

from tracker.video.decode import FrameTimes, VideoSource


class VideoTruncatedWarning(UserWarning):
    """Frames were skipped, or decoding stopped before the container's announced end."""


class VideoTimingWarning(UserWarning):
    """Variable frame rate, or no usable frame times in the container (evenly spaced assumed)."""


class VideoGrowingWarning(UserWarning):
    """The file grew (or changed) while it was read: a recording still being written."""


def _ended_early(source: VideoSource, times: FrameTimes, stopped_at: int) -> bool:
    """Whether a stream whose reads failed from frame ``stopped_at`` on stopped more than half
    a frame short of end_index / fps (or end_s), by its frames' times."""
    if source.end_index is None:
        return False
    if times.last is None:
        return True
    last_index, last_time = times.last
    reached = last_time + (stopped_at - last_index) / source.fps
    announced = source.end_index / source.fps
    if source.end_s is not None:
        announced = min(announced, source.end_s)
    return reached < announced - 0.5 / source.fps


def _megabytes(size: int) -> str:
    return f"{size / 1e6:.1f} MB" if size >= 100_000 else f"{size / 1e3:.0f} KB"


def report(source: VideoSource, times: FrameTimes, first_skipped: int | None,
           failed_from: int | None, opened: tuple[int, int] | None,
           now: tuple[int, int] | None) -> None:
    """Warn about the iteration of ``source`` just finished (called from its __iter__: the
    stack level names the loop that read it); sets its ``truncated`` and ``grew``.
    ``failed_from``: the first of the undecodable frames the stream ended on (None: it did not);
    ``opened``, ``now``: the file's (size, mtime) when opened and now (None: gone)."""
    name = source.path.name
    if source.frames_skipped:
        warnings.warn(f"{name}: skipped {source.frames_skipped} undecodable "
                      f"frame(s) from frame {first_skipped} on (a damaged file); the "
                      f"tracks go on over them", VideoTruncatedWarning, stacklevel=3)
    if failed_from is not None and _ended_early(source, times, failed_from):
        source.truncated = True
        warnings.warn(f"{name}: decoding stopped at frame {failed_from} of "
                      f"{source.end_index} (corrupt or cut-off file); using the "
                      f"{source.frames_read} frames read", VideoTruncatedWarning, stacklevel=3)
    if times.problem is not None:
        warnings.warn(f"{name}: the container {times.problem}; frames from there on are "
                      f"taken as evenly spaced at {source.fps:g} fps", VideoTimingWarning,
                      stacklevel=3)
    elif times.from_container and times.irregular():
        shortest, longest = times.intervals
        warnings.warn(f"{name}: variable frame rate (frames {1000 * shortest:.0f} to "
                      f"{1000 * longest:.0f} ms apart, {source.fps:g} fps announced); each "
                      f"frame keeps its own time", VideoTimingWarning, stacklevel=3)
    if now != opened or source.grew:
        source.grew = True
        used = 0.0 if source.read_until_s is None else source.read_until_s + 1.0 / source.fps
        tracked = f"the first {used:.1f} s" if source.start_s == 0 else f"up to {used:.1f} s"
        if now is None or opened is None:
            warnings.warn(f"{source.path} was removed or replaced while read; tracked "
                          f"{tracked}", VideoGrowingWarning, stacklevel=3)
            return
        change = "grew" if now[0] > opened[0] else "changed"
        warnings.warn(f"{source.path} is still being written ({change} from "
                      f"{_megabytes(opened[0])} to {_megabytes(now[0])} while read); "
                      f"tracked {tracked}", VideoGrowingWarning, stacklevel=3)
