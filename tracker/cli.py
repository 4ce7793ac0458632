"""The ``track`` command: 3-D poses of the people in a static-camera video.

    track VIDEO [--out FILE.mcap] [--bvh DIR] [--json FILE] [--view] [--smooth] [--model FILE]
          [--max-people N] [--start S] [--end S] [--quiet]

Without --out/--json/--bvh/--view it records to VIDEO_STEM.mcap in the current folder. Errors
(bad video, model, options or output paths) print one line and exit non-zero; Ctrl-C stops
cleanly, keeping every output written so far valid.
"""
from __future__ import annotations

import argparse
import math
import os
import signal
import sys
from pathlib import Path

from threadpoolctl import threadpool_limits

from regressor.errors import SilhouettePoseError
from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
from .pipeline import PoseTracker, TrackerSettings
from .progress import Progress
from .run import TrackRun, track_video
from .sinks import open_sinks
from .video import open_video

EXIT_ERROR, EXIT_USAGE, EXIT_INTERRUPTED = 1, 2, 130


class TrackError(SilhouettePoseError):
    """A problem the user can fix (options, paths); printed as one line."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):   # one line, not usage + message
        self.exit(EXIT_USAGE, f"track: error: {message} (see track --help)\n")


def build_parser() -> argparse.ArgumentParser:
    ap = _Parser(prog="track", description="3-D human pose from a static-camera video, by "
                 "relevance vector regression on silhouettes, Kalman-filtered over time.")
    ap.add_argument("video", type=Path, help="video file (mp4, avi, ...)")
    ap.add_argument("--out", type=Path, help="MCAP recording (default VIDEO_STEM.mcap if no "
                    "other output is chosen)")
    ap.add_argument("--bvh", type=Path, metavar="DIR", help="write one BVH per track here")
    ap.add_argument("--json", type=Path, metavar="FILE", help="write a JSON summary")
    ap.add_argument("--view", action="store_true", help="live 3-D skeletons in meshcat "
                    "(browser, 127.0.0.1), played at the video's own speed")
    ap.add_argument("--smooth", action="store_true", help="RTS-smooth each whole track for "
                    "the JSON and BVH outputs (offline use)")
    ap.add_argument("--model", type=Path, default=DEFAULT_MODEL_PATH, help="model file "
                    "(default: the shipped model)")
    ap.add_argument("--max-people", type=int, default=None, metavar="N",
                    help="track at most N people per frame (largest first)")
    ap.add_argument("--start", type=float, default=0.0, metavar="S", help="start at S seconds")
    ap.add_argument("--end", type=float, default=None, metavar="S", help="stop at S seconds")
    ap.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    return ap


def _check_options(args) -> None:
    if args.max_people is not None and not 1 <= args.max_people <= 100:
        raise TrackError(f"--max-people must be between 1 and 100, got {args.max_people}")
    if not (math.isfinite(args.start) and args.start >= 0):
        raise TrackError(f"--start must be a time in seconds >= 0, got {args.start}")
    if args.end is not None and not (math.isfinite(args.end) and args.end > args.start):
        raise TrackError(f"--end must be after --start ({args.start} s), got {args.end}")
    if args.out is None and args.json is None and args.bvh is None and not args.view:
        args.out = Path(args.video.stem + ".mcap")
    for path, what in ((args.out, "--out"), (args.json, "--json")):
        if path is None:
            continue
        if path.is_dir():
            raise TrackError(f"{what} {path} is a folder; give a file name")
        folder = path.parent if str(path.parent) else Path(".")
        if not folder.is_dir():
            raise TrackError(f"{what} {path}: folder {folder} does not exist")
        if not os.access(folder, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
            raise TrackError(f"{what} {path}: not writable")
    if args.bvh is not None:
        if args.bvh.exists() and not args.bvh.is_dir():
            raise TrackError(f"--bvh {args.bvh} exists and is not a folder")
        try:
            args.bvh.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise TrackError(f"--bvh {args.bvh}: cannot create folder ({exc.strerror})")
        if not os.access(args.bvh, os.W_OK):
            raise TrackError(f"--bvh {args.bvh}: not writable")


def _sink_factories(args, source, model) -> tuple[list, list]:
    """(factories of the sinks fed every frame, of those fed smoothed tracks at the end when
    --smooth). One entry per output option: adding an output is adding a line here."""
    def mcap():
        from .sinks.mcap import McapSink
        return McapSink(args.out, metadata={
            "video": {"path": str(args.video), "fps": source.fps,
                      "width": source.width, "height": source.height},
            "model": {"path": str(args.model), **model.summary()},
            "settings": {"smooth": args.smooth, "max_people": args.max_people,
                         "start_s": args.start, "end_s": args.end,
                         "note": "MCAP holds filtered (not smoothed) poses"}})

    def json_summary():
        from .sinks.json_summary import JsonSummarySink
        return JsonSummarySink(args.json, source.fps)

    def bvh():
        from .sinks.bvh import BVHSink
        # Tracks of a few frames are subtraction glitches, not people worth a file.
        return BVHSink(args.bvh, source.fps, prefix=args.video.stem, min_frames=5)

    def view():
        from .sinks.meshcat_view import MeshcatView  # deferred: starts a server process
        return MeshcatView(realtime=True)    # tracking outruns the video: play at its speed

    outputs = [(args.out, mcap, False), (args.json, json_summary, True),
               (args.bvh, bvh, True), (args.view or None, view, False)]
    chosen = [(make, smoothable and args.smooth) for option, make, smoothable in outputs
              if option is not None]
    return [m for m, later in chosen if not later], [m for m, later in chosen if later]


def run(args) -> int:
    """Track args.video into the chosen outputs; returns the exit code."""
    _check_options(args)
    model = load_pose_model(args.model)
    source = open_video(args.video, start_s=args.start, end_s=args.end)
    streaming, smoothed = _sink_factories(args, source, model)
    sinks = open_sinks(streaming + smoothed)
    tracker = PoseTracker(model, source.fps, TrackerSettings(max_people=args.max_people))
    result = track_video(source, tracker, sinks[:len(streaming)],
                         Progress(source.expected_frames(), quiet=args.quiet),
                         smoothed_sinks=sinks[len(streaming):])
    if not args.quiet:
        _print_summary(args, source, result)
    return EXIT_INTERRUPTED if result.interrupted else 0


def _print_summary(args, source, result: TrackRun) -> None:
    state = "interrupted after" if result.interrupted else "tracked"
    tracks = result.tracker.tracks
    print(f"{args.video.name}: {state} {result.frames} frames ({source.width}x{source.height}, "
          f"{source.fps:g} fps video) at {result.fps:.0f} frames/s; {len(tracks)} track(s)")
    for track_id, state_ in sorted(tracks.items()):
        print(f"  track {track_id}: {len(state_.measured)} frames")
    for path, what in ((args.out, "MCAP"), (args.json, "JSON"), (args.bvh, "BVH folder")):
        if path is not None:
            print(f"  {what}: {path}")


def main(argv=None) -> int:
    """Entry point of the ``track`` console script."""
    args = build_parser().parse_args(argv)
    if not os.environ.get("TRACK_DEBUG"):
        # FFmpeg's own complaints ("moov atom not found") would repeat our one-line error in
        # its words; both variables are read when the first video is opened.
        os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
        os.environ.setdefault("OPENCV_LOG_LEVEL", "OFF")
    # SIGTERM stops like Ctrl-C: outputs are closed, not cut off.
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    try:
        # One BLAS thread: the per-frame matrices are small, and threads cost more than they
        # save (a filter step took 8.7 ms with default threads, 0.5 ms with one).
        with threadpool_limits(1):
            return run(args)
    except SilhouettePoseError as exc:
        print(f"track: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except OSError as exc:
        print(f"track: error: {exc.filename or ''}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print("track: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as exc:  # never a traceback for the user; TRACK_DEBUG=1 shows it
        if os.environ.get("TRACK_DEBUG"):
            raise
        print(f"track: internal error: {type(exc).__name__}: {exc} "
              f"(set TRACK_DEBUG=1 for details)", file=sys.stderr)
        return EXIT_ERROR


if __name__ == "__main__":
    sys.exit(main())
