"""Reproduce the paper's regressors on its released data (train split only; test = spiral walk).

    python scripts/reproduce_paper.py --data ../shared/data/ankur/ankurDataPoseSilhouette.mat --json out.json
    python scripts/reproduce_paper.py --data ... --methods kernel_rvm,mixture_sparse_rvm

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

``mixture_sparse_rvm`` is one mixture whose experts are sparse RVMs fitted on all their rows by
fast sparse Bayesian learning over candidate kernels (regressor.sparse_rvm), each frame's pose
the softmax gate's weighting of theirs; among its settings the most accurate is chosen whose
held-out predictions jitter no more than the kernel RVM's. --methods runs only the methods
named, choosing only the hyperparameters they need.

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
from functools import cached_property

import numpy as np

from regressor.dls import DLSRegressor
from regressor.errors import SilhouettePoseError
from regressor.hypothesis_path import HypothesisPathError, continues
from regressor.mixture import MixtureRegressor
from regressor.metrics import contiguous_folds, cross_validate, mean_point_error, point_jitter
from regressor.rvm import RVMRegressor
from regressor.stacking import sequence_starts_to_ids, stack_frames
from sequences.measures import DEFAULT_TOP_ANGLES, correlation, skill
from lab.evaluation import EvaluationError, load_ankur, mixture_path
from tracker.one_line_parser import OneLineParser, stops_in_one_line
from tracker.outputs.files import OutputWriteError
from tracker.outputs.whole_files import write_whole

TRAIN_STARTS = [0, 100, 336, 405, 471, 1530, 1768]   # the 7 training sequences (README)
RV_BUDGET = 0.10                                     # kernel RVM: keep <= 10% of training frames
FEATURE_BUDGET = 0.30                                # linear RVM: keep <= 30 of the 100 features
SPARSE_CANDIDATES = 200                              # candidate kernels per sparse RVM expert


class MeanPose:
    """Predicts the mean training pose (the trivial baseline)."""
    n_basis_ = 0

    def fit(self, X, Y):
        self.mean_ = Y.mean(0)
        return self

    def predict(self, X):
        return np.tile(self.mean_, (len(X), 1))


def step_variance(Y, sequence_ids=None) -> float:
    """s^2 > 0, the mean squared change between consecutive rows of Y (N, K) (poses in time
    order, in the hypotheses' units) with the same sequence_ids (N,) label (default: one)."""
    Y = np.asarray(Y, dtype=np.float64)
    if Y.ndim != 2 or len(Y) < 2:
        raise HypothesisPathError(f"Y must be (N, K) with N >= 2, got shape {Y.shape}")
    if not np.isfinite(Y).all():
        raise HypothesisPathError("Y has non-finite values")
    same = np.ones(len(Y) - 1, bool) if sequence_ids is None else continues(sequence_ids, len(Y))
    if not same.any():
        raise HypothesisPathError("no two consecutive rows belong to one sequence")
    s2 = float((np.diff(Y, axis=0)[same] ** 2).sum(axis=1).mean())
    if not s2 > 0:
        raise HypothesisPathError("the poses never change: the step variance is 0")
    return s2


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
    whole test sequence (lab.evaluation.mixture_path), not each frame's favourite alone. The
    step variance is the training sequences' own (sequence_ids: (N,) label per training row)."""

    def __init__(self, mixture: MixtureRegressor, continuity: float, sequence_ids):
        self.mixture, self.continuity, self.sequence_ids = mixture, continuity, sequence_ids

    def fit(self, X, Y):
        self.mixture.fit(X, Y)
        self.step_var_ = step_variance(Y, self.sequence_ids)
        self.n_basis_ = self.mixture.n_basis_
        if hasattr(self.mixture, "relevance_per_expert"):
            self.relevance_per_expert = self.mixture.relevance_per_expert
        return self

    def predict(self, X):
        """X: one test sequence, in time order."""
        return mixture_path(self.mixture, X, self.step_var_, self.continuity)


class SparseMixture(MixtureRegressor):
    """The mixture of sparse RVM experts (regressor.sparse_rvm): each expert fitted by fast
    sparse Bayesian learning on all the rows of its region, over n_centres candidate kernels;
    the softmax gate; each frame's pose the gate's weighting of the experts' poses
    (combine="mean"). Its count of basis functions: the experts' relevance vectors plus the
    gate's kernel centres (or, for the neighbour gate, the rows or prototypes it keeps)."""

    @property
    def n_basis_(self) -> int:
        gate = getattr(self.gate_, "centres_", getattr(self.gate_, "X_", ()))  # softmax / neighbours
        return int(sum(self.relevance_per_expert())) + len(gate)

    def relevance_per_expert(self) -> list[int]:
        return [int(e.n_basis_) for e in self.experts_]


def sparse_mixture(**params) -> SparseMixture:
    """SparseMixture with its usual parts (sparse RVM experts, softmax gate, the gate's mean)."""
    return SparseMixture(**{"expert": "sparse_rvm", "gate": "softmax", "combine": "mean", **params})


def run_labels(rows: np.ndarray, sequence_ids: np.ndarray) -> np.ndarray:
    """A label per row of rows (sorted indices) that changes wherever two neighbours are not
    consecutive frames of one sequence (a held-out block cut out, or a new sequence)."""
    rows = np.asarray(rows)
    if len(rows) == 0:
        return np.zeros(0, dtype=np.int64)
    breaks = (np.diff(rows) != 1) | (np.diff(sequence_ids[rows]) != 0)
    return np.concatenate([[0], np.cumsum(breaks)])


def choose_tracked(mixtures, continuities, neighbours, X, Y, folds, sequence_ids, log=print,
                   make=None):
    """(mixture parameters, continuity, CV error) of the mixture whose most probable chain of poses has
    the lowest CV error; every held-out block is decoded as the pieces of sequences it holds.
    The experts are fitted once per fold and mixture setting; a neighbour gate's count
    (neighbours; [None] for a softmax gate) only re-reads the stored rows. make(**params): the
    mixture (default: MixtureRVM's RVM experts, neighbour gate)."""
    make = make or (lambda **p: MixtureRVM(expert="rvm", rvm_rows=len(X), gate="neighbours", **p))
    results = []
    for params in mixtures:
        fits = []
        for hold in folds:
            train = np.setdiff1d(np.arange(len(X)), hold)
            model = make(**params).fit(X[train], Y[train])
            fits.append((model, step_variance(Y[train], run_labels(train, sequence_ids)), hold))
        for k, c in itertools.product(neighbours, continuities):
            setting = params if k is None else dict(params, gate_neighbours=k)
            total = 0.0
            for model, step_var, hold in fits:
                if k is not None:     # the gate keeps every training row: another k re-reads them
                    model.set_params(gate_neighbours=k)
                    model.gate_.n_neighbours = k
                P = mixture_path(model, X[hold], step_var, c,
                                 sequence_ids=run_labels(hold, sequence_ids))
                total += mean_point_error(P, Y[hold]) * len(hold)
            err = total / len(X)
            log(f"    {setting}, continuity {c}: cv error {err:.3f}")
            results.append((err, setting, c))
    err, params, c = min(results, key=lambda r: r[0])
    log(f"    chosen: {params}, continuity {c} (cv error {err:.3f})")
    return params, c, err


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


def cv_error_and_jitter(make, X, Y, folds) -> tuple[float, float]:
    """Cross-validated error and jitter (point_jitter of each held-out block's predictions, in
    time order), both averaged over the held-out frames."""
    err, models = cross_validate(make, X, Y, folds)
    jitter = sum(point_jitter(m.predict(X[hold])) * len(hold) for m, hold in zip(models, folds))
    return err, jitter / sum(len(hold) for hold in folds)


def choose_smooth(make, grid, X, Y, folds, max_jitter, log=print):
    """The grid point (dict) with the lowest CV error among those whose held-out predictions
    jitter no more than max_jitter (else the least jittery)."""
    results = []
    for params in grid:
        err, jitter = cv_error_and_jitter(lambda: make(**params), X, Y, folds)
        log(f"    {params}: cv error {err:.3f}, jitter {jitter:.3f}")
        results.append((err, jitter, params))
    ok = [r for r in results if r[1] <= max_jitter] or [min(results, key=lambda r: r[1])]
    return min(ok, key=lambda r: r[0])[2]


def grid(**axes):
    return [dict(zip(axes, v)) for v in itertools.product(*axes.values())]


class _Choices:
    """Each method's hyperparameters, chosen by cross-validation on the training rows X (N, D),
    Y (N, K) over folds the first time a method needs them (train_ids: the training sequence
    of each row)."""

    def __init__(self, X, Y, folds, train_ids):
        self.X, self.Y, self.folds, self.train_ids = X, Y, folds, train_ids

    def report(self) -> dict:
        """The choices made so far, by name."""
        return {name: getattr(self, name) for name in
                ("lin", "lrvm", "kdls", "krvm", "mix", "tracked", "stack_depth", "sparse_mix",
                 "sparse_tracked")
                if name in self.__dict__}

    @cached_property
    def lin(self):
        print("  linear DLS")
        return choose(lambda **p: DLSRegressor("linear", **p),
                      grid(lam=[1e-3, 1e-2, 1e-1, 1.0]), self.X, self.Y, self.folds)

    @cached_property
    def lrvm(self):
        print("  linear RVM")
        return choose(lambda **p: RVMRegressor("linear", output_scale="common", **p),
                      grid(min_gain=[300.0, 1000.0, 3000.0]), self.X, self.Y, self.folds,
                      budget=FEATURE_BUDGET, features=True)

    @cached_property
    def kdls(self):
        print("  kernel DLS")
        return choose(lambda **p: DLSRegressor("gaussian", **p),
                      grid(width_scale=[0.25, 0.5, 1.0], lam=[1e-3, 1e-2]), self.X, self.Y, self.folds)

    @cached_property
    def krvm(self):
        width = self.kdls["width_scale"]
        print("  kernel RVM")
        params = choose(lambda **p: RVMRegressor("gaussian", output_scale="common", **p),
                        grid(width_scale=[width], noise=[0.03, 0.05, 0.1],
                             min_gain=[200.0, 400.0, 800.0]), self.X, self.Y, self.folds,
                        budget=RV_BUDGET)
        MixtureRVM.rvm_params = params        # the mixtures' experts take these settings
        return params

    @cached_property
    def mix(self):
        self.krvm
        print("  mixture of RVM experts")
        # Two gates (regressor.mixture): the softmax gate the tracker's models use, and the
        # regions of the nearest training descriptors, which suits this small set.
        return choose(lambda **p: MixtureRVM(expert="rvm", rvm_rows=len(self.X), **p),
                      grid(n_experts=[2, 4, 8], overlap=[0.2], gate=["softmax"])
                      + grid(n_experts=[4, 8, 16], overlap=[0.2, 0.5], gate=["neighbours"],
                             gate_neighbours=[1, 3, 5]), self.X, self.Y, self.folds)

    @cached_property
    def tracked(self):
        self.krvm
        print("  mixture resolved over time (the most probable chain of the experts' poses)")
        params, continuity, _ = choose_tracked(grid(n_experts=[8, 16, 32], overlap=[0.2, 0.5]),
                                            [1.0, 2.0, 3.0, 5.0], [1, 3, 5], self.X, self.Y,
                                            self.folds, self.train_ids)
        return dict(params, continuity=continuity)

    @cached_property
    def stack_depth(self):
        krvm = self.krvm
        print("  stacking depth")
        stacked = {k: stack_frames(self.X, k, sequence_starts=TRAIN_STARTS) for k in (2, 3, 4)}
        depth = min(stacked, key=lambda k: cross_validate(
            lambda: RVMRegressor("gaussian", output_scale="common", **krvm), stacked[k], self.Y,
            self.folds)[0])
        print(f"    k = {depth}")
        return depth

    @cached_property
    def sparse_mix(self):
        """Experts with the kernel RVM's width and noise; the number of experts, the regions'
        overlap and the gate's damping the most accurate whose held-out predictions jitter no
        more than the kernel RVM's."""
        krvm = self.krvm
        _, bound = cv_error_and_jitter(
            lambda: RVMRegressor("gaussian", output_scale="common", **krvm), self.X, self.Y, self.folds)
        print(f"  mixture of sparse RVM experts (held-out jitter at most the kernel RVM's, {bound:.3f})")
        experts = self.sparse_experts
        params = choose_smooth(lambda **p: sparse_mixture(**experts, **p),
                               grid(n_experts=[4, 8], overlap=[0.5], gate_l2=[1e-3, 3e-3, 1e-2]),
                               self.X, self.Y, self.folds, bound)
        return dict(experts, **params)

    @cached_property
    def sparse_experts(self) -> dict:
        """The sparse RVM experts' settings: the kernel RVM's width and noise."""
        return dict(width_scale=self.krvm["width_scale"], n_centres=SPARSE_CANDIDATES,
                    expert_params={"noise": self.krvm["noise"], "output_scale": "common"})

    @cached_property
    def sparse_tracked(self):
        """As the RVM mixture's (tracked), with the sparse RVM experts and a gate whose model
        keeps fewer basis functions than training rows: the neighbour gate over k-means
        prototypes of the inputs, or the softmax gate, chosen by the same cross-validation."""
        experts = self.sparse_experts
        print("  mixture of sparse RVM experts resolved over time")
        found = [choose_tracked(grid(n_experts=[8, 16], overlap=[0.5], gate_prototypes=[200, 400]),
                                [1.0, 2.0, 3.0], [1, 3, 5], self.X, self.Y, self.folds,
                                self.train_ids, make=lambda **p: sparse_mixture(
                                    gate="neighbours", **experts, **p)),
                 choose_tracked(grid(n_experts=[8, 16], overlap=[0.5], gate_l2=[1e-4, 1e-3]),
                                [1.0, 2.0, 3.0], [None], self.X, self.Y, self.folds,
                                self.train_ids, make=lambda **p: sparse_mixture(**experts, **p))]
        (params, continuity, _), gate = min(zip(found, ["neighbours", "softmax"]),
                                            key=lambda f: f[0][2])
        return dict(experts, gate=gate, **params, continuity=continuity)

#: Each method's (model, stacking depth), from the choices (hyperparameters chosen on demand).
METHODS = {
    "mean_pose": lambda c: (MeanPose(), 1),
    "knn": lambda c: (NearestNeighbours(3), 1),
    "linear_dls": lambda c: (DLSRegressor("linear", **c.lin), 1),
    "linear_rvm": lambda c: (RVMRegressor("linear", output_scale="common", **c.lrvm), 1),
    "kernel_dls": lambda c: (DLSRegressor("gaussian", **c.kdls), 1),
    "kernel_rvm": lambda c: (RVMRegressor("gaussian", output_scale="common", **c.krvm), 1),
    "kernel_rvm_stacked": lambda c: (RVMRegressor("gaussian", output_scale="common", **c.krvm),
                                     c.stack_depth),
    "mixture_rvm": lambda c: (MixtureRVM(expert="rvm", rvm_rows=len(c.X), **c.mix), 1),
    # The mixture with the stacked input at the depth chosen above (the tracker's regressor
    # sees stacked descriptors too), its experts and gate as chosen for one frame.
    "mixture_rvm_stacked": lambda c: (MixtureRVM(expert="rvm", rvm_rows=len(c.X), **c.mix),
                                      c.stack_depth),
    # The same, averaged over BAGS seeds (BaggedMixture).
    "mixture_rvm_bagged": lambda c: (BaggedMixture(BAGS, **c.mix), c.stack_depth),
    # Not per frame: the whole test sequence decoded at once, as a smoother works.
    "mixture_rvm_tracked": lambda c: (TrackedMixture(
        MixtureRVM(expert="rvm", rvm_rows=len(c.X), gate="neighbours",
                   **{k: v for k, v in c.tracked.items() if k != "continuity"}),
        c.tracked["continuity"], c.train_ids), 1),
    # Sparse RVM experts on all their rows (SparseMixture), one frame and stacked.
    "mixture_sparse_rvm": lambda c: (sparse_mixture(**c.sparse_mix), 1),
    "mixture_sparse_rvm_stacked": lambda c: (sparse_mixture(**c.sparse_mix), c.stack_depth),
    "mixture_sparse_rvm_tracked": lambda c: (TrackedMixture(
        sparse_mixture(**{k: v for k, v in c.sparse_tracked.items() if k != "continuity"}),
        c.sparse_tracked["continuity"], c.train_ids), 1),
}


def _main(argv) -> int:
    ap = OneLineParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", required=True, help="ankurDataPoseSilhouette.mat")
    ap.add_argument("--json", help="write the results here")
    ap.add_argument("--methods", help="comma-separated methods to run (default: all of "
                    + ", ".join(METHODS) + ")")
    args = ap.parse_args(argv)
    names = None if args.methods is None else [n.strip() for n in args.methods.split(",")]
    unknown = [n for n in names or () if n not in METHODS]
    if names is not None and (unknown or not names):
        ap.error(f"--methods: unknown method {', '.join(unknown) or repr(args.methods)}; "
                 f"choose from {', '.join(METHODS)}")
    # Before the minutes of work: by the file, so a hard link to --data is refused too.
    ap.check_outputs([("--json", args.json)], [("--data", args.data)])
    try:
        d = load_ankur(args.data)
    except EvaluationError as exc:
        ap.error(f"--data {exc}")
    try:
        report = _reproduce(d, names)
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


def _reproduce(d: dict, names=None) -> dict:
    """The whole run on the paper's data d (load_ankur), or only the methods named (METHODS):
    the table on stdout, the report as a JSON-ready dict. A method's hyperparameters are chosen
    when it (or a method built on it) is first needed."""
    Xraw, Y, Xraw_test, Y_test = d["Y"], d["Z"], d["Y_test"], d["Z_test"]
    folds = contiguous_folds(len(Xraw), 5)

    print("choosing hyperparameters on the training set (5 contiguous blocks)")
    transforms = {"none": lambda A: A, "sqrt": np.sqrt}
    tname = min(transforms, key=lambda t: cross_validate(
        lambda: DLSRegressor("gaussian", lam=1e-2, width_scale=0.5), transforms[t](Xraw), Y, folds)[0])
    X, X_test = transforms[tname](Xraw), transforms[tname](Xraw_test)
    print(f"  descriptor transform: {tname}")
    train_ids = sequence_starts_to_ids(TRAIN_STARTS, len(X))
    chosen = _Choices(X, Y, folds, train_ids)
    names = list(METHODS) if names is None else list(names)
    methods = {name: METHODS[name](chosen) for name in names}
    report = {"n_train": int(len(X)), "ground_truth_jitter": point_jitter(Y_test),
              "descriptor_transform": tname, "hyperparameters": chosen.report(), "methods": {}}
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
        if hasattr(model, "relevance_per_expert"):
            row["relevance_per_expert"] = model.relevance_per_expert()
        report["methods"][name] = row
        print(f"{name:20s} {row['error']:7.3f} {row['skill']:7.3f} {row['corr8']:7.3f} "
              f"{row['jitter']:7.3f} {row['n_basis']:8d} {seconds:7.2f}")
    print(f"{'ground truth':20s} {'':23s} {report['ground_truth_jitter']:7.3f}")
    for name, row in report["methods"].items():
        if "relevance_per_expert" in row:
            print(f"{name}: relevance vectors per expert {row['relevance_per_expert']}")
    if "stack_depth" in report["hyperparameters"]:
        report["stack_depth"] = report["hyperparameters"]["stack_depth"]
    return report


main = stops_in_one_line("reproduce_paper", _main)       # Ctrl-C: one line, no traceback


if __name__ == "__main__":
    sys.exit(main())
