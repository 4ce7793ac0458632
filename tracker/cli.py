"""The ``track`` command (``track --help``). Errors print one line and exit non-zero; Ctrl-C
stops cleanly, every output so far valid; outputs never overwrite an input or each other, nor
an earlier file until complete. Only the standard library is imported at module level (numpy,
OpenCV and the model inside main(), where a Ctrl-C during their import is caught too)."""
from __future__ import annotations

import argparse
import os
import re
import signal
import sys
import threading
import warnings
from pathlib import Path

from regressor.errors import SilhouettePoseError
from tracker import STOP_SIGNALS

EXIT_ERROR, EXIT_USAGE = 1, 2   # a failed run; argparse's status for a usage error
EXIT_INTERRUPTED = 130          # the shell's status for a run ended by Ctrl-C (128 + SIGINT)
ZONE_FOREGROUND = {"sure": True, "colour": False}   # -> TrackerSettings.trust_zone_foreground
DEFAULT_WORKERS = 2 if (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                        else os.cpu_count() or 1) >= 2 else 1    # 2 with a core to spare
#: Copies (tests keep them equal), so that parsing loads no numpy or OpenCV: video.sources'
#: SOURCES, INSTALL_HINT; fixed_lag's MAX_LAG_S; decode's MAX_FPS; DEFAULT_MIN_AREA_FRACTION %.
SILHOUETTE_SOURCES = ("background", "segment", "auto")
SEGMENT_INSTALL = "pip install 'silhouette-pose[segment]'"
MAX_LAG_S, MAX_FPS, DEFAULT_MIN_AREA_PERCENT = 10.0, 1000.0, 0.15
MAX_ROLL_DEG = 90.0     # --roll beyond a quarter turn: the camera upside down, or a wrong sign
VIEW_LAG_S = 0.5        # --lag when not given, with --view (else 0: the filtered poses at once)
MAX_TIME_S = 1e8        # past any video (3 years); 1e308 s would overflow the frame arithmetic
#: --min-area's range, % of the image: below, specks become people; above, only a fifth counts.
MIN_AREA_RANGE_PERCENT = (0.01, 20.0)
#: What ``track`` alone prints: the usage's first line, and where the rest is.
SHORT_USAGE = ("usage: track VIDEO [--out FILE.mcap] [--json FILE] [--bvh DIR] [--view] "
               "[options]\ntrack: give a video file to track (track --help lists the options)\n")
_URL = re.compile(r"[A-Za-z][A-Za-z0-9+.-]*://")   # rtsp://, ... (Path would drop a /)
#: Stop signals received during main(), also if their KeyboardInterrupt was swallowed.
_interrupts: list[int] = []
_previous_unraisable_hook = sys.unraisablehook


def quiet_decoder_logs() -> None:
    """Keep FFmpeg's and OpenCV's logs off stderr unless TRACK_DEBUG: they repeat our errors."""
    if not os.environ.get("TRACK_DEBUG"):
        os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
        os.environ.setdefault("OPENCV_LOG_LEVEL", "OFF")


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line, ``PROG: error: MESSAGE (see PROG
    --help)``, status 2 (the scripts' version: tracker.one_line_parser)."""

    def error(self, message):
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _record_interrupt(number, frame) -> None:
    """Handler of the stop signals: remember the signal, then interrupt as Ctrl-C does."""
    _interrupts.append(number)
    raise KeyboardInterrupt


def _unraisable_interrupt_recorded(unraisable) -> None:
    """sys.unraisablehook during main(): records a KeyboardInterrupt Python could not raise (a
    weakref callback's, a __del__'s) instead of printing it; passes on anything else."""
    if issubclass(unraisable.exc_type, KeyboardInterrupt):
        _interrupts.append(signal.SIGINT)
        return
    _previous_unraisable_hook(unraisable)


def check_interrupted() -> None:
    """Raise KeyboardInterrupt if a stop signal came during main(), even if it was caught."""
    if _interrupts:
        raise KeyboardInterrupt


class _Progress:
    """A progress bar on stderr (a terminal, no --quiet); then a check for a swallowed stop."""

    def __init__(self, source, quiet: bool):
        self._bar = None
        if not quiet and hasattr(sys.stderr, "isatty") and sys.stderr.isatty():
            from tqdm import tqdm
            total = None if source.end_index is None else source.end_index - source.start_index
            self._bar = tqdm(total=total, unit="frame", file=sys.stderr, dynamic_ncols=True,
                             mininterval=0.25)

    def update(self, people_in_view: int) -> None:
        if self._bar is not None:
            self._bar.update(1)
            self._bar.set_postfix_str(f"people {people_in_view}", refresh=False)
        check_interrupted()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()           # idempotent


class TrackError(SilhouettePoseError):
    """A problem the user can fix (options, paths); printed as one line."""


def _file_name(text: str) -> Path:
    """An output file's path; "-" is standard output; one ending in a slash is refused."""
    if text == "-":
        return Path("/dev/stdout")
    if text.endswith(("/", os.sep)) or os.path.basename(text) in ("", ".", ".."):
        raise argparse.ArgumentTypeError(f"{text} names a folder; give a file name")
    return Path(text)


def _video_file(text: str) -> Path:
    """The video's path; a camera index ("0", no such file) or a URL is refused."""
    if _URL.match(text) or (text.isdigit() and not os.path.exists(text)):
        raise argparse.ArgumentTypeError(f"{text}: cameras and streams are not supported; "
                                         f"give a video file")
    return Path(text)


def build_parser() -> argparse.ArgumentParser:
    from importlib import metadata
    try:
        version = metadata.version("silhouette-pose")
    except metadata.PackageNotFoundError:           # run from a folder never installed
        version = "(version unknown)"
    ap = OneLineParser(prog="track", description="3-D human pose from a static-camera video, "
                       "regressed from each person's silhouette (a mixture of kernel experts "
                       "and limb networks), Kalman-filtered over time.")
    ap.add_argument("video", type=_video_file, help="video file (mp4, avi, ...)")
    ap.add_argument("--version", action="version", version=f"track {version}")
    ap.add_argument("--out", type=_file_name, help="MCAP recording (default VIDEO_STEM.mcap if "
                    "no other output is chosen)")
    ap.add_argument("--bvh", type=Path, metavar="DIR", help="write one BVH per track here")
    ap.add_argument("--json", type=_file_name, metavar="FILE", help="write a JSON summary")
    ap.add_argument("--view", action="store_true", help="live 3-D skeletons in meshcat "
                    "(browser, 127.0.0.1), played at the video's own speed")
    ap.add_argument("--smooth", action=argparse.BooleanOptionalAction, default=True, help="the "
                    "JSON and BVH get each whole track RTS-smoothed, the MCAP gets it beside its "
                    "filtered poses (the default: it follows the body better); --no-smooth: the "
                    "JSON and BVH get the MCAP's poses (filtered, or --lag's)")
    ap.add_argument("--lag", type=float, default=None, metavar="S", help="give the live view and "
                    "the MCAP's /pose (with --no-smooth, the JSON and BVH too) each pose about 2S "
                    "seconds late, smoothed over S seconds that followed it: closer to the body "
                    f"than the filter's; 0: the filtered poses at once (default {VIEW_LAG_S:g} "
                    f"with --view, else 0; at most {MAX_LAG_S:g})")
    ap.add_argument("--model", type=Path, help="model file (default: the shipped model)")
    ap.add_argument("--background", type=Path, metavar="IMAGE", help="an image of the empty "
                    "scene (clean plate) from the same camera (default: learned from the video)")
    ap.add_argument("--max-people", type=int, default=None, metavar="N",
                    help="track at most N people per frame (largest first; 1 to 100)")
    ap.add_argument("--start", type=float, default=0.0, metavar="S", help="start at S seconds")
    ap.add_argument("--end", type=float, default=None, metavar="S", help="stop at S seconds")
    ap.add_argument("--fps", type=float, default=None, metavar="F", help="the video's frame rate, "
                    "frames/s, where its file's is missing or wrong (above 0, at most "
                    f"{MAX_FPS:g}; default: the file's)")
    ap.add_argument("--roll", type=float, default=0.0, metavar="DEG", help="the camera's roll: "
                    "how far the scene's vertical leans clockwise, degrees (silhouettes are turned "
                    f"upright; within +-{MAX_ROLL_DEG:g}; default 0)")
    ap.add_argument("--zone-foreground", choices=tuple(ZONE_FOREGROUND), default="colour",
                    help="for a person who stays in one place: where the background is "
                         "unreliable, let colour decide on the foreground too (default: fewer "
                         "ghost blobs, some thin limb pixels lost), or take it as sure person")
    low, high, default = *MIN_AREA_RANGE_PERCENT, DEFAULT_MIN_AREA_PERCENT
    ap.add_argument("--min-area", type=float, default=None, metavar="PERCENT", help="the "
                    f"smallest person, in percent of the image (default {default:g}: about 55 px "
                    f"tall at 640x480; {low:g} to {high:g}); lower it for people far away, raise "
                    "it against clutter")
    ap.add_argument("--workers", type=int, choices=(1, 2), default=DEFAULT_WORKERS, help="2 finds "
                    "the people in a second process (about 1.7x the frames per second, the same "
                    "poses; not with --view), 1 keeps to one process (default "
                    f"{DEFAULT_WORKERS} on this machine)")
    ap.add_argument("--silhouettes", choices=SILHOUETTE_SOURCES, default="auto", help="background "
                    "subtraction (a still camera, people who move), a person segmenter (needs "
                    f"{SEGMENT_INSTALL}), or auto (default): subtraction, but the segmenter where "
                    "the camera moves or someone stays put (if installed)")
    ap.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    return ap


def _check_options(args) -> None:
    """Refuse bad options and output paths before anything is written (TrackError)."""
    low, high = MIN_AREA_RANGE_PERCENT
    # (option, value, in range, what it must be); NaN and infinities compare out of range.
    for option, value, ok, must in (
            ("--max-people", args.max_people, lambda v: 1 <= v <= 100, "between 1 and 100"),
            ("--roll", args.roll, lambda v: abs(v) <= MAX_ROLL_DEG,
             f"between -{MAX_ROLL_DEG:g} and {MAX_ROLL_DEG:g} degrees"),
            ("--start", args.start, lambda v: 0 <= v <= MAX_TIME_S,
             f"a time in seconds between 0 and {MAX_TIME_S:g}"),
            ("--end", args.end, lambda v: args.start < v <= MAX_TIME_S,
             f"after --start ({args.start} s) and at most {MAX_TIME_S:g} s"),
            ("--fps", args.fps, lambda v: 0 < v <= MAX_FPS,
             f"above 0 and at most {MAX_FPS:g} frames/s"),
            ("--lag", args.lag, lambda v: 0 <= v <= MAX_LAG_S,
             f"between 0 and {MAX_LAG_S:g} seconds"),
            ("--min-area", args.min_area, lambda v: low <= v <= high,
             f"between {low:g} and {high:g} percent of the image")):
        if value is not None and not ok(value):
            raise TrackError(f"{option} must be {must}, got {value}")
    if args.silhouettes == "segment":
        from tracker.video.sources import require_segmenter
        require_segmenter()             # SegmenterMissingError: one line, as TrackError
    if args.background is not None:
        from tracker.clean_plate import check_background_file
        check_background_file(args.background)
    if args.out is None and args.json is None and args.bvh is None and not args.view:
        args.out = Path(args.video.stem + ".mcap")
        if _same_file(args.out, args.video):
            raise TrackError(f"the default output {args.out} would be the input video; choose "
                             f"an output with --out")
    _check_outputs(args)
    if args.bvh is not None:
        from tracker.bvh_option import check_folder
        check_folder(args)


def _check_writable(option: str, path: Path, in_place: bool) -> None:
    """TrackError unless the folder of ``path`` (a symlink's target's) exists and ``path`` can
    be written there; in_place: written as it is (no new file in the folder)."""
    folder = Path(os.path.realpath(path)).parent
    if not folder.is_dir():
        shown = folder if path.is_symlink() else (path.parent if str(path.parent) else ".")
        raise TrackError(f"{option} {path}: folder {shown} does not exist")
    if (not in_place and not os.access(folder, os.W_OK)) or \
            (path.exists() and not os.access(path, os.W_OK)):
        raise TrackError(f"{option} {path}: not writable")


def _same_file(a: Path, b: Path) -> bool:
    from tracker.outputs.files import file_identity
    return file_identity(a) == file_identity(b)


def _check_outputs(args) -> None:
    """--out and --json can be written; no output (nor its temporary file) may be an input or
    another output, also through a relative path, a symlink or a hard link (file_identity)."""
    from regressor.pose_model import DEFAULT_MODEL_PATH
    from tracker.outputs.files import file_identity, partial_path, stream_descriptor
    named = [("the input video", args.video), ("the model", args.model or DEFAULT_MODEL_PATH)]
    if args.background is not None:
        named.append(("the --background image", args.background))
    for path, what in ((args.out, "--out"), (args.json, "--json")):
        if path is not None:
            if path.is_dir():
                raise TrackError(f"{what} {path} is a folder; give a file name")
            # /dev/null, a FIFO, /dev/stdout are written in place (tracker.outputs.files)
            _check_writable(what, path, stream_descriptor(path) is not None
                            or (path.exists() and not path.is_file()))
            named += [(what, path), (f"{what}'s temporary file",
                                     partial_path(os.path.realpath(path)))]
    if args.bvh is not None:
        from tracker.bvh_option import check_names
        check_names(args, named)
        named.append(("the --bvh folder", args.bvh))
    seen: dict[tuple, tuple[str, Path]] = {}
    for what, path in named:
        if (key := file_identity(path)) in seen:
            other, other_path = seen[key]
            raise TrackError(f"{what} {path} is the same file as {other} {other_path}; choose "
                             f"another file name (nothing was written)")
        seen[key] = (what, Path(path))


def tracker_settings(args):
    """The tracker.pipeline.TrackerSettings the parsed options ask for."""
    from tracker.pipeline import TrackerSettings
    # Per-track histories only to smooth: without (--no-smooth --lag 0) memory stays flat.
    return TrackerSettings(max_people=args.max_people, roll_deg=args.roll,
                           keep_history=smoothing(args) or lag_seconds(args) > 0,
                           trust_zone_foreground=ZONE_FOREGROUND[args.zone_foreground],
                           min_area_fraction=_min_area_fraction(args))


def smoothing(args) -> bool:
    """Whether smoothed tracks are written: --smooth and a JSON, BVH or MCAP output."""
    return bool(args.smooth) and any(p is not None for p in (args.out, args.json, args.bvh))


def lag_seconds(args) -> float:
    """The fixed-lag smoothing's lag, seconds (--lag, else VIEW_LAG_S with --view, else 0)."""
    return float(args.lag) if args.lag is not None else VIEW_LAG_S if args.view else 0.0


def streamed_kind(args) -> str:
    """What the poses written frame by frame are: "filtered", or "fixed-lag smoothed"."""
    from tracker.tracks import streamed_kind as kind    # deferred: numpy, OpenCV
    return kind(lag_seconds(args))


def _min_area_fraction(args) -> float:
    """--min-area as a fraction of the image (the default when not given)."""
    return (DEFAULT_MIN_AREA_PERCENT if args.min_area is None else args.min_area) / 100.0


def _sink_factories(args, source, model) -> tuple[list, list]:
    """(factories of the sinks fed every frame, of those fed smoothed tracks at the end), in
    the order open_sinks opens them (the MCAP has two, its frames first)."""
    opened = {}
    # The options that change the silhouettes, for the MCAP's metadata when not their defaults.
    silhouette_options = (("zone_foreground", args.zone_foreground != "colour"
                           and args.zone_foreground), ("roll_deg", args.roll),
                          ("min_area_percent", args.min_area),
                          ("background", args.background and str(args.background)))

    def named(sink, option: str):
        sink.option = option            # a failure's line names the option (problem_line)
        return sink

    def mcap():
        from tracker.outputs.mcap import McapSink
        opened["mcap"] = McapSink(args.out, metadata={
            "video": {"path": str(args.video), "fps": source.fps,
                      "width": source.width, "height": source.height},
            "model": {"path": str(args.model), **model.summary()},
            "settings": {"smooth": smoothing(args), "lag_s": lag_seconds(args),
                         "max_people": args.max_people,
                         "start_s": args.start, "end_s": args.end,
                         **{name: value for name, value in silhouette_options if value},
                         "note": f"/pose and /skeleton hold the {streamed_kind(args)} "
                                 "poses, frame by frame (lag_s: how late, at least, each was "
                                 "written, smoothed over what followed); /smoothed/pose and "
                                 "/smoothed/skeleton (with smooth) each whole track smoothed, "
                                 "written at the end"}})
        return named(opened["mcap"], "--out")

    def mcap_smoothed():
        return named(opened["mcap"].smoothed_channel(), "--out")   # after mcap(), in order

    def json_summary():
        from tracker.outputs.json_summary import JsonSummarySink
        return named(JsonSummarySink(args.json, source.fps, poses="smoothed" if smoothing(args)
                                     else streamed_kind(args)), "--json")

    def bvh():
        from tracker.outputs.bvh import BVHSink
        # Tracks of a few frames are subtraction glitches, not people worth a file.
        return named(BVHSink(args.bvh, source.fps, prefix=args.video.stem, min_frames=5),
                     "--bvh")

    def view():
        from tracker.outputs.meshcat_view import MeshcatView  # deferred: starts a server process
        return named(MeshcatView(realtime=True), "--view")   # played at the video's speed

    # The MCAP's smoothed topics come last: the biggest write, the one the others least need.
    outputs = [(args.out, mcap, False), (args.json, json_summary, True),
               (args.bvh, bvh, True), (args.out if smoothing(args) else None, mcap_smoothed, True),
               (args.view or None, view, False)]
    chosen = [(make, smoothable and smoothing(args)) for option, make, smoothable in outputs
              if option is not None]
    return [m for m, later in chosen if not later], [m for m, later in chosen if later]


def run(args) -> int:
    """Track args.video into the chosen outputs; returns the exit code."""
    # Imported before threadpool_limits, which limits only the BLAS libraries already loaded.
    from threadpoolctl import threadpool_limits

    from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
    from tracker import pipeline  # noqa: F401 (loads numpy, scipy, filterpy, OpenCV)
    from tracker.outputs.files import OutputWriteError
    from tracker.run import BackgroundMismatchError, OutputError
    check_interrupted()
    # One BLAS thread: the per-frame matrices are small, and threads cost more than they save.
    with threadpool_limits(1):
        _check_options(args)
        args.model = args.model or DEFAULT_MODEL_PATH
        model = load_pose_model(args.model)
        if model.gives_canonical_pairs and model.canonical_priors is None:
            warnings.warn(f"{args.model} carries no front/back priors; using the shipped "
                          f"model's, which may not fit its side classifier (add its own: python "
                          f"scripts/learn_hypothesis_priors.py --model {args.model} --save "
                          f"NEW.npz)")
        check_interrupted()                  # the model and its imports are loaded
        source = _open_source(args)
        plate = None
        if args.background:
            from tracker.clean_plate import load_background
            plate = load_background(args.background, source)
        try:
            result, sinks = _track_into_outputs(args, source, model, plate)
        except BackgroundMismatchError as exc:
            raise TrackError(f"--background {args.background}: {exc}") from None
        except (OutputWriteError, OutputError) as exc:
            from tracker.cli_failures import output_failure
            raise TrackError(output_failure(args, exc)) from None
    if not args.quiet:
        try:
            _print_summary(args, source, result, sinks)
        except BrokenPipeError:
            # The reader stopped (``track ... | head -1``): nothing more to it, even at exit.
            sys.stdout = open(os.devnull, "w")
    if result.interrupted:
        return EXIT_INTERRUPTED
    if not result.written:      # no outputs written (write_empty), earlier files kept
        from tracker.cli_failures import nobody_found
        raise nobody_found(args, result.frames, 100 * _min_area_fraction(args))
    return 0


def _track_into_outputs(args, source, model, plate) -> tuple:
    """Open the outputs and track the video into them: (TrackRun, the sinks). A run that
    ends before its first pose leaves every file of the outputs' names as it was."""
    from tracker.pipeline import PoseTracker
    from tracker.run import track_video
    from tracker.video.sources import silhouette_extractor
    from tracker.outputs import close_sinks, open_sinks
    from tracker.outputs.files import OutputBusyError, OutputWriteError
    streaming, smoothed = _sink_factories(args, source, model)
    try:
        sinks = open_sinks(streaming + smoothed)   # a refusal abandons those opened before
    except (OutputBusyError, OutputWriteError) as exc:    # nothing of this run's is kept
        from tracker.cli_failures import output_failure
        raise TrackError(output_failure(args, exc, kept=False)) from None
    try:
        settings = tracker_settings(args)
        tracker = PoseTracker(model, source.fps, settings,
                              extractor=silhouette_extractor(args.silhouettes, settings))
        result = track_video(source, tracker, sinks[:len(streaming)],
                             _Progress(source, args.quiet),
                             smoothed_sinks=sinks[len(streaming):], background=plate,
                             workers=args.workers, lag_s=lag_seconds(args), write_empty=False)
    except BaseException:
        # Those track_video never took are abandoned (the MCAP's finalizer would finish it).
        close_sinks(sinks, abandon=True)
        raise
    return result, sinks


def _open_source(args):
    """The video opened with --start, --end and --fps (a time range outside it: TrackError)."""
    from tracker.video.decode import VideoError, open_video
    try:
        return open_video(args.video, start_s=args.start, end_s=args.end, fps=args.fps)
    except VideoError:
        if args.start == 0 and args.end is None:
            raise
    from tracker.cli_failures import time_range_error
    raise time_range_error(args)


def _print_summary(args, source, result, sinks=()) -> None:
    """The run's summary: what was tracked, and which poses each output holds."""
    from tracker.outputs.files import stream_descriptor
    # With an output on standard output (--json /dev/stdout | jq) the summary goes to stderr.
    out = sys.stderr if any(path is not None and stream_descriptor(path) == 1
                            for path in (args.out, args.json)) else sys.stdout
    state = "interrupted after" if result.interrupted else "tracked"
    tracks = result.written         # what the outputs hold (not the tracker's last batch)
    print(f"{args.video.name}: {state} {result.frames} frames ({source.width}x{source.height}, "
          f"{source.fps:g} fps video) at {result.fps:.0f} frames/s; {len(tracks)} track(s)",
          file=out)
    for track_id, counts in sorted(tracks.items()):
        unfamiliar = (f"; {counts.unfamiliar} of them ({counts.unfamiliar / counts.poses:.0%}) "
                      f"unlike the training silhouettes, their poses extrapolated"
                      if counts.unfamiliar else "")
        print(f"  track {track_id}: {counts.poses} frames{unfamiliar}", file=out)
    if not tracks:          # nothing written (the nobody-found error follows unless stopped)
        if result.interrupted:
            from tracker.cli_failures import nothing_written
            print(f"  {nothing_written(args)}", file=out)
        return
    # The JSON and BVH hold the smoothed poses, or after a quick exit those streamed.
    streamed = streamed_kind(args)
    kind = "smoothed" if result.smoothed else streamed
    mcap_kind = f"{streamed} + smoothed" if result.smoothed else streamed
    for path, what, poses in ((args.out, "MCAP", mcap_kind), (args.json, "JSON", kind)):
        if path is not None:
            print(f"  {what} ({poses} poses): {path}", file=out)
    if args.bvh is not None:
        from tracker.bvh_option import files_tail, written_files
        tail = files_tail(args.bvh, args.video.stem, written_files(sinks))
        print(f"  BVH folder ({kind} poses): {args.bvh}{tail}", file=out)


def one_line_warning(prog: str):
    """A warnings.showwarning that prints "PROG: warning: MESSAGE", without the source line."""
    def show(message, category, filename, lineno, file=None, line=None) -> None:
        print(f"{prog}: warning: {message}", file=sys.stderr)
    return show


def main(argv=None) -> int:
    """Entry point of the ``track`` console script."""
    # SIGTERM and SIGHUP stop like Ctrl-C, unless ignored (nohup); main thread only.
    global _previous_unraisable_hook
    _interrupts.clear()
    previous = ({number: signal.getsignal(number) for number in STOP_SIGNALS}
                if threading.current_thread() is threading.main_thread() else {})
    for number, handler in previous.items():
        if handler != signal.SIG_IGN:
            signal.signal(number, _record_interrupt)
    if previous:
        _previous_unraisable_hook, sys.unraisablehook = (sys.unraisablehook,
                                                          _unraisable_interrupt_recorded)
    try:
        parser = build_parser()
        if not (sys.argv[1:] if argv is None else argv):
            parser.exit(EXIT_USAGE, SHORT_USAGE)    # ``track`` alone: what to give it
        args = parser.parse_args(argv)
        quiet_decoder_logs()            # before the first video is opened
        with warnings.catch_warnings():
            warnings.showwarning = one_line_warning("track")
            return run(args)
    except SilhouettePoseError as exc:
        print(f"track: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"track: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:            # also during the first second's imports
        print("track: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as exc:  # never a traceback for the user; TRACK_DEBUG=1 shows it
        if os.environ.get("TRACK_DEBUG"):
            raise
        print(f"track: internal error: {type(exc).__name__}: {exc} "
              f"(set TRACK_DEBUG=1 for details)", file=sys.stderr)
        return EXIT_ERROR
    finally:
        for number, handler in previous.items():
            if handler is not None:
                signal.signal(number, handler)
        if previous:
            sys.unraisablehook = _previous_unraisable_hook
        _interrupts.clear()


if __name__ == "__main__":
    sys.exit(main())
