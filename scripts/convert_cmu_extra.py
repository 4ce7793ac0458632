"""Convert cmu_extra (expmap sequences and dance BVH) to CMU-skeleton BVH files at 30 fps.

    python scripts/convert_cmu_extra.py [--data DIR] [--out DIR] [--fps 30] [--summary JSON]

Writes one BVH per sequence (31-joint CMU skeleton, ZYX channels: read_bvh reads them, and
sequences.dataset.build_dataset takes them like ../cmu trials) into --out, leaving out the
sequences that repeat ../cmu trials (sequences.cmu_extra.DUPLICATES), and a JSON summary
(frames per source and action, conversion time, the dances' fit residual). Files already
written are rewritten; nothing else in --out is touched.
"""
from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from regressor.errors import SilhouettePoseError
from sequences.bvh import write_bvh
from sequences.cmu_extra import DUPLICATES, convert_all
from tracker.one_line_parser import OneLineParser, stops_in_one_line

ROOT = Path(__file__).resolve().parents[1]


def _main(argv=None) -> int:
    parser = OneLineParser(description=__doc__.splitlines()[0])
    shared = Path(os.environ.get("SILHOUETTE_POSE_SHARED", ROOT.parent / "shared"))
    parser.add_argument("--data", default=str(shared / "data" / "cmu_extra"),
                        help="the cmu_extra folder (expmap/ and dances/)")
    parser.add_argument("--out", default="cache/cmu_extra/bvh", help="output BVH folder")
    parser.add_argument("--fps", type=float, default=30.0, help="output frame rate")
    parser.add_argument("--summary", default="", help="write a JSON summary here")
    parser.add_argument("--keep-duplicates", action="store_true",
                        help="also write the sequences that repeat ../cmu trials")
    args = parser.parse_args(argv)
    if not (args.fps > 0 and np.isfinite(args.fps)):
        parser.error(f"--fps must be positive, got {args.fps}")
    if not Path(args.data).is_dir():
        parser.error(f"--data folder not found: {args.data}")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        parser.error(f"--out {out}: not a folder")
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    summary = {"fps": args.fps, "sequences": {}, "left_out": []}
    try:
        items = list(convert_all(args.data, fps=args.fps))
        for item in tqdm(items, desc="converting", unit="seq", disable=None):
            name, kind, action, converted = item.name, item.kind, item.action, item.convert()
            motion = converted.motion
            entry = {"kind": kind, "action": action, "frames": motion.n_frames}
            if converted.residual_mm is not None:
                entry["residual_mm"] = float(np.mean(converted.residual_mm))
            summary["sequences"][name] = entry
            if name in DUPLICATES and not args.keep_duplicates:
                summary["left_out"].append(name)
                continue
            tmp = out / f".{name}.bvh.tmp"
            write_bvh(tmp, motion)          # whole or not at all
            tmp.replace(out / f"{name}.bvh")
    except (SilhouettePoseError, OSError) as exc:
        print(f"convert_cmu_extra: error: {exc}", file=sys.stderr)
        return 1
    summary["seconds"] = time.perf_counter() - start
    if args.summary:
        Path(args.summary).write_text(json.dumps(summary, indent=1) + "\n")
    total = sum(e["frames"] for e in summary["sequences"].values())
    print(f"{len(summary['sequences'])} sequences, {total} frames at {args.fps:g} fps, "
          f"{len(summary['left_out'])} duplicates left out, {summary['seconds']:.1f} s")
    return 0


main = stops_in_one_line("convert_cmu_extra", _main)


if __name__ == "__main__":
    sys.exit(main())
