"""Measure silhouette throughput on one core: skinning + projection + rasterization.

    OMP_NUM_THREADS=1 python scripts/bench_render.py [--frames 400] [--person-px 240]

Poses the body with random joint rotations (no data needed), aims a centred camera at it from a
random azimuth/elevation and fills the mask; prints masks per second.
"""
from __future__ import annotations

import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from sequences.body import Skinner, load_body
from sequences.render import centred_camera, silhouette_mask
from tracker.one_line_parser import OneLineParser


def main() -> None:
    parser = OneLineParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=400)
    parser.add_argument("--person-px", type=float, default=240.0)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    cv2.setNumThreads(1)
    rng = np.random.default_rng(args.seed)
    body = load_body()
    skinner = Skinner(body)
    J = len(body.joint_names)
    # Moderate random poses: rotation vectors of up to ~30 degrees per joint.
    rotations = Rotation.from_rotvec(rng.normal(0, 0.3, (args.frames * J, 3))).as_matrix()
    rotations = rotations.reshape(args.frames, J, 3, 3)
    azimuth = rng.uniform(0, 360, args.frames)
    elevation = rng.uniform(-10, 40, args.frames)
    size = (int(args.person_px * 1.3), int(args.person_px * 1.3))
    root = skinner.rest_root_m
    area = 0
    start = time.perf_counter()
    for t in range(args.frames):
        vertices = skinner.pose(rotations[t], root)
        camera = centred_camera(vertices, azimuth[t], elevation[t], size, args.person_px)
        area += silhouette_mask(vertices, body.faces, body.patch_start, camera).sum()
    elapsed = time.perf_counter() - start
    print(f"{args.frames / elapsed:.0f} masks/s ({len(body.vertices)} vertices, "
          f"{len(body.faces)} triangles, {size[0]}x{size[1]} masks, person {args.person_px:.0f} "
          f"px, mean area {area / args.frames:.0f} px, one thread)")


if __name__ == "__main__":
    main()
