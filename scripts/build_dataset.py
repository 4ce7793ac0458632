"""Render the training data set (silhouettes + pose vectors) from CMU motion capture, cached.

    python scripts/build_dataset.py --bvh-dir ../shared/data/cmu/bvh --cache cache/dataset

Held-out trials (sequences.dataset.HELD_OUT_TRIALS) are never rendered into it. With --extra
DIR (written by scripts/convert_cmu_extra.py) the cmu_extra sequences are rendered too, as
train.py --extra renders them (sequences.cmu_extra.extra_dataset_trials: EXTRA_HELD_OUT left
out, windows of the long ones written beside the cache in cmu_extra_windows/). With --masks
realistic the silhouettes are made the way real ones are (sequences.scene_render: a shaded body
over a real room, H.264, cut out by the tracker's extractor; docs/render_to_real.md), over the
Pose2Sim rooms with --backgrounds DIR (their plates are made once into CACHE/plates), else over
procedural rooms. Re-running with
the same settings reuses the cache; prints the build time and size. Numbers outside their
ranges (as train.py's) are refused in one line naming the option (exit 2).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path


from regressor.errors import SilhouettePoseError
from sequences.cmu_extra import (EXTRA_HELD_OUT, EXTRA_ROWS_PER_TRIAL, CmuExtraError,
                                extra_dataset_trials, extra_sources)
from sequences.backgrounds import plates_folder
from sequences.dataset import (HELD_OUT_TRIALS, MASK_KINDS, DatasetConfig, build_dataset,
                               training_files, views_by_rows)
from tracker.one_line_parser import OneLineParser, stops_in_one_line


def _main(argv=None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bvh-dir", type=Path, default=Path("../shared/data/cmu/bvh"))
    ap.add_argument("--cache", type=Path, default=Path("cache/dataset"))
    ap.add_argument("--views", type=int, default=DatasetConfig.views_per_trial,
                    help="views rendered per trial with --rows-per-trial 0, 1..360 (default "
                         f"{DatasetConfig.views_per_trial})")
    ap.add_argument("--rows-per-trial", type=int, default=800,
                    help="views per trial chosen to give about this many silhouettes per trial "
                         "(1..--max-views); 0: --views for every trial")
    ap.add_argument("--max-views", type=int, default=10, help="at most this many views per "
                    "trial with --rows-per-trial, 1..360 (default 10)")
    ap.add_argument("--extra", type=Path, default=None,
                    help="also render the converted cmu_extra sequences in this folder "
                         "(EXTRA_HELD_OUT left out); default none")
    ap.add_argument("--extra-rows-per-trial", type=int, default=EXTRA_ROWS_PER_TRIAL,
                    help="with --extra: about this many silhouettes per converted sequence "
                         f"(default {EXTRA_ROWS_PER_TRIAL})")
    ap.add_argument("--masks", choices=MASK_KINDS, default="plain",
                    help="plain: rasterised silhouettes (default); realistic: rendered over a "
                         "room, H.264, cut out by the tracker (docs/render_to_real.md)")
    ap.add_argument("--backgrounds", type=Path, default=None,
                    help="with --masks realistic: the Pose2Sim trials' folder (its "
                         "*/videos/camNN.mp4, people removed) or a folder of plate-*.png; "
                         "default: procedural rooms")
    ap.add_argument("--seed", type=int, default=0, help="0..2147483647 (default 0)")
    ap.add_argument("--workers", type=int, default=2, help="rendering processes, 1..64 "
                    "(default 2)")
    args = ap.parse_args(argv)
    # train.py's ranges (it builds the same data set): seeds as numpy takes them.
    for flag, value, low, high in (("--views", args.views, 1, 360),
                                   ("--rows-per-trial", args.rows_per_trial, 0, 10**6),
                                   ("--extra-rows-per-trial", args.extra_rows_per_trial, 1,
                                    10**6),
                                   ("--max-views", args.max_views, 1, 360),
                                   ("--seed", args.seed, 0, 2**31 - 1),
                                   ("--workers", args.workers, 1, 64)):
        if not low <= value <= high:
            ap.error(f"{flag} must be in {low}..{high}, got {value}")
    if args.extra is not None:
        try:                # before the slow steps
            extra_sources(args.extra)
        except CmuExtraError as exc:
            ap.error(str(exc))
    if args.backgrounds is not None and args.masks != "realistic":
        ap.error("--backgrounds needs --masks realistic")
    if args.backgrounds is not None and not args.backgrounds.is_dir():
        ap.error(f"--backgrounds: folder not found: {args.backgrounds}")
    try:
        backgrounds = ("" if args.backgrounds is None
                       else plates_folder(args.backgrounds, args.cache))
        config = DatasetConfig(views_per_trial=args.views, seed=args.seed, masks=args.masks,
                               backgrounds=backgrounds)
        files = training_files(args.bvh_dir)
        print(f"{len(files)} training trials (held out: {', '.join(HELD_OUT_TRIALS)}), "
              + (f"about {args.rows_per_trial} silhouettes each" if args.rows_per_trial
                 else f"{args.views} views each"), file=sys.stderr)
        start = time.perf_counter()
        views = (views_by_rows(files, config, args.rows_per_trial, args.max_views)
                 if args.rows_per_trial else None)
        if args.extra is not None:
            extra, extra_views, rows = extra_dataset_trials(
                args.extra, args.cache.parent / "cmu_extra_windows", config.fps,
                args.extra_rows_per_trial, args.max_views)
            print(f"and {len(extra)} cmu_extra trials (held out: {', '.join(EXTRA_HELD_OUT)}), "
                  f"about {rows} silhouettes", file=sys.stderr)
            files, views = files + extra, {**(views or {}), **extra_views}
        data = build_dataset(files, config, args.cache, workers=args.workers,
                             progress=lambda t, d, n: print(f"  [{d}/{n}] {t}", file=sys.stderr),
                             views=views)
    except (OSError, SilhouettePoseError) as exc:
        print(f"build_dataset: error: {exc}", file=sys.stderr)
        return 1
    elapsed = time.perf_counter() - start
    print(f"{len(data)} silhouettes in {len(set(data.sequence))} sequences, "
          f"{elapsed:.1f} s ({len(data) / elapsed:.0f} silhouettes/s with {args.workers} "
          f"workers)")
    return 0


main = stops_in_one_line("build_dataset", _main)       # Ctrl-C: one line, exit 130


if __name__ == "__main__":
    sys.exit(main())
