"""Render CMU motion capture as a test video (mp4) with a ground-truth sidecar.

    python scripts/render_video.py --bvh ../shared/data/cmu/bvh/16_11.bvh --spiral 30 \
        --size 320x240 --out sequences/data/sample_spiral_walk.mp4

Several --bvh give several people (side by side, --spacing metres apart).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


from sequences.body import sample_body_shapes
from sequences.bvh import BVHError, read_bvh
from sequences.spiral import SpiralError, spiral_walk
from sequences.video import Actor, VideoWriteError, write_video
from tracker.one_line_parser import OneLineParser


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must look like 640x480, got {text!r}")
    return h, w


def main(argv=None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bvh", type=Path, action="append", required=True, help="BVH file (repeat)")
    ap.add_argument("--out", type=Path, required=True, help="output .mp4")
    ap.add_argument("--spiral", type=float, default=None, metavar="DEG_PER_S",
                    help="turn each motion into a spiral walk at this turning rate")
    ap.add_argument("--size", type=_size, default=(480, 640), help="WIDTHxHEIGHT (640x480)")
    ap.add_argument("--fps", type=float, default=30.0)
    ap.add_argument("--azimuth", type=float, default=0.0, help="camera azimuth, degrees")
    ap.add_argument("--elevation", type=float, default=8.0, help="camera elevation, degrees")
    ap.add_argument("--distance", type=float, default=9.0, help="camera distance, metres")
    ap.add_argument("--noise", type=float, default=2.0, help="sensor noise sigma, grey levels")
    ap.add_argument("--spacing", type=float, default=2.5, help="metres between people")
    ap.add_argument("--frames", type=int, default=None, help="frames to render (default: all)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    try:
        motions = [read_bvh(p, fps=args.fps) for p in args.bvh]
        if args.spiral is not None:
            motions = [spiral_walk(m, args.spiral) for m in motions]
        shapes = sample_body_shapes(len(motions), seed=args.seed)
        n = len(motions)
        actors = [Actor(m, shape=s, offset_m=((i - (n - 1) / 2) * args.spacing, 0.0))
                  for i, (m, s) in enumerate(zip(motions, shapes))]
        start = time.perf_counter()

        def progress(done: int, total: int) -> None:
            if done % 30 == 0 or done == total:
                print(f"\rframe {done}/{total}", end="", file=sys.stderr, flush=True)

        sidecar = write_video(args.out, actors, size=args.size, fps=args.fps,
                              azimuth_deg=args.azimuth, elevation_deg=args.elevation,
                              distance_m=args.distance, noise_sigma=args.noise, seed=args.seed,
                              n_frames=args.frames, progress=progress)
    except (OSError, BVHError, SpiralError, VideoWriteError) as exc:
        print(f"render_video: error: {exc}", file=sys.stderr)
        return 1
    elapsed = time.perf_counter() - start
    print(f"\nwrote {args.out} ({args.out.stat().st_size / 1e6:.2f} MB) and {sidecar} "
          f"in {elapsed:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
