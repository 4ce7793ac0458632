"""Render CMU motion capture as a test video (mp4) with a ground-truth sidecar.

    python scripts/render_video.py --bvh ../shared/data/cmu/bvh/16_11.bvh --spiral 30 \
        --size 320x240 --out sequences/data/sample_spiral_walk.mp4

Several --bvh give several people (side by side, --spacing metres apart).
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path


from regressor.errors import SilhouettePoseError
from sequences.body import Skinner, load_body, sample_body_shapes
from sequences.bvh import BVHError, read_bvh
from sequences.spiral import spiral_walk
from sequences.video import (VIDEO_SUFFIXES, Actor, partial_video, replace_video, truth_path,
                             write_video)
from tracker.one_line_parser import EXIT_INTERRUPTED, OneLineParser

MAX_PEOPLE = 10
MAX_FRAMES = 20_000        # write_video holds every frame's posed vertices (60 kB a person)


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must look like 640x480, got {text!r}")
    return h, w


def _check_options(ap: OneLineParser, args) -> None:
    """Refuse absurd options and unusable files in one line, before reading any BVH: every
    number finite and within what the camera, the writer and memory allow, the BVH files
    present, the video and its sidecar (and their temporary names) writable and none of them
    a BVH file or each other."""
    bounds = (("--fps", args.fps, 1, 240, "frames per second"),
              ("--azimuth", args.azimuth, -360, 360, "degrees"),
              ("--distance", args.distance, 0.1, 1000, "metres"),
              ("--noise", args.noise, 0, 50, "grey levels"),
              ("--spacing", args.spacing, 0, 20, "metres"))
    for flag, value, low, high, unit in bounds:
        if not (math.isfinite(value) and low <= value <= high):
            ap.error(f"{flag} must be within {low:g}..{high:g} {unit}, got {value}")
    # sequences.render.look_at_camera's limit: at +-90 the camera's up direction is undefined.
    if not (math.isfinite(args.elevation) and -89 < args.elevation < 89):
        ap.error(f"--elevation must be strictly between -89 and 89 degrees, got "
                 f"{args.elevation}")
    if args.spiral is not None and not (math.isfinite(args.spiral) and abs(args.spiral) <= 720):
        ap.error(f"--spiral must be within -720..720 degrees per second, got {args.spiral}")
    if not all(16 <= side <= 4096 for side in args.size):
        ap.error(f"--size must be within 16..4096 pixels each side, got "
                 f"{args.size[1]}x{args.size[0]}")
    if args.frames is not None and not 1 <= args.frames <= MAX_FRAMES:
        ap.error(f"--frames must be within 1..{MAX_FRAMES}, got {args.frames}")
    if not 0 <= args.seed < 2**32:
        ap.error(f"--seed must be within 0..{2**32 - 1}, got {args.seed}")
    if len(args.bvh) > MAX_PEOPLE:
        ap.error(f"at most {MAX_PEOPLE} --bvh (people), got {len(args.bvh)}")
    for path in args.bvh:       # (the same motion twice is two people doing it)
        if not path.is_file():
            ap.error(f"--bvh {path}: no such file")
    inputs = [("--bvh", path) for path in args.bvh]
    if args.out.suffix.lower() not in VIDEO_SUFFIXES and not args.out.is_dir():
        ap.error(f"--out {args.out}: give a video name ending in "
                 f"{', '.join(VIDEO_SUFFIXES)}")
    partial = partial_video(args.out)
    ap.check_outputs([("--out", args.out), ("its ground-truth sidecar", truth_path(args.out)),
                      ("the temporary video", partial),
                      ("the temporary sidecar", truth_path(partial))], inputs)
    for path in (args.out, truth_path(args.out)):
        if path.exists() and not path.is_file():
            ap.error(f"{path} exists and is not a regular file; choose another --out")


class MotionInputError(SilhouettePoseError, ValueError):
    """A --bvh file that cannot be rendered; one line naming the file."""


def read_motions(paths: list[Path], fps: float, spiral: float | None) -> list:
    """The motions of the --bvh files at fps (spiral walks at that rate unless None), each
    checked against the body model's skeleton now, so a bad file is named before any
    rendering. MotionInputError naming the file for anything unusable."""
    body = load_body()
    motions = []
    for path in paths:
        try:
            motion = read_bvh(path, fps=fps)
        except BVHError:
            raise                   # names the file and line already
        except (ValueError, MemoryError) as exc:
            # e.g. a Frame Time of 1e300: numpy refuses the resampled frame count.
            raise MotionInputError(f"--bvh {path}: cannot read it at {fps:g} fps "
                                   f"({exc or type(exc).__name__})") from None
        try:
            if spiral is not None:
                motion = spiral_walk(motion, spiral)
            Skinner(body, offsets=motion.offsets, names=motion.names,
                    end_sites=motion.end_sites)
        except (SilhouettePoseError, ValueError) as exc:
            raise MotionInputError(f"--bvh {path}: {exc}") from None
        motions.append(motion)
    return motions


def main(argv=None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bvh", type=Path, action="append", required=True, help="BVH file (repeat)")
    ap.add_argument("--out", type=Path, required=True,
                    help="output video (.mp4; the sidecar OUT.truth.npz is written beside it)")
    ap.add_argument("--spiral", type=float, default=None, metavar="DEG_PER_S",
                    help="turn each motion into a spiral walk at this turning rate")
    ap.add_argument("--size", type=_size, default=(480, 640), help="WIDTHxHEIGHT (640x480)")
    ap.add_argument("--fps", type=float, default=30.0, help="frames per second, 1..240")
    ap.add_argument("--azimuth", type=float, default=0.0, help="camera azimuth, degrees")
    ap.add_argument("--elevation", type=float, default=8.0,
                    help="camera elevation, degrees, strictly between -89 and 89")
    ap.add_argument("--distance", type=float, default=9.0, help="camera distance, metres")
    ap.add_argument("--noise", type=float, default=2.0, help="sensor noise sigma, grey levels")
    ap.add_argument("--spacing", type=float, default=2.5, help="metres between people")
    ap.add_argument("--frames", type=int, default=None, help="frames to render (default: all)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    _check_options(ap, args)
    shown = []                  # progress printed: end its line before a message

    def progress(done: int, total: int) -> None:
        if done % 30 == 0 or done == total:
            print(f"\rframe {done}/{total}", end="", file=sys.stderr, flush=True)
            shown.append(True)

    def say(message: str) -> None:
        print(("\n" if shown else "") + f"render_video: {message}", file=sys.stderr)

    try:
        motions = read_motions(args.bvh, args.fps, args.spiral)
        shapes = sample_body_shapes(len(motions), seed=args.seed)
        n = len(motions)
        actors = [Actor(m, shape=s, offset_m=((i - (n - 1) / 2) * args.spacing, 0.0))
                  for i, (m, s) in enumerate(zip(motions, shapes))]
        start = time.perf_counter()
        # Written under temporary names and renamed at the end, so a failed or interrupted
        # run leaves the previous video and its sidecar as they were.
        replace_video(args.out, lambda partial: write_video(
            partial, actors, size=args.size, fps=args.fps, azimuth_deg=args.azimuth,
            elevation_deg=args.elevation, distance_m=args.distance, noise_sigma=args.noise,
            seed=args.seed, n_frames=args.frames, progress=progress))
    except KeyboardInterrupt:
        say(f"interrupted; nothing written ({args.out} is as it was)")
        return EXIT_INTERRUPTED
    # MemoryError: many people or frames at a large size.
    except (OSError, SilhouettePoseError, ValueError, MemoryError) as exc:
        say(f"error: {' '.join(str(exc).split()) or type(exc).__name__}")
        return 1
    elapsed = time.perf_counter() - start
    print(f"\nwrote {args.out} ({args.out.stat().st_size / 1e6:.2f} MB) and "
          f"{truth_path(args.out)} in {elapsed:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
