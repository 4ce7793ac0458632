"""How far real poses lie from the nearest training pose, without and with the cmu_extra motion.

    python scripts/pose_coverage.py --extra cache/cmu_extra/bvh

Queries: the body fitted to each Pose2Sim trial's reference keypoints (balancing, swings:
sequences.pose2sim_measures.reference_body, about 30 s a trial, cached in --cache), and for
scale the held-out CMU trials and the held-out cmu_extra sequences. Training poses: the
trials not held out of --bvh-dir (training and validation), and with --extra the converted
cmu_extra sequences not held out (sequences.cmu_extra.EXTRA_HELD_OUT), all at --fps (10).
Distance: the mean absolute difference over the 53 body angles (heading left out) to the
nearest training pose; per body part the same over that part's angles to the nearest pose by
that part alone; "parts" puts each part's nearest together (mean over the 53 angles);
"joints_mm" is the mean distance of 15 joints (mm, root at the origin, heading removed) to the
nearest training pose by that, blind to which angles make a posture. Prints the median over
each query's frames (and the whole body's 90th percentile), training poses without -> with
the extras.
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
from pathlib import Path

import numpy as np

from regressor.angles import wrap_deg
from regressor.errors import SilhouettePoseError
from sequences.bvh import read_bvh
from sequences.cmu_extra import EXTRA_HELD_OUT, CmuExtraError, extra_sources
from sequences.dataset import HELD_OUT_TRIALS, training_files
from sequences.measures import joints_mm
from sequences.pose_conversions import PART_OF_ENTRY, motion_to_pose_vectors
from tracker.one_line_parser import OneLineParser, stops_in_one_line

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("SILHOUETTE_POSE_SHARED", ROOT.parent / "shared"))
#: The body parts reported, in the table's order (sequences.pose_conversions.PART_OF_ENTRY).
PARTS = ("head", "torso", "left leg", "right leg", "left arm", "right arm")
_ANGLES = 53
_CHUNK_VALUES = 2 * 10**7          # query x training pose x angle values held at once


def part_columns() -> dict[str, np.ndarray]:
    """The pose-vector columns (indices into the 55) of each of PARTS."""
    parts = np.asarray(PART_OF_ENTRY)
    return {p: np.flatnonzero(parts == p) for p in PARTS}


def nearest_distance(queries, training, columns) -> np.ndarray:
    """(Q,) for each query pose (Q, 55): the mean absolute difference (degrees, wrapped) over
    ``columns`` to the nearest of the training poses (N, 55) by that measure."""
    queries = wrap_deg(np.asarray(queries, dtype=np.float64)[:, columns]).astype(np.float32)
    training = wrap_deg(np.asarray(training, dtype=np.float64)[:, columns]).astype(np.float32)
    step = max(1, _CHUNK_VALUES // max(1, training.size))
    out = np.empty(len(queries))
    for start in range(0, len(queries), step):
        diff = np.abs(queries[start:start + step, None] - training[None])
        np.minimum(diff, 360.0 - diff, out=diff)      # wrapped: both sides in [-180, 180]
        out[start:start + step] = diff.mean(axis=2).min(axis=1)
    return out


def posture_mm(poses) -> np.ndarray:
    """Joint positions (N, 15, 3) mm (sequences.measures.joints_mm: root at the origin, CMU
    skeleton) of poses (N, 55) turned to heading 0: what the body looks like, whatever angles
    make it (the fitted reference turns its collar bones, which ../cmu never does)."""
    poses = np.array(poses, dtype=np.float64)
    poses[:, 0], poses[:, 1] = 1.0, 0.0
    return joints_mm(poses)


def nearest_joint_distance(queries_mm, training_mm) -> np.ndarray:
    """(Q,) for each query's joints (Q, J, 3) mm: the mean joint distance (MPJPE) to the
    nearest of the training poses' joints (N, J, 3) by that measure."""
    queries = np.asarray(queries_mm, dtype=np.float32)
    training = np.asarray(training_mm, dtype=np.float32)
    step = max(1, _CHUNK_VALUES // max(1, training.size))
    out = np.empty(len(queries))
    for start in range(0, len(queries), step):
        diff = queries[start:start + step, None] - training[None]
        out[start:start + step] = np.sqrt((diff * diff).sum(axis=3)).mean(axis=2).min(axis=1)
    return out


def coverage(queries, training) -> dict[str, np.ndarray]:
    """Per query pose (Q,): "whole" (nearest_distance over the 53 body angles), each of PARTS,
    "parts" (each part's nearest distance weighted by its angles: the mean over the 53
    angles when every part may come from another training pose), and "joints_mm"
    (nearest_joint_distance of posture_mm)."""
    columns = part_columns()
    out = {"whole": nearest_distance(queries, training, np.arange(2, 2 + _ANGLES))}
    for part, cols in columns.items():
        out[part] = nearest_distance(queries, training, cols)
    out["parts"] = sum(out[p] * len(columns[p]) for p in PARTS) / _ANGLES
    out["joints_mm"] = nearest_joint_distance(posture_mm(queries), posture_mm(training))
    return out


def summarize(distances: dict[str, np.ndarray]) -> dict[str, float]:
    """Medians over frames of coverage's distances, and the whole body's 90th percentile."""
    out = {"frames": int(len(distances["whole"]))}
    out.update({k: round(float(np.median(v)), 2) for k, v in distances.items()})
    out["whole_p90"] = round(float(np.percentile(distances["whole"], 90)), 2)
    return out


def motion_poses(files, fps: float) -> np.ndarray:
    """Pose vectors (N, 55) of every frame of the BVH files at fps, concatenated."""
    return np.concatenate([motion_to_pose_vectors(read_bvh(f, fps=fps)) for f in files])


def reference_fit_poses(root: Path, cache: Path) -> np.ndarray:
    """The body fitted to a Pose2Sim trial's reference (T, 55), cached by the reference
    file's digest (the fit takes about 0.3 s a frame)."""
    from sequences.pose2sim import load_trial, reference_path
    from sequences.pose2sim_measures import reference_body
    digest = hashlib.sha256(reference_path(root).read_bytes()).hexdigest()[:12]
    path = cache / f"{root.name}-reference-{digest}.npz"
    if path.is_file():
        with np.load(path, allow_pickle=False) as z:
            return z["pose"]
    pose = reference_body(load_trial(root)).pose
    cache.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, pose=pose)
    return pose


def _queries(args) -> dict[str, np.ndarray]:
    """The query poses by name: Pose2Sim trials, held-out CMU trials, held-out extras."""
    out = {f"pose2sim {Path(t).name}": reference_fit_poses(Path(t), args.cache)
           for t in args.pose2sim}
    for trial in HELD_OUT_TRIALS:
        path = args.bvh_dir / f"{trial}.bvh"
        if path.is_file():
            out[f"cmu {trial} (held out)"] = motion_poses([path], args.fps)
    if args.extra is not None:
        for kind, prefix in (("expmap", "xm_"), ("dances", "xd_")):
            files = [args.extra / f"{n}.bvh" for n in EXTRA_HELD_OUT if n.startswith(prefix)]
            files = [f for f in files if f.is_file()]
            if files:
                out[f"cmu_extra {kind} (held out)"] = motion_poses(files, args.fps)
    return out


def _table(results: dict, databases: list[str]) -> str:
    """Markdown table: one row per query, cells 'without -> with' (or one figure)."""
    keys = ["whole", "whole_p90", *PARTS, "parts", "joints_mm"]
    lines = ["| query | frames | " + " | ".join(keys) + " |",
             "| --- " * (len(keys) + 2) + "|"]
    for query, by_db in results.items():
        cells = [" -> ".join(f"{by_db[db][k]:.1f}" for db in databases) for k in keys]
        lines.append(f"| {query} | {by_db[databases[0]]['frames']} | " + " | ".join(cells)
                     + " |")
    return "\n".join(lines)


def _main(argv=None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bvh-dir", type=Path, default=SHARED / "data" / "cmu" / "bvh")
    ap.add_argument("--extra", type=Path, default=None,
                    help="converted cmu_extra files (scripts/convert_cmu_extra.py --out DIR)")
    ap.add_argument("--pose2sim", nargs="*", default=[str(SHARED / "data" / "pose2sim" / t)
                                                      for t in ("balancing", "swings")],
                    help="Pose2Sim trial folders (default: balancing and swings)")
    ap.add_argument("--fps", type=float, default=10.0, help="training poses a second")
    ap.add_argument("--cache", type=Path, default=Path("cache/pose_coverage"),
                    help="where the fitted reference bodies are kept")
    ap.add_argument("--json", type=Path, default=None, help="also write the figures here")
    args = ap.parse_args(argv)
    if not (np.isfinite(args.fps) and 0 < args.fps <= 120):
        ap.error(f"--fps must be in (0, 120], got {args.fps}")
    for folder in args.pose2sim:
        if not Path(folder).is_dir():
            ap.error(f"--pose2sim folder not found: {folder}")
    try:
        extra = extra_sources(args.extra) if args.extra is not None else []
        databases = {"cmu": motion_poses(training_files(args.bvh_dir), args.fps)}
        if extra:
            databases["cmu + cmu_extra"] = np.vstack([databases["cmu"],
                                                      motion_poses(extra, args.fps)])
        queries = _queries(args)
    except (OSError, SilhouettePoseError, CmuExtraError) as exc:
        print(f"pose_coverage: error: {exc}", file=sys.stderr)
        return 1
    print("training poses: " + ", ".join(f"{k} {len(v)}" for k, v in databases.items())
          + f" (at {args.fps:g} frames/s)")
    results = {q: {db: summarize(coverage(poses, training))
                   for db, training in databases.items()} for q, poses in queries.items()}
    print(_table(results, list(databases)))
    if args.json:
        args.json.write_text(json.dumps({"training_poses": {k: len(v) for k, v in
                                                             databases.items()},
                                         "fps": args.fps, "results": results}, indent=1) + "\n")
    return 0


main = stops_in_one_line("pose_coverage", _main)


if __name__ == "__main__":
    sys.exit(main())
