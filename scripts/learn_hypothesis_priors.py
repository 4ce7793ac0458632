"""Learn the front/back hypotheses' priors: the regressor's flip statistics on its validation
trials rendered as spiral walks.

    python scripts/learn_hypothesis_priors.py [--cmu ../shared/data/cmu/bvh] [--model FILE]
        [--skip-regressor] [--weights] [--save OUT]

Prints the values that tracker/tracks/hypotheses.py (SWITCH_PROBABILITY; with --weights
EVIDENCE_WEIGHT, which should be chosen after the others are in place) and
tracker/tracks/flip_hypotheses.py (RAW_NEARER_BY_NORM) hold; for a model with limbs and a side
classifier (the default), also the canonical chain's priors on the 28 validation renders
(regressor.canonical_priors; the model file carries them), and with --save OUT writes the
model with those priors to OUT (a new file: never the model itself).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from threadpoolctl import threadpool_limits

import numpy as np

from regressor.pose_model import DEFAULT_MODEL_PATH, PoseModelError, load_pose_model

from regressor.model_writer import save_pose_model
from lab.hypothesis_priors import (choose_weights, learn_canonical_priors, prior_files,
                                               regressor_flip_statistics, replay_heading_rms,
                                               top_experts, validation_renders)
from lab.training import VALIDATION_TRIALS
from tracker.one_line_parser import OneLineParser

CMU = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "cmu" / "bvh"


def main(argv=None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cmu", type=Path, default=CMU)
    ap.add_argument("--model", type=Path, default=DEFAULT_MODEL_PATH)
    ap.add_argument("--skip-regressor", action="store_true")
    ap.add_argument("--weights", action="store_true",
                    help="also choose EVIDENCE_WEIGHT on validation renders")
    ap.add_argument("--experts", type=_numbers(int), default=None,
                    help="comma-separated numbers of a mixture's experts (DEFAULT_EXPERTS) to "
                         "compare by filtered heading RMS on the same validation renders, with "
                         "the current EVIDENCE_WEIGHT")
    ap.add_argument("--save", type=Path, default=None,
                    help="write the model with the canonical priors learned here to this new "
                         "file (a model with limbs and a side classifier)")
    args = ap.parse_args(argv)
    if args.save is not None:
        if args.skip_regressor:
            ap.error("--save needs the regressor's statistics (drop --skip-regressor)")
        if args.save.resolve() == args.model.resolve():
            ap.error(f"--save {args.save} would overwrite the model it reads; give a new file")
        if args.save.exists():
            ap.error(f"--save {args.save} exists; give a new file")
    try:
        model = load_pose_model(args.model)
    except PoseModelError as exc:
        ap.exit(1, f"learn_hypothesis_priors: {exc}\n")
    # Every file the run reads, checked before the slow steps.
    files = (prior_files(args.cmu, check=False)
             if not args.skip_regressor or args.weights or args.experts else [])
    missing = [f for f in files if not f.is_file()]
    if missing:
        ap.error(f"--cmu {args.cmu}: {missing[0].name} not found (the run needs the CMU trials "
                 f"{', '.join(sorted({f.stem for f in files}))})")
    if args.save is not None and not model.gives_canonical_pairs:
        ap.error(f"--save: {args.model} has no side classifier and limbs, so no canonical priors")
    if not args.skip_regressor:
        with threadpool_limits(1):
            stats = regressor_flip_statistics(model,
                                              [args.cmu / f"{t}.bvh" for t in VALIDATION_TRIALS])
        print(json.dumps(stats, indent=1))
    if not args.skip_regressor and model.gives_canonical_pairs:
        # the canonical chain's priors (regressor.canonical_priors), on the 28 renders
        with threadpool_limits(1):
            priors, stats = learn_canonical_priors(model, files)
        print(f"canonical chain priors over the validation renders (the model carries "
              f"{'its own' if model.canonical_priors is not None else 'none'}):")
        print(json.dumps(stats, indent=1))
        if args.save is not None:
            model.canonical_priors = priors
            if args.save.exists():            # it may have appeared during the run
                ap.exit(1, f"learn_hypothesis_priors: {args.save} appeared during the run; "
                           f"not overwritten\n")
            try:
                save_pose_model(args.save, model)
            except (PoseModelError, OSError) as exc:
                ap.exit(1, f"learn_hypothesis_priors: cannot write {args.save}: {exc}\n")
            print(f"wrote {args.save}: the model with these priors")
    # The model as it now is (with the priors learned above when --save wrote them).
    if args.weights:
        _choose_weights(model, files)
    if args.experts:
        _compare_experts(model, files, list(args.experts))
    return 0


def _numbers(kind):
    """An argparse type: comma-separated positive numbers of this kind, as a tuple."""
    def parse(text: str) -> tuple:
        try:
            values = tuple(kind(x) for x in text.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not comma-separated "
                                             f"{kind.__name__} values") from None
        if not all(v > 0 for v in values):
            raise argparse.ArgumentTypeError(f"{text!r}: every value must be positive")
        return values
    return parse


def _compare_experts(model, files, counts) -> None:
    with threadpool_limits(1):
        renders = validation_renders(model, files, n_experts=max(counts))
        for m in counts:
            rms = [replay_heading_rms(model, top_experts(r, m)) for r in renders.values()]
            print(f"experts {m}: mean filtered heading RMS {np.mean(rms):.1f} deg over "
                  f"{len(rms)} validation renders", flush=True)


def _choose_weights(model, files) -> None:
    with threadpool_limits(1):
        renders = validation_renders(model, files)
        best, table = choose_weights(model, renders)
    print("mean filtered heading RMS (deg) over", len(renders), "validation renders:")
    for ew, rms in table.items():
        print(f"  evidence_weight {ew:.2f}: {np.mean(list(rms.values())):.1f}")
    print(f"EVIDENCE_WEIGHT = {best:.3g}")


if __name__ == "__main__":
    raise SystemExit(main())
