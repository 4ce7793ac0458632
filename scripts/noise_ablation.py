"""Does training on video-like silhouettes close the render gap? Same rows, same codebook,
same mixture settings; clean renders vs sequences.mask_noise versions; scored on spiral-walk
videos of validation trials through the tracker's extractor (raw stacked output).

    python scripts/noise_ablation.py --cache /work/cache --bvh-dir ../shared/data/cmu/bvh

Rows: the walking and running trials of the training set (the CMU index says "walk" or
"run"), so the clean descriptors cost minutes, not the whole data set's.
"""
from __future__ import annotations

import csv
import json
import sys
from pathlib import Path


import numpy as np
from threadpoolctl import threadpool_limits

from regressor.codebook import Codebook
from regressor.descriptor import DescriptorSettings
from regressor.mixture import MixtureRegressor
from regressor.pose_model import transform_descriptors
from regressor.stacking import stack_frames
from sequences.dataset import DatasetConfig, build_dataset, training_files, views_by_rows
from sequences.video import load_truth
from lab.training import (VALIDATION_TRIALS, angle_measures, dataset_descriptors,
                          descriptor_cache_key)
from regressor.mixture_fit import regression_targets
from regressor.training import MixtureOptions, angle_centres, mixture_space
from tracker.one_line_parser import OneLineParser
from select_mixture import VIDEO_TRIALS, video_descriptors


def main(argv=None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bvh-dir", type=Path, default=Path("../shared/data/cmu/bvh"))
    ap.add_argument("--cache", type=Path, default=Path("cache"))
    ap.add_argument("--rows-per-trial", type=int, default=800)
    ap.add_argument("--max-views", type=int, default=10)
    ap.add_argument("--experts", type=int, default=8)
    args = ap.parse_args(argv)
    config = DatasetConfig()
    index = {r["file"].split("/")[-1][:-4]: r["description"]
             for r in csv.DictReader(open(args.bvh_dir.parent / "MANIFEST.tsv"), delimiter="\t")}
    all_files = training_files(args.bvh_dir)
    views = views_by_rows(all_files, config, args.rows_per_trial, args.max_views)
    key = descriptor_cache_key(config, views, noisy=True)
    with np.load(args.cache / f"descriptors-{key}.npz") as z:
        X_all, codebook = z["X"], Codebook(z["centres"], float(z["sigma"]))
    data = build_dataset(all_files, config, args.cache / "dataset", views=views)
    trials = np.asarray(data.trial_of_sequence)[data.sequence]
    walks = sorted(t for t in set(trials) if ("walk" in index[t] or "run" in index[t]))
    rows = np.flatnonzero(np.isin(trials, walks))
    clean_path = args.cache / f"ablation-clean-{key}.npz"
    if clean_path.is_file():
        Xc = np.load(clean_path)["X"]
    else:
        Xc = dataset_descriptors(data.masks[rows], DescriptorSettings(), codebook, workers=2)
        np.savez(clean_path, X=Xc)
    pose, seq = data.pose[rows], data.sequence[rows]
    val = np.isin(trials[rows], VALIDATION_TRIALS)
    del data
    centre = angle_centres(pose[~val])
    Y = regression_targets(pose, centre)
    videos = {t: video_descriptors(args.cache / "videos" / f"{t}_spiral30.mp4", codebook,
                                   DescriptorSettings()) for t in VIDEO_TRIALS}
    truths = {t: load_truth(args.cache / "videos" / f"{t}_spiral30.mp4")["pose"][:, 0]
              for t in VIDEO_TRIALS}
    out = {"walk_trials": walks, "rows": int((~val).sum())}
    for name, X in (("clean", Xc), ("noisy", X_all[rows])):
        Xs = stack_frames(transform_descriptors(X, "sqrt"), 3, sequence_ids=seq)
        with threadpool_limits(2):
            mix = MixtureRegressor(n_experts=args.experts).fit(
                Xs[~val], Y[~val], mixture_space(MixtureOptions(partition="descriptor"), Xs, Y, np.flatnonzero(~val))[~val])
        res = {}
        for t, (idx, D) in videos.items():
            p = mix.predict(stack_frames(transform_descriptors(D, "sqrt"), 3))
            p[:, 2:] = (p[:, 2:] + centre + 180) % 360 - 180
            res[t] = angle_measures(p, truths[t][idx], centre)
        out[name] = res
        print(name, json.dumps(res), flush=True)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
