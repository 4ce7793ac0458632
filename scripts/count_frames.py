"""Parse every BVH file in a folder and print its frame count at a chosen rate and parse time.

    python scripts/count_frames.py [folder] [--fps 30]

The folder defaults to ../shared/data/cmu/bvh beside the repository. A folder that does not
exist or is a file, and an --fps outside 1..240, are refused in one line (exit 2); files that
cannot be read are listed as ERROR and make the exit status 1.
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from sequences.bvh import BVHError, read_bvh
from tracker.one_line_parser import OneLineParser, stops_in_one_line


def _main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", nargs="?", type=Path,
                        default=ROOT.parent / "shared" / "data" / "cmu" / "bvh",
                        help="folder of .bvh files (default: ../shared/data/cmu/bvh beside the "
                             "repository)")
    parser.add_argument("--fps", type=float, default=30.0,
                        help="target frame rate, 1..240 (default 30)")
    args = parser.parse_args(argv)
    if not (math.isfinite(args.fps) and 1 <= args.fps <= 240):
        parser.error(f"--fps must be within 1..240 frames per second, got {args.fps}")
    if not args.folder.is_dir():
        parser.error(f"{args.folder}: " + ("is a file, not a folder" if args.folder.exists()
                                           else "no such folder"))
    paths = sorted(args.folder.glob("*.bvh"))
    if not paths:
        print(f"no .bvh files in {args.folder}", file=sys.stderr)
        return 1
    total_frames, total_seconds, failures = 0, 0.0, 0
    for path in paths:
        start = time.perf_counter()
        try:
            motion = read_bvh(path, fps=args.fps)
        except (BVHError, OSError) as error:    # OSError: a folder named *.bvh, unreadable
            print(f"{path.name:<12} ERROR {getattr(error, 'strerror', None) or error}")
            failures += 1
            continue
        seconds = time.perf_counter() - start
        total_frames += motion.n_frames
        total_seconds += seconds
        print(f"{path.name:<12} {motion.n_frames:6d} frames  {seconds * 1000:7.1f} ms")
    print(f"{len(paths)} files, {total_frames} frames at {args.fps:g} fps "
          f"({total_frames / args.fps / 60:.1f} min of motion), parsed in {total_seconds:.2f} s"
          + (f", {failures} failed" if failures else ""))
    return 1 if failures else 0


main = stops_in_one_line("count_frames", _main)       # Ctrl-C: one line, exit 130


if __name__ == "__main__":
    sys.exit(main())
