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
import time
from pathlib import Path


from regressor.pose_model import DEFAULT_MODEL_PATH, PoseModelError, load_pose_model
from .bvh_sink import BVHSink
from .filtering import FilterError
from .json_summary import JsonSummarySink
from .mcap_sink import McapSink
from .pipeline import PoseTracker, TrackedPose
from .progress import Progress
from .silhouettes import median_background
from .skeleton_geometry import SinkInputError
from .video import VideoError, open_video

EXIT_ERROR, EXIT_USAGE, EXIT_INTERRUPTED = 1, 2, 130
_BACKGROUND_SAMPLES = 25        # frames spread over the video for the median background


class TrackError(Exception):
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


def _open_sinks(args, source, model) -> tuple[list, list]:
    """(streaming sinks fed every frame, offline sinks fed at the end when --smooth)."""
    streaming, offline = [], []
    try:
        if args.out is not None:
            streaming.append(McapSink(args.out, metadata={
                "video": {"path": str(args.video), "fps": source.fps,
                          "width": source.width, "height": source.height},
                "model": {"path": str(args.model), **model.summary()},
                "settings": {"smooth": args.smooth, "max_people": args.max_people,
                             "start_s": args.start, "end_s": args.end,
                             "note": "MCAP holds filtered (not smoothed) poses"}}))
        later = offline if args.smooth else streaming
        if args.json is not None:
            later.append(JsonSummarySink(args.json, source.fps))
        if args.bvh is not None:
            # Tracks of a few frames are subtraction glitches, not people worth a file.
            later.append(BVHSink(args.bvh, source.fps, prefix=args.video.stem, min_frames=5))
        if args.view:
            from .meshcat_view import MeshcatView  # deferred: starts a server process
            streaming.append(MeshcatView())
    except BaseException:
        _close_all(streaming + offline)
        raise
    return streaming, offline


def _close_all(sinks) -> list[str]:
    problems = []
    for sink in sinks:
        try:
            sink.close()
        except Exception as exc:  # keep closing the others: each holds the user's results
            problems.append(f"{type(sink).__name__}: {exc}")
    return problems


def _write(sinks, pose: TrackedPose, filtered=None) -> None:
    for sink in sinks:
        sink.write(pose.frame_index, pose.time_s, pose.track_id, pose.raw,
                   pose.filtered if filtered is None else filtered, pose.ambiguous,
                   pose.joints_m, centroid_px=pose.centroid_px)


def _smooth_tracks(tracker: PoseTracker, records: dict[int, list[TrackedPose]], sinks) -> None:
    """RTS-smooth every track's raw poses and feed them to the offline sinks in frame order."""
    smoothed = {track_id: tracker.smoothed_track(track_id) for track_id in records}
    order = sorted((p.frame_index, tid, i) for tid, ps in records.items() for i, p in enumerate(ps))
    for _, track_id, i in order:
        _write(sinks, records[track_id][i], smoothed[track_id][i])


def run(args) -> int:
    """Track args.video into the chosen outputs; returns the exit code."""
    _check_options(args)
    model = load_pose_model(args.model)
    source = open_video(args.video, start_s=args.start, end_s=args.end)
    streaming, offline = _open_sinks(args, source, model)
    tracker = PoseTracker(model, source.fps, (source.width, source.height),
                          max_people=args.max_people)
    tracker.prime(median_background(source.sample_frames(_BACKGROUND_SAMPLES)))
    records: dict[int, list[TrackedPose]] = {}
    summaries = [s for s in streaming + offline if isinstance(s, JsonSummarySink)]
    progress = Progress(source.expected_frames(), quiet=args.quiet)
    frames, interrupted, started = 0, False, time.perf_counter()
    try:
        for index, time_s, frame in source:
            if args.view:   # tracking outruns the video: show it at its own speed
                ahead = (time_s - args.start) - (time.perf_counter() - started)
                if ahead > 0:
                    time.sleep(ahead)
            poses = tracker.process(index, time_s, frame)
            for summary in summaries:       # frames with nobody in view count too
                summary.mark_frame(index)
            for pose in poses:
                _write(streaming, pose)
                if args.smooth:
                    records.setdefault(pose.track_id, []).append(pose)
            frames += 1
            progress.update(len(poses))
    except KeyboardInterrupt:
        interrupted = True
    finally:
        progress.close()
        if not interrupted and args.smooth:
            _smooth_tracks(tracker, records, offline)
        problems = _close_all(streaming + offline)
    elapsed = time.perf_counter() - started
    if problems:
        raise TrackError("could not finish outputs: " + "; ".join(problems))
    if not args.quiet:
        _print_summary(args, source, tracker, frames, elapsed, interrupted)
    return EXIT_INTERRUPTED if interrupted else 0


def _print_summary(args, source, tracker, frames, elapsed, interrupted) -> None:
    state = "interrupted after" if interrupted else "tracked"
    fps = frames / elapsed if elapsed > 0 else 0.0
    print(f"{args.video.name}: {state} {frames} frames ({source.width}x{source.height}, "
          f"{source.fps:g} fps video) at {fps:.0f} frames/s; {len(tracker.tracks)} track(s)")
    for track_id, state_ in sorted(tracker.tracks.items()):
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
        from threadpoolctl import threadpool_limits
    except ImportError:                      # pragma: no cover - declared dependency
        threadpool_limits = None
    try:
        # One BLAS thread: the per-frame matrices are small, and threads cost more than they
        # save (a filter step took 8.7 ms with default threads, 0.5 ms with one).
        if threadpool_limits is not None:
            with threadpool_limits(1):
                return run(args)
        return run(args)
    except (TrackError, VideoError, PoseModelError, SinkInputError, FilterError) as exc:
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
