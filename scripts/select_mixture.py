"""Choose the mixture's settings on the validation trials (never on held-out ones), and draw
the learning curve.

    python scripts/select_mixture.py --cache /work/cache --rows-per-trial 800 --max-views 10 \
        --grid default --json out.json

Uses the cached data set and descriptors of scripts/train.py (same options). Candidates are
fitted on the training rows (validation trials excluded) and scored two ways, both on
validation trials only: (1) the data set's own validation rows (02_02, 08_03, 05_02, 06_10,
09_04, 02_05, as rendered for training, video-like noise), (2) spiral-walk videos of 02_02 and
08_03 through the tracker's silhouette extractor, raw stacked output (no filter). Measures:
err53, skill against the training-mean pose, corr8 (lab.training.angle_measures).
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path


import numpy as np
from threadpoolctl import threadpool_limits

from regressor.codebook import Codebook
from regressor.descriptor import DescriptorSettings
from regressor.descriptor_batch import descriptors_for_masks
from regressor.mixture import MixtureRegressor
from regressor.pose_model import transform_descriptors
from regressor.stacking import stack_frames
from sequences.dataset import DatasetConfig, build_dataset, training_files, views_by_rows
from sequences.video import load_truth
from tracker.one_line_parser import OneLineParser
from tracker.video.silhouettes import SilhouetteExtractor, median_background
from lab.training import VALIDATION_TRIALS, angle_measures, descriptor_cache_key
from regressor.mixture_fit import regression_targets
from regressor.training import angle_centres, partition_space
from tracker.video.decode import open_video

VIDEO_TRIALS = ("02_02", "08_03")


def video_masks(path: Path) -> list:
    """The largest person's mask per frame as the tracker extracts it (None: nobody)."""
    src = open_video(path)
    ex = SilhouetteExtractor()
    ex.prime(median_background(src.sample_frames(25)))
    out = []
    for _, _, frame in src:
        people = ex(frame)
        out.append(people[0].mask if people else None)
    return out


def video_descriptors(path: Path, codebook: Codebook, settings: DescriptorSettings):
    """(frame indices, descriptors (n, D)) of the frames where a person was found."""
    masks = video_masks(path)
    idx = [i for i, m in enumerate(masks) if m is not None and m.sum() > 50]
    return np.array(idx), descriptors_for_masks([masks[i] for i in idx], settings, codebook)


def main(argv=None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bvh-dir", type=Path, default=Path("../shared/data/cmu/bvh"))
    ap.add_argument("--cache", type=Path, default=Path("cache"))
    ap.add_argument("--video-dir", type=Path, default=None)
    ap.add_argument("--rows-per-trial", type=int, default=800)
    ap.add_argument("--max-views", type=int, default=10)
    ap.add_argument("--clean", action="store_true")
    ap.add_argument("--grid", default="default")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    video_dir = args.video_dir or args.cache / "videos"
    config = DatasetConfig()
    files = training_files(args.bvh_dir)
    views = views_by_rows(files, config, args.rows_per_trial, args.max_views)
    meta_path = args.cache / f"meta-{descriptor_cache_key(config, views, False)}.npz"
    if not meta_path.is_file():
        data = build_dataset(files, config, args.cache / "dataset", views=views)
        np.savez(meta_path, pose=data.pose, sequence=data.sequence,
                 trial_of_sequence=np.array(data.trial_of_sequence))
        del data
    with np.load(meta_path) as z:
        pose, sequence, tos = z["pose"], z["sequence"], z["trial_of_sequence"]
    key = descriptor_cache_key(config, views, noisy=not args.clean)
    with np.load(args.cache / f"descriptors-{key}.npz") as z:
        X, codebook = z["X"], Codebook(z["centres"], float(z["sigma"]))
    settings = DescriptorSettings()
    trials = tos[sequence]
    val = np.isin(trials, VALIDATION_TRIALS)
    centre = angle_centres(pose[~val])
    Y = regression_targets(pose, centre)
    videos = {}
    for t in VIDEO_TRIALS:
        path = video_dir / f"{t}_spiral30.mp4"
        idx, D = video_descriptors(path, codebook, settings)
        videos[t] = (idx, D, load_truth(path)["pose"][:, 0])
    grids = {
        "default": [dict()],
        "k": [dict(stack_depth=k) for k in (1, 2, 3, 4)],
        "width": [dict(width_scale=w) for w in (0.1, 0.25, 0.5)] +
                 [dict(lam=l) for l in (1e-3, 1e-1)],
        "experts": [dict(n_experts=e) for e in (1, 4, 8, 16, 24)],
        "pick": [dict(n_experts=24), dict(width_scale=0.1), dict(stack_depth=2),
                 dict(lam=0.1), dict(n_centres=800)],
        "curve": [dict(rows=n) for n in (2000, 4000, 8000, 16000, 32000, 0)],
        "more": [dict(n_experts=24, width_scale=0.5), dict(n_experts=24, stack_depth=4)],
        "curve24": [dict(n_experts=24, rows=n) for n in (4000, 16000)],
        "centres": [dict(n_centres=c) for c in (200, 400, 800)],
        "space": [dict(), dict(space="joint"), dict(space="descriptor")],
        "partition": [dict(heading_scale=h) for h in (1.0, 3.0, 6.0)] +
                     [dict(standardise=False, heading_scale=30.0), dict(overlap=0.0),
                      dict(overlap=0.5)],
    }
    def space(o, Xt, Yt):
        Z = partition_space(Yt, o["heading_scale"],
                            Yt[:, 2:].std(axis=0) if o["standardise"] else None)
        if o["space"] == "pose":
            return Z
        S = (Xt - Xt.mean(0)) / (Xt.std(0) + 1e-9) * np.sqrt(Z.shape[1] / Xt.shape[1])
        return S if o["space"] == "descriptor" else np.hstack([Z, o["descriptor_weight"] * S])

    results = []
    base = dict(space="descriptor", descriptor_weight=1.0, stack_depth=3, n_experts=12, overlap=0.2, n_centres=400, width_scale=0.25,
                lam=0.01, heading_scale=3.0, standardise=True, rows=0)
    for grid in args.grid.split(","):
        for change in grids[grid]:
            o = {**base, **change}
            k = o["stack_depth"]
            Xs = stack_frames(transform_descriptors(X, "sqrt"), k, sequence_ids=sequence)
            train = np.flatnonzero(~val)
            if o["rows"]:
                train = train[np.linspace(0, len(train) - 1, o["rows"]).astype(int)]
            start = time.perf_counter()
            with threadpool_limits(2):
                mix = MixtureRegressor(n_experts=o["n_experts"], overlap=o["overlap"],
                                       n_centres=o["n_centres"], width_scale=o["width_scale"],
                                       lam=o["lam"]).fit(
                    Xs[train], Y[train], space(o, Xs[train], Y[train]))
            fit_s = time.perf_counter() - start

            def poses(Z):
                out = mix.predict(Z)
                out[:, 2:] = (out[:, 2:] + centre + 180) % 360 - 180
                return out

            row = {**o, "fit_s": round(fit_s, 1), "n_train": int(len(train))}
            vrows = np.flatnonzero(val)
            row["val_rows"] = angle_measures(poses(Xs[vrows]), pose[vrows], centre)
            for t, (idx, D, truth) in videos.items():
                Zs = stack_frames(transform_descriptors(D, "sqrt"), k)
                row[f"video_{t}"] = angle_measures(poses(Zs), truth[idx], centre)
            results.append(row)
            print(json.dumps(row), flush=True)
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
