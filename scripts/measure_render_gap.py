"""Measure the render-to-real gap: the same motion as a plain mask, with today's hand-made noise,
and made the realistic way (sequences.scene_render), against real video's silhouettes.

    python scripts/measure_render_gap.py --bvh-dir ../shared/data/cmu/bvh \\
        --backgrounds ../shared/data/pose2sim --plates cache/plates \\
        --real-json real.json --videos cache/gap_videos --sheet gap.png
    # real.json: from scripts/evaluate_real.py --trial all --json real.json

For each held-out trial (sequences.dataset.HELD_OUT_TRIALS) and --views views of it, the first
--frames frames are made three ways: plain (the data set's rasterised masks), hand noise
(sequences.mask_noise through the extractor's cleaning, what training uses today) and
realistic. Printed: the Pose2Sim cameras' heights and tilts beside the realistic cameras';
per kind, the model's novelty (PoseEstimates.novelty of the stacked descriptors: median and share
above 1) and the descriptor distance to the plain mask of the same frame (median, and over the
median distance between two random plain frames); for the realistic masks their IoU with the
plain mask in the frame and their area over it, and the milliseconds per frame with the
estimated time for the default training set; with --real-json, the real views' novelty as
evaluate_real.py measured it through the tracker. Bad options: one line, exit 2.
"""
from __future__ import annotations

import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from regressor.errors import SilhouettePoseError
from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
from regressor.stacking import stack_frames
from sequences.backgrounds import load_plates, pose2sim_plates
from sequences.body import Skinner, load_body
from sequences.bvh import read_bvh
from sequences.dataset import (HELD_OUT_TRIALS, DatasetConfig, realistic_motion_masks,
                               render_motion_masks, training_files, view_settings,
                               views_by_rows, _view_rng)
from sequences.scene_render import SceneConfig, write_video
from tracker.one_line_parser import OneLineParser, stops_in_one_line

KINDS = ("plain", "hand noise", "realistic")


def pose2sim_cameras(calibration: Path) -> list[tuple[str, float, float]]:
    """(view, height m, tilt down deg) of each Pose2Sim camera (Z up in its calibration)."""
    from sequences.pose2sim import read_calibration
    out = []
    for name, cam in read_calibration(calibration).items():
        centre = -cam.R.T @ cam.t
        out.append((name, float(centre[2]), float(np.degrees(np.arcsin(-cam.R[2, 2])))))
    return out


def trial_masks(path: Path, frames: int, views: int, plates, seed: int,
                videos: Path | None = None) -> dict:
    """The three kinds of masks of the first `frames` frames of a trial in `views` views:
    {kind: list of masks, 'sequence': ids, 'iou', 'area', 'seconds'}. With videos, the first
    view's realistic clips are written there as TRIAL-START.mp4."""
    from lab.training import noisy_masks
    motion = read_bvh(path, fps=30.0)
    n = min(frames, motion.n_frames)
    motion = replace(motion, euler_deg=motion.euler_deg[:n], root_position=motion.root_position[:n])
    config = DatasetConfig(views_per_trial=views, seed=seed)
    body, out = load_body(), {k: [] for k in (*KINDS, "sequence", "iou", "area")}
    out["seconds"] = 0.0
    for v, view in enumerate(view_settings(config, path.stem)):
        skinner = Skinner(body, offsets=motion.offsets, names=motion.names,
                          end_sites=motion.end_sites, shape=view["shape"])
        plain = render_motion_masks(motion, skinner, view["azimuth_deg"], view["elevation_deg"],
                                    view["distance_m"], config.person_px, config.mask_size)
        keep = None
        if videos is not None and v == 0:
            def keep(clip, first):
                write_video(videos / f"{path.stem}-{first}.mp4", clip)
        start = time.perf_counter()
        real, info = realistic_motion_masks(motion, skinner, view["azimuth_deg"], plates,
                                            _view_rng(seed, path.stem + "/scene", v),
                                            config.mask_size, on_clip=keep)
        out["seconds"] += time.perf_counter() - start
        out["plain"] += list(plain)
        out["hand noise"] += noisy_masks(plain, seed + v)
        out["realistic"] += list(real)
        out["sequence"] += [f"{path.stem}/{v}"] * n
        out["iou"] += list(info["iou"])
        out["area"] += list(info["area"])
    return out


def describe_all(model, masks: list) -> np.ndarray:
    """Descriptors (n, D), NaN rows for masks the model cannot describe."""
    X = np.full((len(masks), model.descriptor_length), np.nan)
    for i, mask in enumerate(masks):
        try:
            X[i] = model.describe(np.asarray(mask, bool))
        except SilhouettePoseError:
            pass
    return X


def kind_measures(model, X: np.ndarray, plain: np.ndarray, sequence: list, rng) -> dict:
    """Novelty and descriptor distances to the plain masks' of one kind's descriptors."""
    ok = np.isfinite(X).all(axis=1) & np.isfinite(plain).all(axis=1)
    ids = np.unique(sequence, return_inverse=True)[1]
    Xf = np.where(np.isfinite(X), X, 0.0)
    novelty = model.hypotheses(stack_frames(Xf, model.stack_depth, ids)).novelty[ok]
    distance = np.linalg.norm(X[ok] - plain[ok], axis=1)
    a, b = rng.integers(ok.sum(), size=(2, 2000))
    between = np.median(np.linalg.norm(plain[ok][a] - plain[ok][b], axis=1))
    return {"novelty": float(np.median(novelty)), "above_1": float((novelty > 1).mean()),
            "distance": float(np.median(distance)),
            "relative": float(np.median(distance) / between),
            "described": int(ok.sum()), "rows": len(X)}


def tracked_novelty(videos: list[Path], model: Path) -> dict:
    """{video stem: median novelty of its frames} from the ``track`` command (this checkout's,
    python -m tracker.cli VIDEO --model MODEL --json), all tracks' frames pooled: the novelty
    under the model being measured, as the real views' is."""
    import subprocess
    import tempfile
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for video in videos:
            summary = Path(tmp) / "track.json"
            run = subprocess.run([sys.executable, "-m", "tracker.cli", str(video), "--model",
                                  str(model), "--json", str(summary)],
                                 capture_output=True, text=True)
            if run.returncode:
                raise OSError(f"track {video}: {run.stderr.strip().splitlines()[-1:]}")
            tracks = json.loads(summary.read_text())["tracks"]
            values = [x for t in (tracks.values() if isinstance(tracks, dict) else tracks)
                      for x in t["novelty"] if x is not None]
            if values:
                out[video.stem] = float(np.median(values))
    return out


def real_novelty(paths: list[Path]) -> dict:
    """{trial/view: median novelty} from evaluate_real.py --json files."""
    out = {}
    for path in paths:
        result = json.loads(path.read_text())
        trials = result.get("trials", result) if "views" not in result else {path.stem: result}
        for name, trial in trials.items():
            if not isinstance(trial, dict) or "views" not in trial:
                continue
            for view, r in trial["views"].items():
                median = r.get("novelty", {}).get("median")
                if median is not None:
                    out[f"{name}/{view}"] = float(median)
    return out


def training_set_estimate(bvh_dir: Path, ms_per_frame: float, workers: int) -> tuple[int, float]:
    """(rows of the default training set (build_dataset.py's 800 rows per trial, 10 views at
    most), its estimated minutes at ms_per_frame on `workers` processes)."""
    files = training_files(bvh_dir)
    config = DatasetConfig()
    views = views_by_rows(files, config, 800, 10)
    from sequences.dataset import bvh_frame_count
    rows = sum(int(bvh_frame_count(p) * config.fps / 120.0) * views[p.stem] for p in files)
    return rows, rows * ms_per_frame / 1000 / 60 / workers


def write_sheet(path: Path, data: dict, n: int = 8, size: int = 112) -> None:
    """n frames spread over the data, one row per kind, each mask's box fitted in size px."""
    import cv2
    from sequences.scene_render import on_canvas
    picks = np.linspace(0, len(data["plain"]) - 1, n).round().astype(int)
    rows = []
    for kind in KINDS:
        tiles = [cv2.resize(on_canvas(np.asarray(data[kind][i], bool), (224, 224), 0.9)
                            .astype(np.uint8) * 255, (size, size), interpolation=cv2.INTER_AREA)
                 for i in picks]
        rows.append(np.hstack(tiles))
    cv2.imwrite(str(path), np.vstack(rows))


def _report(args, model, data: dict, reals: dict, tracked: dict) -> None:
    print("cameras: Pose2Sim (height m, tilt down deg): " + ", ".join(
        f"{n} {h:.2f} {t:.0f}" for n, h, t in pose2sim_cameras(args.calibration)))
    scene = SceneConfig()
    print(f"         realistic renders: height {scene.camera_height_m[0]}-"
          f"{scene.camera_height_m[1]} m, distance {scene.distance_m[0]}-{scene.distance_m[1]} "
          f"m, aimed at {0.9} m (tilt about 5-25 deg)")
    rng = np.random.default_rng(0)
    X = {k: describe_all(model, data[k]) for k in KINDS}
    print(f"{len(data['plain'])} frames of {len(set(data['sequence']))} sequences "
          f"(held-out trials: {', '.join(sorted({s.split('/')[0] for s in data['sequence']}))})")
    print(f"{'kind':<12} {'novelty median':>15} {'> 1':>6} {'desc. dist. to plain':>21} "
          f"{'/ between frames':>17} {'described':>10}")
    for kind in KINDS:
        m = kind_measures(model, X[kind], X["plain"], data["sequence"], rng)
        print(f"{kind:<12} {m['novelty']:>15.2f} {100 * m['above_1']:>5.0f}% "
              f"{m['distance']:>21.2f} {m['relative']:>17.2f} {m['described']:>6}/{m['rows']}")
    iou, area = np.array(data["iou"]), np.array(data["area"])
    print(f"realistic vs plain in the frame: IoU median {np.median(iou):.2f} (10th percentile "
          f"{np.percentile(iou, 10):.2f}), area ratio median {np.median(area):.2f} "
          f"(10-90th {np.percentile(area, 10):.2f}-{np.percentile(area, 90):.2f})")
    ms = 1000 * data["seconds"] / len(data["plain"])
    rows, minutes = training_set_estimate(args.bvh_dir, ms, args.workers)
    print(f"speed: {ms:.0f} ms per realistic frame (render, H.264, extraction; one process); "
          f"the default training set's {rows} rows: about {minutes:.0f} min on {args.workers} "
          f"workers")
    if tracked:
        values = np.array(list(tracked.values()))
        print("realistic videos through track (first view, first clip of each trial): novelty "
              "median " + ", ".join(f"{k} {v:.2f}" for k, v in tracked.items())
              + f"; median of videos {np.median(values):.2f}")
    if reals:
        values = np.array(list(reals.values()))
        print("real (evaluate_real.py, tracker): novelty median per view "
              + ", ".join(f"{k} {v:.2f}" for k, v in reals.items())
              + f"; median of views {np.median(values):.2f}")


def _main(argv=None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bvh-dir", type=Path, default=Path("../shared/data/cmu/bvh"))
    ap.add_argument("--backgrounds", type=Path, default=Path("../shared/data/pose2sim"),
                    help="Pose2Sim trials (their videos give the rooms) or a folder of plates")
    ap.add_argument("--plates", type=Path, default=Path("cache/plates"),
                    help="where the rooms' plates are cached (default cache/plates)")
    ap.add_argument("--calibration", type=Path,
                    default=Path("../shared/data/pose2sim/balancing/calibration/"
                                 "Calib_qualisys.toml"))
    ap.add_argument("--model", type=Path, default=DEFAULT_MODEL_PATH)
    ap.add_argument("--frames", type=int, default=120, help="frames per trial, 1..10000")
    ap.add_argument("--views", type=int, default=2, help="views per trial, 1..12")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2,
                    help="workers assumed for the training set's time estimate")
    ap.add_argument("--videos", type=Path, metavar="DIR", help="also write each trial's first "
                    "realistic view as MP4 clips in DIR and track the first clip of each with "
                    "this checkout's track (--json): novelty as the real clips get it")
    ap.add_argument("--sheet", type=Path, metavar="PNG", help="write 8 frames of each kind "
                    "(rows: plain, hand noise, realistic) as a PNG")
    ap.add_argument("--real-json", type=Path, nargs="*", default=[],
                    help="evaluate_real.py --json outputs: the real views' novelty")
    args = ap.parse_args(argv)
    if not 1 <= args.frames <= 10000 or not 1 <= args.views <= 12:
        ap.error(f"--frames must be 1..10000 and --views 1..12, got {args.frames}, {args.views}")
    for flag, path in (("--bvh-dir", args.bvh_dir), ("--backgrounds", args.backgrounds)):
        if not path.is_dir():
            ap.error(f"{flag}: folder not found: {path}")
    for path in [args.model, args.calibration, *args.real_json]:
        if not path.is_file():
            ap.error(f"file not found: {path}")
    try:
        if args.videos is not None:
            args.videos.mkdir(parents=True, exist_ok=True)
        model = load_pose_model(args.model)
        plates = (load_plates(str(args.backgrounds)) if any(args.backgrounds.glob("plate-*.png"))
                  else pose2sim_plates(args.backgrounds, args.plates))
        data: dict = {}
        for trial in HELD_OUT_TRIALS:
            one = trial_masks(args.bvh_dir / f"{trial}.bvh", args.frames, args.views, plates,
                              args.seed, args.videos)
            for k, v in one.items():
                data[k] = data.get(k, 0.0 if k == "seconds" else []) + v
            print(f"  {trial}: {len(one['plain'])} frames", file=sys.stderr)
        if args.sheet is not None:
            write_sheet(args.sheet, data)
        reals = real_novelty(args.real_json)
        tracked = {}
        if args.videos is not None:
            tracked = tracked_novelty(sorted(args.videos.glob("*-0.mp4")), args.model)
        _report(args, model, data, reals, tracked)
    except (OSError, ValueError, SilhouettePoseError) as exc:
        print(f"measure_render_gap: error: {exc}", file=sys.stderr)
        return 1
    return 0


main = stops_in_one_line("measure_render_gap", _main)


if __name__ == "__main__":
    sys.exit(main())
