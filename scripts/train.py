"""Train the default model from CMU motion capture and write it (npz, no pickle).

    python scripts/train.py --bvh-dir ../shared/data/cmu/bvh \
        --out regressor/models/default_model.npz

Steps (cached under --cache, so a re-run only redoes what changed): render the training set
(held-out trials excluded), fit the shape-context codebook, compute descriptors, fit the
stacked kernel RVM, estimate the Kalman filter's noise models on validation trials; for a model
with limbs and a side classifier (the default), learn the front/back chain's priors on the
validation trials rendered four ways (regressor.canonical_priors; about 40 s).
"""
from __future__ import annotations

import contextlib
import json
import multiprocessing
import os
import signal
import sys
import threading
import time
from pathlib import Path


import numpy as np
from threadpoolctl import threadpool_limits

from regressor.angles import wrap_deg
from regressor.descriptor import DescriptorSettings
from regressor.errors import SilhouettePoseError
from regressor.layout import MAX_GRID
from regressor.limb_net import MAX_MEMBERS
from regressor.limb_net_training import require_training_dependencies
from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
from regressor.model_writer import save_pose_model
from sequences.backgrounds import plates_folder
from sequences.cmu_extra import (EXTRA_HELD_OUT, EXTRA_ROWS_PER_TRIAL, CmuExtraError,
                                 extra_dataset_trials, extra_sources, source_sequence,
                                 training_sources)
from sequences.dataset import (HELD_OUT_TRIALS, DatasetConfig, DatasetError,
                               build_dataset, trial_name, training_files, views_by_rows)
from sequences.splice import SpliceConfig, SpliceError, recipe_name, write_spliced_files
from lab.hypothesis_priors import learn_canonical_priors, prior_files
from lab.training import (VALIDATION_TRIALS, TrainingOptions, cached_descriptors,
                          cached_layouts, codebook_digest, dataset_descriptors,
                          descriptor_cache_key, fit_dataset_codebook, fit_noisy_codebook,
                          noisy_dataset_inputs, noisy_dataset_layouts, train_mixture_model,
                          train_pose_model)
from regressor.training import CANONICAL_RULES, EXPERT_CHOICES, MixtureOptions
from tracker.one_line_parser import EXIT_INTERRUPTED, OneLineParser


def _every_10000(start: float, log, what: str):
    """A progress(done, total) callback that logs ``what`` about every 10,000 masks."""
    return (lambda d, n: log(f"  {what} {d}/{n} ({time.perf_counter() - start:.0f} s)")
            if d % 10000 < 500 else None)


def _describe_clean(args, masks, settings, codebook, start: float, log, what: str):
    """Descriptors (N, K) of the clean masks (N, H, W) on the codebook (--clean); progress
    logged as ``what``."""
    return dataset_descriptors(masks, settings, codebook, workers=args.workers,
                               progress=_every_10000(start, log, what))


def _mirrored_inputs(args, data, settings, codebook, key: str, start: float, log,
                    made: dict):
    """(histograms (N, D), layouts (N, grid^2) or None) of the data set's masks' mirror
    images (flipped left to right), cached as the masks' own are (the codebook's digest in
    the key, so a new codebook never meets old mirrored descriptors). made: the arrays the
    descriptor pass already made (noisy_dataset_inputs; from scratch it makes the mirror
    images' inputs with the masks' own), else they are made here. With --clean, the clean
    flipped masks are described."""
    mirror_key = f"{key}-reflected-{codebook_digest(codebook, settings)}"

    def mirror_input(name: str):
        if name not in made:
            log("mirror images: descriptors ...")
            if args.clean:
                made["mirror_histograms"] = _describe_clean(
                    args, data.masks[:, :, ::-1], settings, codebook, start, log,
                    "mirrored descriptors")
            else:
                made.update(_noisy_inputs(args, data.masks, settings, codebook, True, start,
                                          log, "mirror images' inputs"))
        return made[name]

    X_mirror, _ = cached_descriptors(args.cache, mirror_key,
                                     lambda: (mirror_input("mirror_histograms"), codebook))
    layouts = None
    if args.layout_grid:
        layouts = cached_layouts(args.cache, mirror_key, args.layout_grid,
                                 lambda: mirror_input("mirror_layouts"))
    log(f"  mirror images ready ({time.perf_counter() - start:.0f} s so far)")
    return X_mirror, layouts


def _noisy_inputs(args, masks, settings, codebook, mirror: bool, start: float, log,
                  what: str) -> dict:
    """noisy_dataset_inputs of masks (their histograms, layouts with --layout-grid, and with
    mirror their mirror images'), progress logged as ``what``; --masks realistic: of the masks
    as they are (no hand noise)."""
    grid = args.layout_grid if args.regressor == "mixture" else 0
    return noisy_dataset_inputs(masks, settings, codebook, grid=grid, mirror=mirror,
                                seed=args.seed, workers=args.workers,
                                progress=_every_10000(start, log, what),
                                degrade=args.masks == "noisy")


def _check_numbers(ap, args) -> None:
    """Refuse absurd numeric options in one line, before the slow steps (rendering alone
    takes minutes)."""
    # --seed: numpy and scikit-learn take seeds in 0..2**32 - 1, and the experts and limb
    # networks add their index to it.
    bounds = (("--seed", args.seed, 0, 2**31 - 1),
              ("--stack", args.stack, 1, 30), ("--n-fit", args.n_fit, 1, 10**6),
              ("--rows-per-trial", args.rows_per_trial, 0, 10**6),
              ("--extra-rows-per-trial", args.extra_rows_per_trial, 1, 10**6),
              ("--spliced", args.spliced, 0, 10_000),
              ("--max-views", args.max_views, 1, 360), ("--views", args.views, 1, 360),
              ("--experts", args.experts, 1, 1000),
              ("--codebook-centres", args.codebook_centres, 10, 1000),
              ("--centres", args.centres, 1, 10**5),
              ("--layout-grid", args.layout_grid, 0, MAX_GRID),
              ("--components", args.components, 0, 10**5))
    for flag, value, low, high in bounds:
        if not low <= value <= high:
            ap.error(f"{flag} must be in {low}..{high}, got {value}")
    for flag, value in (("--width-scale", args.width_scale), ("--lam", args.lam)):
        if not (np.isfinite(value) and value > 0):
            ap.error(f"{flag} must be a positive number, got {value}")
    dims = MixtureOptions.heading_index_dims
    if args.regressor == "mixture" and args.heading_index_rows and args.components < dims:
        ap.error(f"the heading index (--heading-index-rows > 0) compares the first {dims} "
                 f"principal directions: it needs --components >= {dims}, got "
                 f"{args.components} (or pass --heading-index-rows 0)")
    if args.masks == "realistic" and args.clean:
        ap.error("--masks realistic makes video-like masks; --clean trains on the plain "
                 "renders: pass one of them")
    if args.backgrounds is not None and args.masks != "realistic":
        ap.error("--backgrounds needs --masks realistic")
    if args.backgrounds not in (None, "procedural") and not Path(args.backgrounds).is_dir():
        ap.error(f"--backgrounds: folder not found: {args.backgrounds} (a folder, or "
                 f"procedural)")
    if args.clean and args.regressor == "mixture" and args.layout_grid:
        ap.error("--layout-grid needs the video-like masks (drop --clean, or pass "
                 "--layout-grid 0)")


def _mask_settings(args) -> dict:
    """DatasetConfig's mask settings of --masks and --backgrounds: none for noisy (plain
    renders, the data set's default, so its cache key stays), else realistic masks over the
    procedural rooms ("") or the plates of --backgrounds DIR
    (sequences.backgrounds.plates_folder)."""
    if args.masks == "noisy":
        return {}
    rooms = args.backgrounds or "procedural"
    return {"masks": "realistic",
            "backgrounds": "" if rooms == "procedural" else plates_folder(rooms, args.cache)}


def _check_out(ap, args) -> None:
    """Refuse, before the slow steps, an --out that could not be written or would overwrite
    what training reads or writes: a BVH file of --bvh-dir (or a file named like one there: it
    would be read as a trial next time), or a file of the --cache (its rendered trials,
    spliced motions, descriptors and layouts)."""
    out = args.out.resolve()
    if out.parent == args.bvh_dir.resolve() and out.suffix.lower() == ".bvh":
        ap.error(f"--out {args.out} is named like the motion capture in --bvh-dir "
                 f"{args.bvh_dir}; choose another file name")
    cache = args.cache.resolve()
    if (out.parent in (cache / "dataset", cache / "spliced")
            or cache / "cmu_extra_windows" in out.parents
            or out.parent == cache and out.name.startswith(("descriptors-", "layouts-"))):
        ap.error(f"--out {args.out} would be among the files training keeps in --cache "
                 f"{args.cache}; choose another file name")
    motions = sorted(args.bvh_dir.glob("*.bvh")) if args.bvh_dir.is_dir() else []
    ap.check_outputs([("--out", args.out)], [("--bvh-dir", path) for path in motions])


def main(argv=None) -> int:
    """Train (see the module docstring); Ctrl-C ends it at once with one line, exit 130."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        return _main(argv)          # an ignored Ctrl-C (nohup, `&`) or a caller's own handler
    main_pid = os.getpid()

    def interrupted(number, frame):
        # Rendering and descriptors run in pools of worker processes, which wait for their
        # running tasks (a trial's rendering: a minute or more) before letting an interrupt
        # of this process through: `kill -INT` of it did not stop it within 5 s. So the
        # workers are stopped first. A worker (forked: it inherits this handler) leaves
        # Ctrl-C, which a terminal sends it too, to this process.
        if os.getpid() != main_pid:
            return
        # A pool's own thread then fails on the futures it was cancelling (InvalidStateError:
        # CANCELLED), even after main() has returned, and would print a traceback after the
        # one-line message: the run is over, so the threads' errors from here on are dropped
        # (not restored: the pools' threads are joined only at the interpreter's exit).
        threading.excepthook = lambda args: None
        for child in multiprocessing.active_children():
            with contextlib.suppress(OSError, ValueError):    # gone meanwhile
                child.terminate()
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, interrupted)
    try:
        return _main(argv)
    except KeyboardInterrupt:
        print("train: interrupted (finished steps stay in the --cache: a re-run resumes there)",
              file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def _main(argv) -> int:
    """Train as the options say: the data set, its inputs, the fit, the model file; the report
    as JSON on stdout, progress on stderr. Exit 0, 1 with one line on a failed step, 2 on a
    bad option."""
    args = _parse_args(argv)
    log = lambda msg: print(msg, file=sys.stderr, flush=True)  # noqa: E731
    start = time.perf_counter()
    try:
        data, config, key = _dataset(args, start, log)
        settings = DescriptorSettings()
        X, codebook, layouts, mirrored = _inputs(args, data, settings, key, start, log)
        model, options, report = _fit(args, data, config, X, codebook, settings, layouts,
                                      mirrored, log)
        _write_model(args, model, data, config, options, report, log)
        if model.mixture is not None:       # the file stores centres as float16: check it
            _check_round_trip(args, model, data, X, layouts, report)
    except (OSError, DatasetError, SpliceError, ValueError, SilhouettePoseError) as exc:
        print(f"train: error: {exc}", file=sys.stderr)
        return 1
    total = time.perf_counter() - start
    print(json.dumps({"model": str(args.out), "size_bytes": args.out.stat().st_size,
                      "total_seconds": round(total, 1), **report}, indent=1))
    return 0


def _parse_args(argv):
    """The options of argv, checked before the slow steps (one-line error, exit 2), with
    --limb-nets and --side-classifier's defaults filled in."""
    ap = OneLineParser(description=__doc__.splitlines()[0])
    _add_data_options(ap)
    _add_model_options(ap)
    args = ap.parse_args(argv)
    _check_numbers(ap, args)
    _check_model_options(ap, args)
    if not 1 <= args.workers <= 64:
        ap.error(f"--workers must be in 1..64, got {args.workers}")
    if args.heading_index_rows < 0:
        ap.error(f"--heading-index-rows must be >= 0, got {args.heading_index_rows}")
    _check_out(ap, args)
    if args.extra is not None:
        try:                # before the slow steps
            extra_sources(args.extra)
        except CmuExtraError as exc:
            ap.error(str(exc))
    return args


def _add_data_options(ap) -> None:
    """The options of the files, the data set and its masks, the regressor, seed and workers,
    and the RVM baseline's."""
    ap.add_argument("--bvh-dir", type=Path, default=Path("../shared/data/cmu/bvh"))
    ap.add_argument("--cache", type=Path, default=Path("cache"))
    ap.add_argument("--out", type=Path, default=DEFAULT_MODEL_PATH)
    ap.add_argument("--views", type=int, default=DatasetConfig.views_per_trial,
                    help="views rendered per trial with --rows-per-trial 0 (default "
                         f"{DatasetConfig.views_per_trial}); otherwise the rows decide")
    ap.add_argument("--stack", type=int, default=TrainingOptions.stack_depth)
    ap.add_argument("--n-fit", type=int, default=TrainingOptions.n_fit)
    ap.add_argument("--width-scale", type=float, default=TrainingOptions.width_scale)
    ap.add_argument("--rows-per-trial", type=int, default=800,
                    help="views per trial chosen to give about this many silhouettes per trial "
                         "(1..--max-views); 0: --views for every trial")
    ap.add_argument("--max-views", type=int, default=10)
    ap.add_argument("--spliced", type=int, default=0,
                    help="also train on this many spliced motions: a training trial whose "
                         "limbs come from other training trials (sequences.splice; validation "
                         "trials never take part), rendered as the trials are; default 0 (24 "
                         "did not help on real video: docs/accuracy.md, 2026-12-04)")
    ap.add_argument("--extra", type=Path, default=None,
                    help="also train on the converted cmu_extra sequences in this folder "
                         "(python scripts/convert_cmu_extra.py --out DIR), those of "
                         "sequences.cmu_extra.EXTRA_HELD_OUT left out; default none")
    ap.add_argument("--extra-rows-per-trial", type=int, default=EXTRA_ROWS_PER_TRIAL,
                    help="with --extra: about this many silhouettes per converted sequence "
                         "(views of a short one, windows of a long one; default "
                         f"{EXTRA_ROWS_PER_TRIAL}, which keeps training within an hour)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2,
                    help="processes for rendering and descriptors, threads for the mixture, "
                         "and limb networks fitted at once (default 2)")
    ap.add_argument("--regressor", choices=("mixture", "rvm"), default="mixture",
                    help="mixture of kernel experts (default) or the single RVM baseline")
    ap.add_argument("--clean", action="store_true",
                    help="train on the clean renders (default: video-like silhouettes, "
                         "sequences.mask_noise)")
    ap.add_argument("--masks", choices=("noisy", "realistic"), default="noisy",
                    help="noisy: plain renders degraded by hand-written noise "
                         "(sequences.mask_noise; default); realistic: rendered over a room, "
                         "H.264, cut out by the tracker's extractor (docs/render_to_real.md), "
                         "learnt from as they are (no hand noise on top)")
    ap.add_argument("--backgrounds", default=None, metavar="DIR|procedural",
                    help="with --masks realistic: the rooms, procedural (our synthetic rooms; "
                         "the default) or a folder of plate-*.png or of Pose2Sim trials (their "
                         "plates made once into CACHE/plates; they are the real test trials' "
                         "rooms: a model trained over them and judged on Pose2Sim has seen "
                         "the test scenes)")


def _add_model_options(ap) -> None:
    """The options of the mixture of experts, its limb head, networks and side classifier."""
    ap.add_argument("--expert", choices=tuple(EXPERT_CHOICES), default=MixtureOptions.expert,
                    help="the mixture's experts: sparse RVMs over --centres candidate kernels "
                         "each, fitted on all their rows, with a predictive variance per "
                         "frame (default), or damped least squares on --centres kernels (dls)")
    ap.add_argument("--variance", choices=("off", "on"), default="off",
                    help="with sparse RVM experts, also store their predictive variance "
                         "(regressor.optional_parts.predict_variance): about 15 MB at 24 x 400 "
                         "centres; as the filter's per-frame R it did not pay "
                         "(docs/rvm_experts.md); default off")
    ap.add_argument("--experts", type=int, default=MixtureOptions.n_experts)
    ap.add_argument("--centres", type=int, default=MixtureOptions.n_centres)
    ap.add_argument("--lam", type=float, default=MixtureOptions.lam)
    ap.add_argument("--partition", choices=("input", "descriptor", "pose", "joint"),
                    default=MixtureOptions.partition)
    ap.add_argument("--codebook-centres", type=int, default=100,
                    help="k-means centres of the shape-context codebook, the length of each "
                         "frame's histogram (default 100, the paper's; 300 did no better: "
                         "docs/accuracy.md, stop 47)")
    ap.add_argument("--layout-grid", type=int, default=MixtureOptions.layout_grid,
                    help="silhouette layout cells per side added to each frame's descriptor "
                         "(regressor.layout; 0: shape contexts only)")
    ap.add_argument("--canonical", choices=CANONICAL_RULES, default=MixtureOptions.canonical,
                    help="fit each pose's canonical member of {pose, front/back flip}: the "
                         "side of the limbs' principal flip direction, or the one facing the "
                         "camera's half (the tracker's chain then picks the member, limbs "
                         "included); default none")
    ap.add_argument("--limb-head", choices=CANONICAL_RULES, default=None,
                    help="also fit the experts on each pose's canonical member by this rule, "
                         "for the tracker's limbs (regressor.optional_parts.LimbHead); default "
                         f"{MixtureOptions.limb_head}, none with --canonical")
    ap.add_argument("--limb-nets", type=int, default=None,
                    help="fit the limb head as an ensemble of this many neural networks "
                         "(regressor.limb_net; needs scikit-learn: pip install -e '.[train]'); "
                         "0: a second set of expert weights instead; default "
                         f"{MixtureOptions.limb_net_members} with a limb head")
    ap.add_argument("--limb-net-mirror", choices=("on", "off"), default="on",
                    help="fit the limb networks on every training silhouette's mirror image "
                         "too (the masks flipped left to right; their descriptors are cached "
                         "beside the others); default on")
    ap.add_argument("--limb-net-noise", type=float, default=MixtureOptions.limb_net_noise,
                    help="fit the limb networks with fresh Gaussian noise on their inputs each "
                         "epoch, this fraction of each input's spread (regressor.limb_net; "
                         f"default {MixtureOptions.limb_net_noise})")
    ap.add_argument("--limb-net-output", choices=("euler", "rot6d"),
                    default=MixtureOptions.limb_net_output,
                    help="what the limb networks regress: each joint's Euler angles about their "
                         "training means, or its rotation as 6 numbers (regressor.rotation6d; "
                         f"default {MixtureOptions.limb_net_output})")
    ap.add_argument("--limb-net-reversed", type=float,
                    default=MixtureOptions.limb_net_reversed,
                    help="fit the limb networks on this share (0..1) of the training rows "
                         "played backwards too (their stacked frames in reverse order; "
                         f"default {MixtureOptions.limb_net_reversed})")
    ap.add_argument("--limb-net-epochs", type=int, default=MixtureOptions.limb_net_epochs,
                    help="at most this many epochs per limb network (each stops earlier when "
                         "its held-out tenth stops gaining; default "
                         f"{MixtureOptions.limb_net_epochs})")
    ap.add_argument("--side-classifier", choices=("on", "off"), default=None,
                    help="with limbs, also fit the front/back side classifier "
                         "(regressor.side_classifier; needs scikit-learn); the tracker then "
                         "carries the limbs' canonical member and its flip; default on with "
                         "a limb head, off without")
    ap.add_argument("--heading-index-rows", type=int, default=MixtureOptions.heading_index_rows,
                    help="training rows kept for the nearest-neighbour heading "
                         "(regressor.heading_index; needs --components >= 50; 0: none)")
    ap.add_argument("--components", type=int, default=MixtureOptions.components,
                    help="principal directions the stacked input is projected on (0: none)")


def _check_model_options(ap, args) -> None:
    """Refuse in one line the regressor's options that do not go together, and fill in the
    defaults of --limb-nets and --side-classifier (they depend on the limb head)."""
    if args.limb_head not in (None, "none"):
        if args.regressor != "mixture":
            ap.error("--limb-head needs the mixture regressor")
        if args.canonical != "none":
            ap.error("a model fitted on canonical members (--canonical) takes no --limb-head")
    if args.limb_nets is not None:
        if not 0 <= args.limb_nets <= MAX_MEMBERS:
            ap.error(f"--limb-nets must be in 0..{MAX_MEMBERS}, got {args.limb_nets}")
        if args.limb_nets and (args.regressor != "mixture" or _limb_head(args) == "none"):
            ap.error("--limb-nets needs the mixture regressor with a limb head")
    elif args.regressor == "mixture" and _limb_head(args) != "none":
        args.limb_nets = MixtureOptions.limb_net_members
    else:
        args.limb_nets = 0
    has_limbs = args.regressor == "mixture" and _limb_head(args) != "none"
    if has_limbs and not args.limb_nets and args.expert != "dls":
        ap.error("a limb head of expert weights (--limb-nets 0) needs --expert dls; pass "
                 "--limb-head none for a model without limbs")
    if args.side_classifier == "on" and not has_limbs:
        ap.error("--side-classifier needs the mixture regressor with a limb head")
    if args.side_classifier is None:
        args.side_classifier = "on" if has_limbs else "off"
    if not 0.0 <= args.limb_net_reversed <= 1.0:
        ap.error(f"--limb-net-reversed must be in 0..1, got {args.limb_net_reversed}")
    if not 0.0 <= args.limb_net_noise <= 2.0:
        ap.error(f"--limb-net-noise must be in 0..2, got {args.limb_net_noise}")
    if not 1 <= args.limb_net_epochs <= 1000:
        ap.error(f"--limb-net-epochs must be in 1..1000, got {args.limb_net_epochs}")
    if args.limb_nets or args.side_classifier == "on":
        try:       # before the slow steps, not after them
            require_training_dependencies()
            if args.side_classifier == "on":
                prior_files(args.bvh_dir)
        except ValueError as exc:
            ap.error(str(exc))


def _dataset(args, start: float, log):
    """(data set, its DatasetConfig, the cache key of its descriptors): the training trials
    rendered (cached under --cache), with --spliced motions and --extra sequences; the key
    names the rows and masks, so other rows never meet these descriptors."""
    config = DatasetConfig(views_per_trial=args.views, seed=args.seed,
                           **_mask_settings(args))
    files = training_files(args.bvh_dir)
    per_trial = (f"1-{args.max_views} views each for about {args.rows_per_trial} "
                 f"silhouettes" if args.rows_per_trial else f"{args.views} views")
    log(f"data set: {len(files)} trials x {per_trial} (held out: "
        f"{', '.join(HELD_OUT_TRIALS)})")
    splice = None
    if args.spliced:
        sources = [f for f in files if trial_name(f) not in VALIDATION_TRIALS]
        splice = SpliceConfig(n_motions=args.spliced, seed=args.seed)
        files = files + write_spliced_files(sources, splice, args.cache / "spliced")
        log(f"  and {args.spliced} spliced motions of {len(sources)} trials "
            f"({time.perf_counter() - start:.0f} s so far)")
    views = (views_by_rows(files, config, args.rows_per_trial, args.max_views)
             if args.rows_per_trial else None)
    if args.extra is not None:
        extra, extra_views, rows = extra_dataset_trials(
            args.extra, args.cache / "cmu_extra_windows", config.fps,
            args.extra_rows_per_trial, args.max_views)
        log(f"  and cmu_extra: {len(extra)} trials from --extra {args.extra} (held out: "
            f"{', '.join(EXTRA_HELD_OUT)}), about {rows} silhouettes")
        files, views = files + extra, {**(views or {}), **extra_views}
    data = build_dataset(files, config, args.cache / "dataset", workers=args.workers,
                         progress=lambda t, d, n: log(f"  rendered {t} [{d}/{n}]"),
                         views=views)
    log(f"  {len(data)} silhouettes ({time.perf_counter() - start:.0f} s so far)")
    key = (f"v1-{config.digest()}" if views is None and args.clean else
           descriptor_cache_key(config, views,
                                noisy=not args.clean and args.masks == "noisy"))
    if args.codebook_centres != 100:     # the default's key stays what its caches are under
        key += f"-cb{args.codebook_centres}"
    if splice is not None and views is None:  # the views then name no trial: say which
        key += "-" + recipe_name(splice, sources)
    return data, config, key


def _inputs(args, data, settings, key: str, start: float, log):
    """(descriptors (N, K), codebook, layouts (N, grid^2) or None, mirror images' (histograms,
    layouts) or None) of the data set's masks, each cached under --cache by key."""
    # From scratch, one pass over the video-like masks makes their histograms, layouts
    # and mirror images' inputs together (each mask degraded and described once).
    want_mirror = (args.regressor == "mixture" and bool(args.limb_nets)
                   and args.limb_net_mirror == "on")
    made: dict = {}

    def compute():
        log("codebook and descriptors ...")
        # Realistic masks are video-like already: their codebook is the plain one's.
        fit = (fit_noisy_codebook if args.masks == "noisy" and not args.clean
               else fit_dataset_codebook)
        codebook = fit(data, settings, n_centres=args.codebook_centres, seed=args.seed)
        if args.clean:
            return _describe_clean(args, data.masks, settings, codebook, start, log,
                                   "descriptors"), codebook
        made.update(_noisy_inputs(args, data.masks, settings, codebook, want_mirror,
                                  start, log, "descriptors"))
        return made["histograms"], codebook

    X, codebook = cached_descriptors(args.cache, key, compute)
    log(f"  descriptors ready ({time.perf_counter() - start:.0f} s so far)")
    layouts = None
    if args.regressor == "mixture" and args.layout_grid:
        layouts = cached_layouts(
            args.cache, key, args.layout_grid,
            lambda: made["layouts"] if "layouts" in made else
            noisy_dataset_layouts(data.masks, args.layout_grid, seed=args.seed,
                                  workers=args.workers, degrade=args.masks == "noisy"))
        log(f"  layouts ready ({time.perf_counter() - start:.0f} s so far)")
    mirrored = None
    if want_mirror:
        mirrored = _mirrored_inputs(args, data, settings, codebook, key, start, log, made)
    return X, codebook, layouts, mirrored


def _fit(args, data, config, X, codebook, settings, layouts, mirrored, log):
    """(model, its options, validation report): the RVM baseline or the mixture of experts
    (with its limb networks and side classifier) fitted on the data set's inputs, BLAS and
    the mixture's threads limited to --workers."""
    if args.regressor == "rvm":
        options = TrainingOptions(stack_depth=args.stack, n_fit=args.n_fit,
                                  width_scale=args.width_scale, seed=args.seed)
        with threadpool_limits(args.workers):
            model, report = train_pose_model(data, X, codebook, settings, options,
                                             config.fps, log=log)
    else:
        options = _mixture_options(args)
        with threadpool_limits(args.workers):
            model, report = train_mixture_model(data, X, codebook, settings, options,
                                                config.fps, log=log, layouts=layouts,
                                                mirrored=mirrored, workers=args.workers)
    return model, options, report


def _mixture_options(args) -> MixtureOptions:
    """The mixture's MixtureOptions of the options; --width-scale only when given other than
    its default (the RVM baseline's), so the mixture keeps its own default."""
    return MixtureOptions(stack_depth=args.stack, n_experts=args.experts,
                          expert=args.expert,
                          n_centres=args.centres, lam=args.lam, seed=args.seed,
                          partition=args.partition, layout_grid=args.layout_grid,
                          components=args.components, canonical=args.canonical,
                          limb_head=_limb_head(args),
                          heading_index_rows=args.heading_index_rows,
                          limb_net_members=args.limb_nets,
                          limb_net_noise=args.limb_net_noise,
                          limb_net_epochs=args.limb_net_epochs,
                          limb_net_output=args.limb_net_output,
                          limb_net_reversed=args.limb_net_reversed,
                          limb_net_mirror=bool(args.limb_nets)
                          and args.limb_net_mirror == "on",
                          side_classifier=args.side_classifier == "on",
                          **({"width_scale": args.width_scale}
                             if args.width_scale != TrainingOptions.width_scale else {}))


def _write_model(args, model, data, config, options, report: dict, log) -> None:
    """Write the model to --out with its description (model_description; the predictive
    variance dropped unless --variance on), then, for a model giving canonical pairs, learn
    its chain's priors into the file."""
    report["noise_aware"] = not args.clean
    if args.variance == "off":
        model.variance_calibration = None
    model.description = model_description(data, config, options, report,
                                          extra=args.extra is not None)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    save_pose_model(args.out, model)
    if model.gives_canonical_pairs:
        _learn_priors(args, model, report, log)


def _check_round_trip(args, model, data, X, layouts, report: dict) -> None:
    """Record in report how far the model loaded back from --out (centres and the heading
    index's inputs stored as float16) predicts from the fitted one, in degrees: the angles'
    max, the heading's median and max, the limbs' max, on about 500 of the data set's rows."""
    from regressor.optional_parts import predict_batch, predict_limbs
    from regressor.pose_model import frame_descriptors
    from regressor.stacking import stack_frames
    from sequences.pose_vector import heading_deg
    rows = slice(0, len(X), max(1, len(X) // 500))
    probe = stack_frames(frame_descriptors(X, model.transform, layouts,
                                           model.layout_weight),
                         model.stack_depth, sequence_ids=data.sequence)[rows]
    loaded = load_pose_model(args.out)
    before, after = predict_batch(model, probe), predict_batch(loaded, probe)
    diff = np.abs(wrap_deg(after[:, 2:] - before[:, 2:]))
    report["file_round_trip_max_deg"] = round(float(diff.max()), 3)
    # The heading too: the index's inputs are stored as float16, which can change a
    # query's neighbours.
    diff = np.abs(wrap_deg(heading_deg(after) - heading_deg(before)))
    report["heading_round_trip_deg"] = {"median": round(float(np.median(diff)), 3),
                                        "max": round(float(diff.max()), 3)}
    if model.has_limbs:
        diff = np.abs(wrap_deg(predict_limbs(loaded, probe)[:, 2:]
                               - predict_limbs(model, probe)[:, 2:]))
        report["limbs_round_trip_max_deg"] = round(float(diff.max()), 3)


def model_description(data, config, options, report: dict, extra: bool) -> dict:
    """What the model file records of its training: the trials (windows of a long cmu_extra
    sequence named once, by the sequence), the rows, frames and sequences of each source
    (sequences.cmu_extra.training_sources; ``python -m regressor describe`` prints them), the
    held-out trials (the cmu_extra ones too with extra), the data set's settings, the
    options and the validation report."""
    return {"data": "CMU motion capture (mocap.cs.cmu.edu), rendered",
            "trials": list(dict.fromkeys(map(source_sequence, data.trials))),
            "sources": training_sources(np.asarray(data.trial_of_sequence)[data.sequence],
                                        data.frame),
            "held_out": list(HELD_OUT_TRIALS) + (list(EXTRA_HELD_OUT) if extra else []),
            "dataset": json.loads(json.dumps(config.__dict__)),
            "options": options.__dict__, "validation": report}


def _learn_priors(args, model, report: dict, log) -> None:
    """The front/back chain's priors for the model just written to args.out
    (regressor.canonical_priors), learned on validation renders as ``track`` will see the
    model: loaded from the file (its centres are float16 there), one BLAS thread. Written
    into the file; if they cannot be learned, the file stays as it is, with a warning."""
    log("learning the canonical chain's priors on the validation renders ...")
    start = time.perf_counter()
    saved = load_pose_model(args.out)
    try:
        with threadpool_limits(1):
            priors, stats = learn_canonical_priors(saved, prior_files(args.bvh_dir))
    except ValueError as exc:
        log(f"train: warning: no canonical priors ({exc}); {args.out} is kept without them "
            f"(tracker.tracks.hypotheses' defaults apply)")
        return
    report["canonical_priors"] = stats
    saved.canonical_priors = model.canonical_priors = priors
    saved.description["validation"]["canonical_priors"] = stats
    save_pose_model(args.out, saved)
    log(f"  canonical priors: switch {stats['switch_probability']}, the canonical member the "
        f"truer on {stats['canonical_overall']:.3f} of frames "
        f"({time.perf_counter() - start:.0f} s)")


def _limb_head(args) -> str:
    """--limb-head as given, else the default, which is "none" for a canonical model."""
    if args.limb_head is not None:
        return args.limb_head
    return "none" if args.canonical != "none" else MixtureOptions.limb_head


if __name__ == "__main__":
    sys.exit(main())
