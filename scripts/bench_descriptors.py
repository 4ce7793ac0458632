"""Time the silhouette descriptor (mask -> 100-D histogram) on synthetic person-like masks.

Run single-threaded for a per-core figure:
    OMP_NUM_THREADS=1 python scripts/bench_descriptors.py [--count 200] [--height 240]
Prints milliseconds per silhouette end to end and per stage (edge sampling, shape contexts,
soft voting). The codebook is fitted on a separate batch first and is not timed.
"""
from __future__ import annotations

import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")  # before numpy loads its BLAS

import cv2
import numpy as np

from regressor.codebook import soft_histogram
from regressor.descriptor import DescriptorSettings, descriptor_for_mask
from regressor.training import fit_codebook_for_masks
from regressor.edges import sample_edge_points
from regressor.shape_context import shape_contexts
from tracker.one_line_parser import OneLineParser


def _limb(mask: np.ndarray, start: np.ndarray, angle_deg: float, length: float, width: float) -> np.ndarray:
    """Draw a limb (thick line) from start at angle_deg (0 = down, positive = towards +x); return its end."""
    a = np.radians(angle_deg)
    end = start + length * np.array([np.sin(a), np.cos(a)])
    cv2.line(mask, tuple(int(v) for v in start), tuple(int(v) for v in end), 1, max(int(width), 1))
    return end


def person_mask(height: int, rng: np.random.Generator) -> np.ndarray:
    """A person-like (height, ~0.6 height) uint8 silhouette: head, torso, two jointed arms and legs
    at random angles (walking / reaching-like)."""
    h = float(height)
    mask = np.zeros((height, int(0.75 * h)), np.uint8)
    cx = mask.shape[1] / 2
    cv2.ellipse(mask, (int(cx), int(0.07 * h)), (int(0.045 * h), int(0.06 * h)), 0, 0, 360, 1, -1)
    cv2.ellipse(mask, (int(cx), int(0.30 * h)), (int(0.08 * h), int(0.17 * h)), 0, 0, 360, 1, -1)
    for side in (-1, 1):
        shoulder = np.array([cx + side * 0.07 * h, 0.17 * h])
        elbow = _limb(mask, shoulder, side * rng.uniform(5, 80), 0.15 * h, 0.045 * h)
        _limb(mask, elbow, side * rng.uniform(0, 60), 0.14 * h, 0.035 * h)
        hip = np.array([cx + side * 0.04 * h, 0.45 * h])
        knee = _limb(mask, hip, rng.uniform(-25, 25), 0.24 * h, 0.06 * h)
        _limb(mask, knee, rng.uniform(-20, 20), 0.25 * h, 0.05 * h)
    return mask


def _time_stages(masks, settings, codebook) -> np.ndarray:
    """Seconds per mask for (edges, contexts, voting), shape (len(masks), 3)."""
    out = np.empty((len(masks), 3))
    for i, m in enumerate(masks):
        t0 = time.perf_counter()
        pts = sample_edge_points(m, settings.n_points, settings.include_holes)
        t1 = time.perf_counter()
        ctx = shape_contexts(pts, settings.n_angular, settings.n_radial, settings.r_inner, settings.r_outer)
        t2 = time.perf_counter()
        soft_histogram(ctx, codebook, settings.n_votes, settings.total)
        t3 = time.perf_counter()
        out[i] = (t1 - t0, t2 - t1, t3 - t2)
    return out


def main() -> None:
    parser = OneLineParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=200, help="silhouettes timed")
    parser.add_argument("--height", type=int, default=240, help="silhouette height in pixels")
    parser.add_argument("--points", type=int, default=DescriptorSettings.n_points, help="edge points")
    parser.add_argument("--repeats", type=int, default=5, help="timed passes over the batch")
    parser.add_argument("--holes", action="store_true", help="also sample hole boundaries")
    args = parser.parse_args()

    settings = DescriptorSettings(n_points=args.points, include_holes=args.holes)
    rng = np.random.default_rng(0)
    train = [person_mask(args.height, rng) for _ in range(200)]
    codebook = fit_codebook_for_masks(train, settings, n_centres=100, seed=0)
    masks = [person_mask(args.height, rng) for _ in range(args.count)]

    for m in masks[:5]:  # warm-up
        descriptor_for_mask(m, settings, codebook)
    # The machine may be shared: repeat the batch and report the median and best pass.
    passes = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        for m in masks:
            descriptor_for_mask(m, settings, codebook)
        passes.append((time.perf_counter() - t0) / len(masks))
    stages = np.median([_time_stages(masks, settings, codebook).mean(axis=0) for _ in range(args.repeats)], axis=0)

    print(f"{len(masks)} silhouettes {args.height} px tall, {settings.n_points} edge points, "
          f"holes={settings.include_holes}, OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}")
    print(f"end to end: {np.median(passes) * 1e3:.3f} ms per silhouette "
          f"(median of {args.repeats} passes; best {min(passes) * 1e3:.3f} ms)")
    for name, sec in zip(("edge sampling", "shape contexts", "soft voting"), stages):
        print(f"  {name:15s} {sec * 1e3:.3f} ms")


if __name__ == "__main__":
    main()
