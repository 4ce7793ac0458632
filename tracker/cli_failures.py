"""The messages of ``track`` runs that fail, in the options' terms: an output that could not
be written, a time range outside the video, nobody found. Loaded only then."""
from __future__ import annotations

import math
import os
from pathlib import Path

from tracker.cli import TrackError
from tracker.outputs.files import partial_path, stream_descriptor
from tracker.video.decode import open_video


def time_range_error(args) -> TrackError:
    """Why --start/--end give no frames of args.video (a fault of the file raises here)."""
    whole = open_video(args.video, fps=args.fps)
    count = whole.frame_count
    # The first frame as tracker.video.decode.open_video numbers it.
    if count is not None and math.floor(args.start * whole.fps + 1e-9) >= count:
        return TrackError(f"--start {args.start:g} s is past the end of {args.video} "
                          f"({count / whole.fps:.2f} s, {count} frames at {whole.fps:g} fps)")
    end = "its end" if args.end is None else f"--end {args.end:g} s"
    return TrackError(f"no frames in the chosen time range of {args.video} (--start "
                      f"{args.start:g} s to {end} at {whole.fps:g} fps)")


def nobody_found(args, frames: int, min_area_percent: float) -> TrackError:
    """The error of a run that tracked nobody in its ``frames`` frames (nothing written)."""
    return TrackError(f"{args.video}: nobody found in its {frames} frames (a person must move "
                      f"against a still background and cover at least {min_area_percent:g} % "
                      f"of the image: --min-area); {nothing_written(args)}")


def nothing_written(args) -> str:
    """The end of the nobody-found error: what became of the outputs asked for."""
    if args.out is None and args.json is None and args.bvh is None:
        return "nothing to show"
    return "no output files written (files already of those names are left as they were)"


def _output_option(args, path: Path | None) -> str | None:
    """The option whose output ``path`` is (the file, its partial file, a BVH file or lock
    in the --bvh folder), None if none's."""
    if path is None:
        return None
    real = os.path.realpath(path)
    for option, given in (("--out", args.out), ("--json", args.json)):
        if given is not None:
            target = os.path.realpath(given)
            if real in (target, os.path.realpath(partial_path(target))):
                return option
    if args.bvh is not None and os.path.dirname(real) == os.path.realpath(args.bvh):
        return "--bvh"
    return None


def output_failure(args, exc, kept: bool = True) -> str:
    """An output's failure (OutputWriteError, OutputBusyError, or OutputError from closing)
    in the user's terms: its option and, with ``kept``, where the MCAP's recording so far is
    kept when it is (tracker.outputs.mcap keeps its partial file on a full disk)."""
    option = _output_option(args, getattr(exc, "path", None))
    message = f"{option} {exc}" if option else str(exc)
    kept = _kept_recording(args) if kept else None
    if kept is not None and str(kept) not in message:
        message += (f"; the recording so far is kept in {kept} "
                    f"(tracker.outputs.mcap_repair.recover_mcap makes a readable file of it)")
    return message


def _kept_recording(args) -> Path | None:
    """The --out MCAP's partial file when a failed run left one holding data, else None."""
    if args.out is None:
        return None
    if stream_descriptor(args.out) is not None or (args.out.exists()
                                                   and not args.out.is_file()):
        return None
    partial = partial_path(os.path.realpath(args.out))
    try:
        if not (partial.is_file() and partial.stat().st_size > 0):
            return None
    except OSError:
        return None
    # Shown as the user named the output, unless it is a link (written beside its target).
    return partial if args.out.is_symlink() else partial_path(args.out)
