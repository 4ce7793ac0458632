"""Reproduce the paper's regressors on its released data (train split only; test = spiral walk).

    python scripts/reproduce_paper.py --data ../shared/data/ankur/ankurDataPoseSilhouette.mat --json out.json

Every hyperparameter (descriptor transform, damping, kernel width, RVM noise and cost, stacking
depth) is chosen by blocked cross-validation on the 1927 training frames (5 contiguous blocks);
the RVMs pick the lowest-error setting within a sparsity budget (kernel: fold models keep <= 10%
of their training frames; linear: <= 30% of the features).

Every method but one answers each frame alone. ``mixture_rvm_tracked`` decodes the whole test
sequence at once: the most probable chain of the mixture's experts' poses, each frame's gate
probabilities against Gaussian steps as large as the training motion's
(regressor.hypothesis_path): offline, over the whole clip, as a smoother works (the tracker
itself does not decode experts; its ``--smooth`` chains front/back states and limb members).
Its experts, gate and the weight of the steps are chosen by the same cross-validation, each
held-out block decoded as the pieces of training sequences it holds. ``mixture_rvm_bagged``
answers each frame alone but is not one mixture: the mean of BAGS mixtures' most probable poses
(``mixture_rvm_stacked``'s settings, seeds 0..BAGS-1).

A --data that is not the paper's data (missing, not a MATLAB file, cut short, without its four
arrays of numbers at their shapes) or a --json that could not be written or is the --data file
(also through a link) is refused before any work (exit 2); a failure on the data later is one
line naming the file (exit 1), Ctrl-C one line (exit 130). --json is written whole or not at
all.
"""
from __future__ import annotations

import itertools
import json
import sys
import time

import numpy as np

from regressor.dls import DLSRegressor
from regressor.errors import SilhouettePoseError
from regressor.hypothesis_path import step_variance
from regressor.mixture import MixtureRegressor
from regressor.metrics import contiguous_folds, cross_validate, mean_point_error, point_jitter
from regressor.rvm import RVMRegressor
from regressor.stacking import sequence_starts_to_ids, stack_frames
from sequences.measures import DEFAULT_TOP_ANGLES, correlation, skill
from tracker.offline.evaluation import EvaluationError, load_ankur
from tracker.one_line_parser import OneLineParser, stops_in_one_line
from tracker.sinks.files import OutputWriteError, write_whole

TRAIN_STARTS = [0, 100, 336, 405, 471, 1530, 1768]   # the 7 training sequences (README)
RV_BUDGET = 0.10                                     # kernel RVM: keep <= 10% of training frames
FEATURE_BUDGET = 0.30                                # linear RVM: keep <= 30 of the 100 features
class MeanPose:
    """Predicts the mean training pose (the trivial baseline)."""
    n_basis_ = 0

    def fit(self, X, Y):
        self.mean_ = Y.mean(0)
        return self

    def predict(self, X):
        return np.tile(self.mean_, (len(X), 1))


class NearestNeighbours:
    """Mean pose of the k nearest training descriptors (Euclidean); keeps every training frame."""

    def __init__(self, k: int = 3):
        self.k = k

    def fit(self, X, Y):
        self.X_, self.Y_, self.n_basis_ = X, Y, len(X)
        return self

    def predict(self, X):
        d2 = (X * X).sum(1)[:, None] - 2 * X @ self.X_.T + (self.X_ * self.X_).sum(1)[None]
        return self.Y_[np.argsort(d2, axis=1)[:, :self.k]].mean(1)


class MixtureRVM(MixtureRegressor):
    """The mixture of RVM experts (regressor.mixture, after Agarwal & Triggs 2005): each expert
    a kernel RVM with the single kernel RVM's chosen settings (rvm_params), and the count of
    basis functions its experts keep, as the table reports for every method, plus the training
    rows a neighbour gate keeps (as kNN's count is its training rows)."""

    rvm_params: dict = {}

    def _new_expert(self, e: int):
        return RVMRegressor("gaussian", output_scale="common", **self.rvm_params)

    @property
    def n_basis_(self) -> int:
        kept = getattr(self.gate_, "X_", ())
        return int(sum(e.n_basis_ for e in self.experts_)) + len(kept)


#: Mixtures averaged by mixture_rvm_bagged. The training split's blocked cross-validation
#: falls with more and levels off (the stacked input, the chosen mixture: 1 / 10 / 20 seeds
#: 3.055 / 2.977 / 2.975; 2026-12-04, one-off /work/tmp/s44/bag_paper.py).
BAGS = 10


class BaggedMixture:
    """``bags`` mixtures of RVM experts alike but for their seed (the k-means of their
    partition, their experts' own), each frame's answer the mean of their most probable
    poses: where one mixture's partition cuts a motion arbitrarily, the others cut it
    elsewhere (bagging over initialisations; every member sees every training row). Not one
    mixture's most probable pose, which the issue asks of ``mixture_rvm``: a row of its own."""

    def __init__(self, bags: int, **mix):
        self.bags, self.mix = bags, mix

    def fit(self, X, Y):
        self.members_ = [MixtureRVM(expert="rvm", rvm_rows=len(X), seed=seed, **self.mix)
                         .fit(X, Y) for seed in range(self.bags)]
        return self

    def predict(self, X):
        return np.mean([member.predict(X) for member in self.members_], axis=0)

    @property
    def n_basis_(self) -> int:
        return int(sum(member.n_basis_ for member in self.members_))


class TrackedMixture:
    """The mixture's experts' poses resolved over time: the most probable chain of them over the
    whole test sequence (MixtureRegressor.predict_path), not each frame's favourite alone. The
    step variance is the training sequences' own (sequence_ids: (N,) label per training row)."""

    def __init__(self, mixture: MixtureRVM, continuity: float, sequence_ids):
        self.mixture, self.continuity, self.sequence_ids = mixture, continuity, sequence_ids

    def fit(self, X, Y):
        self.mixture.fit(X, Y)
        self.step_var_ = step_variance(Y, self.sequence_ids)
        self.n_basis_ = self.mixture.n_basis_
        return self

    def predict(self, X):
        """X: one test sequence, in time order."""
        return self.mixture.predict_path(X, self.step_var_, self.continuity)


def run_labels(rows: np.ndarray, sequence_ids: np.ndarray) -> np.ndarray:
    """A label per row of rows (sorted indices) that changes wherever two neighbours are not
    consecutive frames of one sequence (a held-out block cut out, or a new sequence)."""
    rows = np.asarray(rows)
    if len(rows) == 0:
        return np.zeros(0, dtype=np.int64)
    breaks = (np.diff(rows) != 1) | (np.diff(sequence_ids[rows]) != 0)
    return np.concatenate([[0], np.cumsum(breaks)])


def choose_tracked(mixtures, continuities, neighbours, X, Y, folds, sequence_ids, log=print):
    """(mixture parameters, continuity) of the neighbour-gated mixture whose most probable
    chain of poses has the lowest CV error; every held-out block is decoded as the pieces of
    sequences it holds. The experts are fitted once per fold and mixture setting; the gate's
    neighbour count only re-reads the stored rows."""
    results = []
    for params in mixtures:
        fits = []
        for hold in folds:
            train = np.setdiff1d(np.arange(len(X)), hold)
            model = MixtureRVM(expert="rvm", rvm_rows=len(X), gate="neighbours", **params)
            model.fit(X[train], Y[train])
            fits.append((model, step_variance(Y[train], run_labels(train, sequence_ids)), hold))
        for k, c in itertools.product(neighbours, continuities):
            total = 0.0
            for model, step_var, hold in fits:
                # The gate keeps every training row: another k only re-reads them.
                model.set_params(gate_neighbours=k)
                model.gate_.n_neighbours = k
                P = model.predict_path(X[hold], step_var, c,
                                       sequence_ids=run_labels(hold, sequence_ids))
                total += mean_point_error(P, Y[hold]) * len(hold)
            err = total / len(X)
            log(f"    {dict(params, gate_neighbours=k)}, continuity {c}: cv error {err:.3f}")
            results.append((err, dict(params, gate_neighbours=k), c))
    err, params, c = min(results, key=lambda r: r[0])
    log(f"    chosen: {params}, continuity {c} (cv error {err:.3f})")
    return params, c


def choose(make, grid, X, Y, folds, budget=None, features=False, log=print):
    """The grid point (dict) with the lowest CV error; with a budget, among those whose fold
    models keep <= budget of their candidate bases (training rows, or features if features)
    (else the sparsest)."""
    results = []
    for params in grid:
        err, models = cross_validate(lambda: make(**params), X, Y, folds)
        frac = max(m.n_basis_ / (X.shape[1] if features else len(X) - len(f)) for m, f in zip(models, folds))
        log(f"    {params}: cv error {err:.3f}, kept {100 * frac:.1f}%")
        results.append((err, frac, params))
    ok = [r for r in results if budget is None or r[1] <= budget] or [min(results, key=lambda r: r[1])]
    return min(ok, key=lambda r: r[0])[2]


def grid(**axes):
    return [dict(zip(axes, v)) for v in itertools.product(*axes.values())]


def _main(argv) -> int:
    ap = OneLineParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", required=True, help="ankurDataPoseSilhouette.mat")
    ap.add_argument("--json", help="write the results here")
    args = ap.parse_args(argv)
    # Before the minutes of work: by the file, so a hard link to --data is refused too.
    ap.check_outputs([("--json", args.json)], [("--data", args.data)])
    try:
        d = load_ankur(args.data)
    except EvaluationError as exc:
        ap.error(f"--data {exc}")
    try:
        report = _reproduce(d)
    except SilhouettePoseError as exc:        # numbers the regressors cannot use
        print(f"reproduce_paper: error: --data {args.data}: {exc}", file=sys.stderr)
        return 1
    if args.json:
        try:             # whole or not at all: a re-run's --json keeps the last complete one
            write_whole(args.json, lambda path: path.write_text(json.dumps(report, indent=2)))
        except OutputWriteError as exc:
            print(f"reproduce_paper: error: {exc}", file=sys.stderr)
            return 1
    return 0


def _reproduce(d: dict) -> dict:
    """The whole run on the paper's data d (load_ankur): the table on stdout, the report
    as a JSON-ready dict."""
    Xraw, Y, Xraw_test, Y_test = d["Y"], d["Z"], d["Y_test"], d["Z_test"]
    folds = contiguous_folds(len(Xraw), 5)

    print("choosing hyperparameters on the training set (5 contiguous blocks)")
    transforms = {"none": lambda A: A, "sqrt": np.sqrt}
    tname = min(transforms, key=lambda t: cross_validate(
        lambda: DLSRegressor("gaussian", lam=1e-2, width_scale=0.5), transforms[t](Xraw), Y, folds)[0])
    X, X_test = transforms[tname](Xraw), transforms[tname](Xraw_test)
    print(f"  descriptor transform: {tname}")
    print("  linear DLS"); lin = choose(lambda **p: DLSRegressor("linear", **p), grid(lam=[1e-3, 1e-2, 1e-1, 1.0]), X, Y, folds)
    print("  linear RVM"); lrvm = choose(lambda **p: RVMRegressor("linear", output_scale="common", **p),
                                        grid(min_gain=[300.0, 1000.0, 3000.0]), X, Y, folds,
                                        budget=FEATURE_BUDGET, features=True)
    print("  kernel DLS"); kdls = choose(lambda **p: DLSRegressor("gaussian", **p),
                                        grid(width_scale=[0.25, 0.5, 1.0], lam=[1e-3, 1e-2]), X, Y, folds)
    print("  kernel RVM"); krvm = choose(lambda **p: RVMRegressor("gaussian", output_scale="common", **p),
                                        grid(width_scale=[kdls["width_scale"]], noise=[0.03, 0.05, 0.1],
                                             min_gain=[200.0, 400.0, 800.0]), X, Y, folds, budget=RV_BUDGET)
    print("  mixture of RVM experts")
    MixtureRVM.rvm_params = krvm
    # Two gates (regressor.mixture): the softmax gate the tracker's models use, and the
    # regions of the nearest training descriptors, which suits this small set.
    mix = choose(lambda **p: MixtureRVM(expert="rvm", rvm_rows=len(X), **p),
                 grid(n_experts=[2, 4, 8], overlap=[0.2], gate=["softmax"])
                 + grid(n_experts=[4, 8, 16], overlap=[0.2, 0.5], gate=["neighbours"],
                        gate_neighbours=[1, 3, 5]), X, Y, folds)
    print("  mixture resolved over time (the most probable chain of the experts' poses)")
    train_ids = sequence_starts_to_ids(TRAIN_STARTS, len(X))
    tracked, continuity = choose_tracked(grid(n_experts=[8, 16, 32], overlap=[0.2, 0.5]),
                                         [1.0, 2.0, 3.0, 5.0], [1, 3, 5], X, Y, folds, train_ids)
    stacked = {k: stack_frames(X, k, sequence_starts=TRAIN_STARTS) for k in (2, 3, 4)}
    print("  stacking depth")
    depth = min(stacked, key=lambda k: cross_validate(
        lambda: RVMRegressor("gaussian", output_scale="common", **krvm), stacked[k], Y, folds)[0])
    print(f"    k = {depth}")

    methods = {
        "mean_pose": (MeanPose(), 1), "knn": (NearestNeighbours(3), 1),
        "linear_dls": (DLSRegressor("linear", **lin), 1),
        "linear_rvm": (RVMRegressor("linear", output_scale="common", **lrvm), 1),
        "kernel_dls": (DLSRegressor("gaussian", **kdls), 1),
        "kernel_rvm": (RVMRegressor("gaussian", output_scale="common", **krvm), 1),
        "kernel_rvm_stacked": (RVMRegressor("gaussian", output_scale="common", **krvm), depth),
        "mixture_rvm": (MixtureRVM(expert="rvm", rvm_rows=len(X), **mix), 1),
        # The mixture with the stacked input at the depth chosen above (the tracker's regressor
        # sees stacked descriptors too), its experts and gate as chosen for one frame.
        "mixture_rvm_stacked": (MixtureRVM(expert="rvm", rvm_rows=len(X), **mix), depth),
        # The same, averaged over BAGS seeds (BaggedMixture).
        "mixture_rvm_bagged": (BaggedMixture(BAGS, **mix), depth),
        # Not per frame: the whole test sequence decoded at once, as a smoother works.
        "mixture_rvm_tracked": (TrackedMixture(MixtureRVM(expert="rvm", rvm_rows=len(X),
                                                          gate="neighbours", **tracked),
                                               continuity, train_ids), 1),
    }
    report = {"n_train": int(len(X)), "ground_truth_jitter": point_jitter(Y_test),
              "descriptor_transform": tname, "stack_depth": depth,
              "hyperparameters": {"linear_dls": lin, "linear_rvm": lrvm, "kernel_dls": kdls, "kernel_rvm": krvm,
                                  "mixture_rvm": mix,
                                  "mixture_rvm_tracked": dict(tracked, continuity=continuity)},
              "methods": {}}
    # Beside each error: the mean training pose's error and skill = 1 - error / that, and the
    # correlation of the 8 most-moving coordinates (a flat output scores 0 there).
    const_error = mean_point_error(np.tile(Y.mean(0), (len(Y_test), 1)), Y_test)
    top = np.argsort(Y_test.std(axis=0))[::-1][:DEFAULT_TOP_ANGLES]
    report["constant_error"] = const_error
    print(f"\n{'method':20s} {'error':>7s} {'skill':>7s} {'corr8':>7s} {'jitter':>7s} "
          f"{'n_basis':>8s} {'fit s':>7s}")
    for name, (model, k) in methods.items():
        A, B = stack_frames(X, k, sequence_starts=TRAIN_STARTS), stack_frames(X_test, k)
        start = time.perf_counter()
        model.fit(A, Y)
        seconds = time.perf_counter() - start
        P = model.predict(B)
        error = mean_point_error(P, Y_test)
        row = {"error": error, "skill": skill(error, const_error),
               "corr8": float(correlation(P[:, top], Y_test[:, top]).mean()),
               "jitter": point_jitter(P), "n_basis": int(model.n_basis_), "fit_seconds": seconds}
        report["methods"][name] = row
        print(f"{name:20s} {row['error']:7.3f} {row['skill']:7.3f} {row['corr8']:7.3f} "
              f"{row['jitter']:7.3f} {row['n_basis']:8d} {seconds:7.2f}")
    print(f"{'ground truth':20s} {'':23s} {report['ground_truth_jitter']:7.3f}")
    return report


main = stops_in_one_line("reproduce_paper", _main)       # Ctrl-C: one line, no traceback


if __name__ == "__main__":
    sys.exit(main())
