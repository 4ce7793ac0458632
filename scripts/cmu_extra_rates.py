"""Check the frame rates of cmu_extra against motion speed (numbers for docs/cmu_extra.md).

    python scripts/cmu_extra_rates.py [--data DIR] [--cmu DIR]

For the walks (expmap walking, walking_extra) and ../cmu's walks (120 fps): median ground speed
of the root (m/s) and stride frequency (dominant frequency of the left ankle's height, Hz) at
the assumed rate. For the dances: median root and wrist speeds (m/s) at the assumed rate, salsa
beside the other dances and ../cmu's dance trials (subject 05, 120 fps).
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

from sequences.bvh import read_bvh
from sequences.expmap import EXPMAP_FPS, expmap_files, read_expmap_motion
from sequences.pose_vector import forward_kinematics
from sequences.retarget import DANCE_FPS, dance_files, read_dance
from sequences.skeleton import CMU_UNIT_M
from tracker.one_line_parser import OneLineParser, stops_in_one_line

ROOT = Path(__file__).resolve().parents[1]


def speeds(motion) -> tuple[float, float, float]:
    """(median root ground speed m/s, stride frequency Hz, median right-wrist speed m/s)."""
    P, _ = forward_kinematics(motion.offsets, motion.parents, motion.local_rotations(),
                              motion.root_position)
    P = P * CMU_UNIT_M
    fps = motion.fps
    root = np.linalg.norm(np.diff(P[:, 0, [0, 2]], axis=0), axis=1) * fps
    ankle = P[:, motion.names.index("LeftFoot"), 1]
    spectrum = np.abs(np.fft.rfft(ankle - ankle.mean()))
    freq = np.fft.rfftfreq(len(ankle), 1.0 / fps)
    band = freq > 0.3
    stride = float(freq[band][np.argmax(spectrum[band])])
    wrist = np.linalg.norm(np.diff(P[:, motion.names.index("RightHand")], axis=0), axis=1) * fps
    return float(np.median(root)), stride, float(np.median(wrist))


def report(label: str, motions) -> None:
    s = np.array([speeds(m) for m in motions])
    print(f"{label:34s} n={len(s):3d}  ground {np.median(s[:, 0]):.2f} m/s  stride "
          f"{np.median(s[:, 1]):.2f} Hz  wrist {np.median(s[:, 2]):.2f} m/s")


def _main(argv=None) -> int:
    shared = Path(os.environ.get("SILHOUETTE_POSE_SHARED", ROOT.parent / "shared"))
    parser = OneLineParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=str(shared / "data" / "cmu_extra"))
    parser.add_argument("--cmu", default=str(shared / "data" / "cmu" / "bvh"))
    args = parser.parse_args(argv)
    for option, folder in (("--data", args.data), ("--cmu", args.cmu)):
        if not Path(folder).is_dir():
            parser.error(f"{option} folder not found: {folder}")
    manifest = Path(args.cmu).parent / "MANIFEST.tsv"
    kinds = {}
    for line in manifest.read_text().splitlines()[1:]:
        cells = line.split("\t")
        kinds[Path(cells[0]).stem] = cells[3].split()[0].strip(",")
    cmu = {k: [read_bvh(Path(args.cmu) / f"{t}.bvh", fps=None) for t, d in kinds.items()
               if d == k] for k in ("walk", "dance", "run")}
    report("../cmu walk (120 fps)", cmu["walk"])
    report("../cmu run (120 fps)", cmu["run"])
    report("../cmu dance, subject 05 (120 fps)", cmu["dance"])
    walks = [p for p in expmap_files(Path(args.data) / "expmap")
             if p.parent.name in ("walking", "walking_extra")]
    runs = [p for p in expmap_files(Path(args.data) / "expmap") if p.parent.name == "running"]
    for fps in (EXPMAP_FPS, EXPMAP_FPS / 2):
        for label, files in (("walk", walks), ("run", runs)):
            motions = []
            for p in files:
                m = read_expmap_motion(p, fps=None)
                m.fps = fps
                motions.append(m)
            report(f"expmap {label} at {fps:g} fps", motions)
    for kind in ("salsa", "indian", "martial"):
        files = [p for p in dance_files(Path(args.data) / "dances") if p.parent.name == kind]
        native = [read_dance(p, fps=None).motion for p in files]
        for fps in (DANCE_FPS[kind], 2 * DANCE_FPS[kind]) if kind == "salsa" else (
                DANCE_FPS[kind],):
            for m in native:
                m.fps = fps
            report(f"dances {kind} at {fps:g} fps", native)
    return 0


main = stops_in_one_line("cmu_extra_rates", _main)


if __name__ == "__main__":
    sys.exit(main())
