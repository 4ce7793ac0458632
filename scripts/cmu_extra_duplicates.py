"""Which cmu_extra sequences repeat trials of ../cmu: nearest poses over aligned frames.

    python scripts/cmu_extra_duplicates.py [--data DIR] [--cmu DIR] [--out TSV]

Every sequence is converted to the CMU skeleton at 30 fps and described per frame by its 18
pose-joint positions with the heading removed (pose vector -> joint positions on one skeleton,
so subject proportions do not count). For each frame the nearest ../cmu frame is found (k-d
tree); a sequence whose frames are nearly all within MATCH_MM (rms over joints) of frames of one
trial, met in order (the matched index advancing one frame per frame), repeats that trial.
Prints one line per sequence: name, median nearest distance (mm), best trial, share of frames
matched to it within MATCH_MM, share of consecutive matches advancing by one frame.
"""
from __future__ import annotations

import os
import sys
from collections import Counter
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree
from tqdm import tqdm

from sequences.bvh import read_bvh
from sequences.cmu_extra import convert_all
from sequences.pose_conversions import motion_to_pose_vectors
from sequences.pose_vector import joint_positions
from sequences.skeleton import CMU_UNIT_M
from tracker.one_line_parser import OneLineParser, stops_in_one_line

ROOT = Path(__file__).resolve().parents[1]

#: Frames nearer than this (rms joint distance, mm) to a trial's frame count as matched: the
#: repeats found lie at 1-5 mm (the expmap root orientation differs from the BVH's by ~0.4
#: degrees), other sequences at 20 mm or more.
MATCH_MM = 10.0


def describe(motion) -> np.ndarray:
    """(T, 54) heading-free pose-joint positions (CMU units) of a motion at 30 fps."""
    v = motion_to_pose_vectors(motion, 0.0)
    v[:, 0], v[:, 1] = 1.0, 0.0
    return joint_positions(v).reshape(len(v), -1)


def _main(argv=None) -> int:
    shared = Path(os.environ.get("SILHOUETTE_POSE_SHARED", ROOT.parent / "shared"))
    parser = OneLineParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=str(shared / "data" / "cmu_extra"))
    parser.add_argument("--cmu", default=str(shared / "data" / "cmu" / "bvh"))
    parser.add_argument("--out", default="", help="write the table here (TSV)")
    args = parser.parse_args(argv)
    for option, folder in (("--data", args.data), ("--cmu", args.cmu)):
        if not Path(folder).is_dir():
            parser.error(f"{option} folder not found: {folder}")
    feats, owner, index = [], [], []
    for path in tqdm(sorted(Path(args.cmu).glob("*.bvh")), desc="../cmu", unit="trial",
                     disable=None):
        f = describe(read_bvh(path, fps=30.0))
        feats.append(f)
        owner += [path.stem] * len(f)
        index.append(np.arange(len(f)))
    tree = cKDTree(np.concatenate(feats))
    owner, index = np.array(owner), np.concatenate(index)
    n_joints = 18
    rows = ["name\tframes\tmedian_mm\tbest_trial\tshare_matched\tbest_trial_frames\tshare_in_order"]
    for item in tqdm(list(convert_all(args.data)), desc="cmu_extra", unit="seq", disable=None):
        f = describe(item.convert().motion)
        dist, nearest = tree.query(f)
        # Euclidean distance over 54 numbers -> a mean joint distance bound (rms over joints)
        mm = dist / np.sqrt(n_joints) * CMU_UNIT_M * 1000.0
        best, _ = Counter(owner[nearest]).most_common(1)[0]
        close = (owner[nearest] == best) & (mm < MATCH_MM)
        steps = np.diff(index[nearest])
        in_order = float(np.mean((steps == 1) & close[1:] & close[:-1])) if len(f) > 1 else 0.0
        rows.append(f"{item.name}\t{len(f)}\t{np.median(mm):.2f}\t{best}\t{close.mean():.3f}\t"
                    f"{int(np.sum(owner == best))}\t"
                    f"{in_order:.3f}")
    text = "\n".join(rows) + "\n"
    print(text, end="")
    if args.out:
        Path(args.out).write_text(text)
    return 0


main = stops_in_one_line("cmu_extra_duplicates", _main)


if __name__ == "__main__":
    sys.exit(main())
