"""Benchmark the live view's pacing: how evenly `track --view` shows a video's frames.

    python scripts/bench_view.py                         # the shipped sample, lags 0 0.5 2
    python scripts/bench_view.py --video my.mp4 --lag 0.5 5

For each lag (`track --lag`), tracks the video into a live view (tracker.outputs.meshcat_view,
its own server on 127.0.0.1, as `track --view` opens it; no browser needed) that plays at the
video's own speed, and prints the wall-clock gaps between frames shown (median, 99th
percentile, largest, how many over 50 ms) against the video's frame interval, and the wall time
of the run. Each run lasts about as long as the video. Since 2026-12-04 the view draws from a
thread of its own (tracker.outputs.playout); before, every pause of the tracking loop (the
smoothing of a block with a lag) showed as a pause of the view, which this measures.

A video that cannot be opened or an absurd lag is refused in one line (exit 2); Ctrl-C stops
in one line (exit 130).
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from tracker.cli import MAX_LAG_S            # track --lag's upper end
from tracker.one_line_parser import OneLineParser, quiet_decoder_logs, stops_in_one_line

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sequences" / "data" / "sample_spiral_walk.mp4"


def lag(text: str) -> float:
    """A --lag value: seconds, 0 to MAX_LAG_S."""
    value = float(text)
    if not (math.isfinite(value) and 0.0 <= value <= MAX_LAG_S):
        raise ValueError(text)
    return value


def measure(video: Path, lag_s: float, model) -> dict:
    """Track video into a realtime live view with this lag; the wall-clock times (s) at which
    each frame was shown and the video times (s) they belong to."""
    from tracker import PoseTracker, track_video
    from tracker.pipeline import TrackerSettings
    from tracker.outputs.meshcat_view import MeshcatView
    from tracker.video.decode import open_video

    class TimedView(MeshcatView):
        """The live view, noting when each frame's drawing is done."""

        def __init__(self):
            super().__init__(realtime=True, print_url=False)
            self.shown: list[tuple[float, float]] = []

        def _finish_frame(self):
            fresh = self._frame is not None and not self._frame_done
            super()._finish_frame()
            if fresh:
                self.shown.append((self._frame_time_s, time.perf_counter()))

    source = open_video(video)
    tracker = PoseTracker(model, source.fps, TrackerSettings(keep_history=lag_s > 0))
    started = time.perf_counter()
    with TimedView() as view:
        track_video(source, tracker, [view], lag_s=lag_s).stop_if_interrupted()
    shown = np.array(view.shown).reshape(-1, 2)
    return {"video_s": shown[:, 0], "wall_s": shown[:, 1],
            "run_s": time.perf_counter() - started, "interval_s": 1.0 / source.fps}


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(description=__doc__.splitlines()[0])
    parser.add_argument("--video", type=Path, default=SAMPLE,
                        help="video to track (default: the shipped sample)")
    parser.add_argument("--lag", type=lag, nargs="+", default=[0.0, 0.5, 2.0],
                        metavar="S", help=f"lags to measure, seconds, 0-{MAX_LAG_S:g} "
                                          f"(default 0 0.5 2)")
    args = parser.parse_args(argv)
    if not args.video.is_file():
        parser.error(f"--video {args.video}: no such file")
    from regressor.pose_model import load_pose_model
    from tracker.video.decode import VideoError, open_video
    quiet_decoder_logs()
    try:
        open_video(args.video)
    except VideoError as exc:
        parser.error(str(exc))
    model = load_pose_model()
    print(f"{args.video.name}: the live view's gaps between frames shown (wall clock)")
    with threadpool_limits(1):                       # as the track command runs
        for lag_s in args.lag:
            run = measure(args.video, lag_s, model)
            if len(run["wall_s"]) < 2:
                print(f"bench_view.py: {args.video}: {len(run['wall_s'])} frames with people "
                      f"drawn: no gaps to measure", file=sys.stderr)
                return 1
            gaps = np.diff(run["wall_s"]) * 1e3
            print(f"  --lag {lag_s:g}: {len(run['wall_s'])} frames, video interval "
                  f"{run['interval_s'] * 1e3:.0f} ms; gaps median {np.median(gaps):.0f} ms, "
                  f"99th percentile {np.percentile(gaps, 99):.0f}, largest {gaps.max():.0f}, "
                  f"{int((gaps > 50).sum())} over 50 ms; run {run['run_s']:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(stops_in_one_line("bench_view.py", main)())
