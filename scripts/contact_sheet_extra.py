"""Contact sheets of the converted cmu_extra motion beside a ../cmu walk, as stick figures.

    python scripts/contact_sheet_extra.py [--data DIR] [--cmu-walk BVH] [--out-dir docs]

Writes docs/cmu_extra_expmap.png and docs/cmu_extra_dances.png: one row per sequence, a few
frames spread over it, drawn in metres at one scale for every row (the ../cmu walk 02_01 is
the first row), front view with the heading turned to face the viewer (the body's left, red,
on the image's right), the floor at height 0 (feet settled on it as the converter does:
sequences.cmu_extra.settle_on_floor). Each row is labelled with its duration and median
ground speed at 30 fps, so units, up axis, left/right and speed can be checked by eye.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402 (after the backend is chosen)
import numpy as np

from sequences.bvh import read_bvh
from sequences.cmu_extra import settle_on_floor
from sequences.expmap import read_expmap_motion
from sequences.pose_conversions import motion_to_pose_vectors
from sequences.pose_vector import joint_positions
from sequences.retarget import read_dance
from sequences.skeleton import BONES_FOR_DRAWING, CMU_UNIT_M, POSE_JOINTS
from tracker.one_line_parser import OneLineParser, stops_in_one_line

ROOT = Path(__file__).resolve().parents[1]

COLUMNS = 8
SPACING_M = 1.1
EXPMAP_ROWS = ("train/basketball_signal/basketball_signal_1.txt",
               "train/directing_traffic/directing_traffic_1.txt",
               "train/jumping/jumping_2.txt", "train/soccer/soccer_1.txt",
               "test/washwindow/washwindow_1.txt", "train/walking_extra/walking_20.txt",
               "train/running/running_1.txt")
DANCE_ROWS = ("salsa/01.bvh", "salsa/16.bvh", "indian/04.bvh", "indian/13.bvh",
              "martial/03.bvh", "martial/08.bvh")


def _side(name: str) -> str:
    return "red" if "Left" in name else "blue" if "Right" in name else "black"


def draw_row(ax, motion, label: str, y0: float) -> None:
    """Draw COLUMNS frames of a 30-fps motion along a row whose floor is at height y0."""
    v = motion_to_pose_vectors(motion, 0.0)
    speed = np.median(np.linalg.norm(np.diff(motion.root_position[:, [0, 2]], axis=0), axis=1)
                      ) * motion.fps * CMU_UNIT_M
    v[:, 0], v[:, 1] = 1.0, 0.0
    root = np.zeros((len(v), 3))
    root[:, 1] = motion.root_position[:, 1]
    P = joint_positions(v, motion, root_position=root) * CMU_UNIT_M
    frames = np.linspace(0, len(v) - 1, COLUMNS).round().astype(int)
    idx = {n: i for i, n in enumerate(POSE_JOINTS)}
    for c, t in enumerate(frames):
        x0 = c * SPACING_M
        for a, b in BONES_FOR_DRAWING:
            pa, pb = P[t, idx[a]], P[t, idx[b]]
            ax.plot([x0 + pa[0], x0 + pb[0]], [y0 + pa[1], y0 + pb[1]], color=_side(b), lw=1.5)
        ax.text(x0, y0 - 0.12, f"{t / motion.fps:.1f} s", ha="center", fontsize=6)
    ax.plot([-0.6, (COLUMNS - 0.5) * SPACING_M], [y0, y0], color="0.7", lw=0.5)
    ax.text(-0.65, y0 + 0.9, f"{label}\n{motion.n_frames / motion.fps:.1f} s, "
            f"{speed:.2f} m/s", ha="right", va="center", fontsize=7)


def sheet(rows, title: str, out: Path) -> None:
    """rows: (label, motion at 30 fps); one figure, one scale."""
    height = 2.2
    x_span = (COLUMNS + 2.0) * SPACING_M + 2.0
    y_span = (len(rows) - 1) * height + 2.4
    fig, ax = plt.subplots(figsize=(15, 15 * y_span / x_span + 0.4))
    for r, (label, motion) in enumerate(rows):
        draw_row(ax, motion, label, -r * height)
    ax.set_aspect("equal")
    ax.set_xlim(-2.6, (COLUMNS - 0.4) * SPACING_M)
    ax.set_ylim(-(len(rows) - 1) * height - 0.3, 2.1)
    ax.set_title(title + "  (metres; left side red, right blue; heading turned to face the "
                 "viewer)", fontsize=9)
    ax.tick_params(labelsize=6)
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    plt.close(fig)


def _main(argv=None) -> int:
    shared = Path(os.environ.get("SILHOUETTE_POSE_SHARED", ROOT.parent / "shared"))
    parser = OneLineParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=shared / "data" / "cmu_extra")
    parser.add_argument("--cmu-walk", type=Path,
                        default=shared / "data" / "cmu" / "bvh" / "02_01.bvh")
    parser.add_argument("--out-dir", type=Path, default=ROOT / "docs")
    args = parser.parse_args(argv)
    for option, path in (("--data", args.data), ("--cmu-walk", args.cmu_walk),
                         ("--out-dir", args.out_dir)):
        if not path.exists():
            parser.error(f"{option} not found: {path}")
    walk = ("../cmu 02_01 walk", read_bvh(args.cmu_walk, fps=30.0))
    rows = [walk] + [(name.split("/")[-1][:-4], settle_on_floor(
        read_expmap_motion(args.data / "expmap" / name)))
                     for name in EXPMAP_ROWS]
    sheet(rows, "cmu_extra expmap, converted, 30 fps", args.out_dir / "cmu_extra_expmap.png")
    rows = [walk] + [(name[:-4], settle_on_floor(
        read_dance(args.data / "dances" / name).motion))
                     for name in DANCE_ROWS]
    sheet(rows, "cmu_extra dances, retargeted, 30 fps", args.out_dir / "cmu_extra_dances.png")
    return 0


main = stops_in_one_line("contact_sheet_extra", _main)


if __name__ == "__main__":
    sys.exit(main())
