"""``track --bvh DIR``: the folder's checks before the run and the summary's BVH files;
loaded only with --bvh."""
from __future__ import annotations

import glob
import os
import re
from pathlib import Path

from tracker.cli import TrackError, _check_writable, _same_file


def check_names(args, named: list[tuple[str, Path]]) -> None:
    """TrackError if a ``named`` (what, path) file could be a BVH, partial or lock file in --bvh."""
    bvh_names = re.compile(rf"\.?{re.escape(args.video.stem)}(_\d+\.bvh(\.partial)?|"
                           rf"\.bvh\.lock)")
    for what, path in named:
        if path.name and bvh_names.fullmatch(path.name) and \
                _same_file(path.parent if str(path.parent) else Path("."), args.bvh):
            raise TrackError(f"{what} {path} may be overwritten by the BVH files in "
                             f"--bvh {args.bvh}; choose another name or folder")


def check_folder(args) -> None:
    """--bvh names a folder, made by the BVH sink if missing, but only one level, in a folder
    that exists; the video's name must leave its files' names within the file system's."""
    if args.bvh.exists() and not args.bvh.is_dir():
        raise TrackError(f"--bvh {args.bvh} exists and is not a folder")
    _check_writable("--bvh", args.bvh, in_place=args.bvh.is_dir())
    first = f"{args.video.stem}_0.bvh"
    if len(os.fsencode(first)) > 255:           # the file system's longest name, bytes
        raise TrackError(f"--bvh {args.bvh}: the video's name is too long for its tracks' "
                         f"BVH files (VIDEO_STEM_0.bvh would be {len(os.fsencode(first))} "
                         f"bytes, over 255); rename or link the video shorter")


def written_files(sinks) -> list[Path] | None:
    """The BVH files the run's BVH sink wrote, by track id (None without one)."""
    from tracker.outputs.bvh import BVHSink
    return next(([path for _, path in sorted(sink.paths.items())]
                 for sink in sinks if isinstance(sink, BVHSink)), None)


def files_tail(folder: Path, stem: str, written: list[Path] | None) -> str:
    """The BVH line's tail: the files this run wrote and those of the video's name it did not
    (an earlier run's, with more tracks: they stay, and would pass for this run's)."""
    if written is None:
        return ""

    def names(paths: list[Path]) -> str:
        shown = ", ".join(p.name for p in paths[:3])
        return shown + (f" and {len(paths) - 3} more" if len(paths) > 3 else "")
    pattern = re.compile(rf"{re.escape(stem)}_(\d+)\.bvh")
    mine = {p.name for p in written}
    older = sorted((p for p in folder.glob(f"{glob.escape(stem)}_*.bvh")
                    if pattern.fullmatch(p.name) and p.name not in mine),
                   key=lambda p: int(pattern.fullmatch(p.name).group(1)))   # by track number
    tail = f" ({names(written)})" if written else " (no track long enough for a file)"
    if older:
        tail += f"; also there from an earlier run, not replaced: {names(older)}"
    return tail
