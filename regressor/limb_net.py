"""The limbs by an ensemble of small neural networks on the regressor's input (issue 9).

The mixture's limb head (:class:`regressor.pose_model.LimbHead`) regresses each silhouette's
canonical body (the member of {pose, front/back flip} facing the camera's half,
sequences.pose_vector.canonical_member) by kernel ridge on 400 centres per expert: each expert
sees its own region and smooths within it. A multi-layer perceptron on the same input and
targets shares its features over all the training rows. Seeded networks differ a lot from
one another (the validation videos' correlation of the 8 most-moving angles at the true
heading moved by up to 0.17 between two seeds), so several are averaged.

How the recipe (eight (512, 256) networks, mirror images in training, int8 weights) was
chosen, and what was tried and not adopted: docs/tuning.md, "regressor/limb_net.py".

A :class:`LimbNet` is plain arrays (no pickle): ReLU hidden layers, a linear output, inputs
standardised by a mean and one scale, outputs by a mean and a scale per value. The networks
give either the pose vector's 55 values, the 53 body angles as wrapped offsets (degrees) from
``angle_centre_deg`` as the experts' (older files), or ROT6D_OUTPUTS values: the
heading's (cos, sin), the root's two tilts as such offsets, and each joint's rotation as 6
numbers (regressor.rotation6d, a continuous representation); the output width says which.
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from typing import Callable

import numpy as np
from threadpoolctl import threadpool_limits

from .angles import POSE_DIM, regression_targets, wrap_deg
from .relu_layers import (as_float32_layers, check_parts, dequantised_int8, forward,
                          forward_mean, quantised_int8, stacked_members, standardised,
                          typical_inputs)
from .rotation6d import ROT6D_LENGTH, angles_to_rot6d, rot6d_to_angles

PREFIX = "limb_net_"        # the file parts' names
MAX_MEMBERS, MAX_LAYERS = 16, 8
#: The networks' outputs with 6-D rotations: (cos, sin), the root's two tilts, 6 per joint.
ROT6D_OUTPUTS = 2 + ROT6D_LENGTH
#: fit_limb_net's target representations -> the networks' output width.
OUTPUT_WIDTHS = {"euler": POSE_DIM, "rot6d": ROT6D_OUTPUTS}


@dataclass
class LimbNet:
    """An ensemble of networks with shared standardisation. members: per network, its layers
    [(W (n_in, n_out), b (n_out,)), ...], the last linear, the others ReLU; the ensemble's
    output is the members' mean. input_mean (P,), input_scale (scalar) standardise the
    regressor's input X (N, P); output_mean, output_scale (O,) undo the targets'
    standardisation, O = 55 (Euler angles) or ROT6D_OUTPUTS (6-D rotations; module
    docstring); angle_centre_deg (53,); canonical_direction (55,): the rule the targets'
    members were chosen by (sequences.pose_vector.canonical_member)."""

    members: list[list[tuple[np.ndarray, np.ndarray]]]
    input_mean: np.ndarray
    input_scale: float
    output_mean: np.ndarray
    output_scale: np.ndarray
    angle_centre_deg: np.ndarray
    canonical_direction: np.ndarray

    def __post_init__(self):
        self.members = [as_float32_layers(layers, "limb network") for layers in self.members]
        self.input_mean = np.asarray(self.input_mean, dtype=np.float64)
        self.input_scale = float(self.input_scale)
        self.output_mean = np.asarray(self.output_mean, dtype=np.float64)
        self.output_scale = np.asarray(self.output_scale, dtype=np.float64)
        self.angle_centre_deg = np.asarray(self.angle_centre_deg, dtype=np.float64)
        self.canonical_direction = np.asarray(self.canonical_direction, dtype=np.float64)
        self._stacked = None
        problem = self._problem()
        if problem:
            raise ValueError(f"invalid limb network: {problem}")
        # checked: the members as one batched stack for predict on one row (a copy of the
        # weights, 7.9 MB for the default's eight; members are not changed after this)
        self._stacked = stacked_members(self.members)

    def _problem(self) -> str | None:
        """The first inconsistency of the parts, or None."""
        if not self.members or not all(self.members):
            return "no members or a member without layers"
        if len(self.members) > MAX_MEMBERS \
                or any(len(layers) != len(self.members[0]) for layers in self.members) \
                or len(self.members[0]) > MAX_LAYERS:
            return (f"members must be 1..{MAX_MEMBERS} networks of the same 1..{MAX_LAYERS} "
                    f"layers")
        if self.input_mean.ndim != 1 or len(self.input_mean) < 1:
            return f"input mean has shape {self.input_mean.shape}"
        for m, layers in enumerate(self.members):
            n_in = len(self.input_mean)
            for i, (W, b) in enumerate(layers):
                if W.ndim != 2 or W.shape[0] != n_in or b.shape != (W.shape[1],):
                    return (f"member {m} layer {i} has shape {W.shape} / {b.shape} after "
                            f"{n_in} values")
                n_in = W.shape[1]
            if n_in not in OUTPUT_WIDTHS.values() or n_in != self.output_width:
                return (f"member {m} gives {n_in} values, not "
                        f"{' or '.join(map(str, sorted(OUTPUT_WIDTHS.values())))}"
                        + ("" if m == 0 else " as member 0"))
        width = self.output_width
        if self.output_mean.shape != (width,) or self.output_scale.shape != (width,) \
                or self.angle_centre_deg.shape != (POSE_DIM - 2,) \
                or self.canonical_direction.shape != (POSE_DIM,):
            return (f"output parts do not have {width} values (53 centres, a direction of "
                    f"{POSE_DIM})")
        arrays = [self.input_mean, self.output_mean, self.output_scale, self.angle_centre_deg,
                  self.canonical_direction,
                  *(a for layers in self.members for layer in layers for a in layer)]
        if not all(np.isfinite(a).all() for a in arrays) or not np.isfinite(self.input_scale):
            return "non-finite values"
        if not (self.input_scale > 0 and np.all(self.output_scale > 0)):
            return "scales must be positive"
        if np.any(np.abs(self.angle_centre_deg) > 180.0) \
                or not abs(np.linalg.norm(self.canonical_direction) - 1) < 1e-6:
            return "centres must be angles in [-180, 180] and the direction a unit vector"
        # absurd but finite parts (a tiny scale, a huge mean) overflow on typical inputs
        with np.errstate(all="ignore"):
            if not np.isfinite(self.predict(typical_inputs(self.input_mean))).all():
                return "it gives non-finite poses"
        return None

    @property
    def output_width(self) -> int:
        """The networks' output width: 55 (Euler angles) or ROT6D_OUTPUTS (6-D rotations;
        a network of another width is refused on load)."""
        return int(self.members[0][-1][0].shape[1])

    @property
    def input_length(self) -> int:
        """P, the length of the regressor's input the network takes."""
        return len(self.input_mean)

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Canonical poses (N, 55) from the regressor's inputs X (N, P): (cos, sin) of the
        heading, then the 53 body angles in degrees wrapped to (-180, 180]."""
        x = standardised(X, self.input_mean, self.input_scale)
        # batched for the tracker's one row per person; for many rows (offline evaluation,
        # training) one by one is faster and holds less (the first layers of all members
        # at once would be N x 4096 values)
        if self._stacked is not None and len(x) == 1:
            mean = forward_mean(x, self._stacked)
        else:
            mean = np.mean([forward(x, layers) for layers in self.members], axis=0,
                           dtype=np.float64)
        out = mean * self.output_scale + self.output_mean
        if out.shape[1] == ROT6D_OUTPUTS:
            # the members' mean 6-D values made rotations (Gram-Schmidt); the root's tilts
            # are offsets from their centres, as every angle is in the Euler case
            angles = rot6d_to_angles(out[:, 2:])
            angles[:, :2] += self.angle_centre_deg[:2]
            return np.hstack([out[:, :2], wrap_deg(angles)])
        out[:, 2:] = wrap_deg(out[:, 2:] + self.angle_centre_deg)
        return out

    def to_arrays(self, prefix: str = PREFIX) -> dict:
        """The file parts, keyed by ``prefix``; each weight matrix as int8 with a float32
        scale per output column (``S{m}_{i}``; relu_layers.quantised_int8), half of float16's
        space. Measured on the 4,509 validation rows with the four networks of 2026-12-02:
        the poses move by 0.13 deg mean, 0.8 deg at the 99th percentile (float16: hundredths
        of a degree), and the correlation of the 8 most-moving angles is unchanged (0.6471
        -> 0.6475); training reports the largest change on the validation rows as
        limb_net_int8_max_deg (lab.training.train_mixture_model). Files written
        before that hold float16 weights and no scales; from_arrays reads both."""
        out = {f"{prefix}shape": np.array([len(self.members), len(self.members[0])], np.int64),
               f"{prefix}input_mean": self.input_mean,
               f"{prefix}input_scale": np.float64(self.input_scale),
               f"{prefix}output_mean": self.output_mean,
               f"{prefix}output_scale": self.output_scale,
               f"{prefix}angle_centre_deg": self.angle_centre_deg,
               f"{prefix}canonical_direction": self.canonical_direction}
        for m, layers in enumerate(self.members):
            for i, (W, b) in enumerate(layers):
                out[f"{prefix}W{m}_{i}"], out[f"{prefix}S{m}_{i}"] = quantised_int8(W)
                out[f"{prefix}b{m}_{i}"] = b.astype(np.float32)
        return out

    @classmethod
    def from_arrays(cls, a, prefix: str = PREFIX) -> "LimbNet | None":
        """The network in a file's parts a (mapping), None when it has none; ValueError when
        it is incomplete or inconsistent."""
        if f"{prefix}shape" not in a:
            if any(str(k).startswith(prefix) for k in a.keys()):
                raise ValueError("limb network is incomplete")
            return None
        shape = np.asarray(a[f"{prefix}shape"])
        if shape.shape != (2,) or not np.issubdtype(shape.dtype, np.integer) \
                or not (1 <= shape[0] <= MAX_MEMBERS and 1 <= shape[1] <= MAX_LAYERS):
            raise ValueError(f"limb network shape must be two integers (members "
                             f"1..{MAX_MEMBERS}, layers 1..{MAX_LAYERS})")
        names = [f"{prefix}{s}" for s in ("input_mean", "input_scale", "output_mean",
                                          "output_scale", "angle_centre_deg",
                                          "canonical_direction")]
        layers = [[(f"{prefix}W{m}_{i}", f"{prefix}b{m}_{i}", f"{prefix}S{m}_{i}")
                   for i in range(int(shape[1]))] for m in range(int(shape[0]))]
        # int8 weights with per-column scales (to_arrays), or float16 ones (older files): a
        # file with any int8 weight or any scale part is the former, and then needs them all
        quantised = (f"{prefix}W0_0" in a and np.asarray(a[f"{prefix}W0_0"]).dtype == np.int8) \
            or any(str(k).startswith(f"{prefix}S") for k in a.keys())
        weights = [k for member in layers for k, _, _ in member]
        needed = names + [k for member in layers for W, b, S in member
                          for k in ((W, b, S) if quantised else (W, b))]
        scale = check_parts(a, needed, prefix, f"{prefix}shape", "limb network",
                            "shape does not declare",
                            int8_parts=tuple(weights) if quantised else ())

        def weight(W: str, S: str) -> np.ndarray:
            return (dequantised_int8(a[W], a[S], f"limb network part {W}") if quantised
                    else a[W])

        return cls([[(weight(W, S), a[b]) for W, b, S in member] for member in layers],
                   a[names[0]], scale, a[names[2]], a[names[3]], a[names[4]], a[names[5]])


def fit_limb_net(X: np.ndarray, targets: np.ndarray, angle_centre_deg: np.ndarray,
                 canonical_direction: np.ndarray, members: int = 3,
                 hidden: tuple[int, ...] = (512, 256), alpha: float = 1e-3,
                 max_iter: int = 200, seed: int = 0, workers: int = 1,
                 input_noise: float = 0.0, output: str = "euler",
                 log: Callable[[str], None] = lambda message: None) -> LimbNet:
    """Fit a :class:`LimbNet` of ``members`` networks (seeds seed, seed + 1, ...) on inputs
    X (N, P) and canonical poses targets (N, 55) (cos, sin, then 53 angles in degrees) with
    scikit-learn's MLPRegressor (Adam, minibatches of 256, L2 alpha, 10 % of the rows held
    out for early stopping after 10 epochs without gain: drawn at random, so their
    neighbours in time and their mirror twins are fitted and the held-out R^2 is optimistic;
    it stops near epoch 60, and fitted on every row the validation trials' corr8 is flat from
    epoch 12 to 36, so stopping later costs nothing; seeded, so a refit on the same
    machine gives the same arrays). workers: members fitted at once, each in its own process
    on one thread (the networks are small: two one-thread fits finish in about the time one
    two-thread fit takes); each member is fitted on one thread whatever ``workers`` is, so
    the arrays do not depend on it (so workers=1 fits on one thread too, slower than before
    on a machine with many cores). input_noise: each epoch, every training input gets fresh
    Gaussian noise of this fraction of its column's spread (0: none; the held-out tenth is
    scored clean); a new silhouette's input is off its nearest training rows by far more than
    the rows' own spacing, and noise teaches the networks to be smooth across that gap.
    output: "euler" (the 53 angles as wrapped offsets from angle_centre_deg) or "rot6d" (each
    joint's rotation as 6 numbers, the root's tilts as offsets; the module docstring).
    Needs scikit-learn and joblib (training only)."""
    if not 1 <= members <= MAX_MEMBERS or not 1 <= len(hidden) + 1 <= MAX_LAYERS:
        raise ValueError(f"a limb network has 1..{MAX_MEMBERS} members and 0..{MAX_LAYERS - 1} "
                         f"hidden layers, got {members} and {len(hidden)}")
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if not 0.0 <= input_noise <= 2.0:
        raise ValueError(f"input_noise must be in 0..2 (a fraction of each input's spread), "
                         f"got {input_noise}")
    if output not in OUTPUT_WIDTHS:
        raise ValueError(f"output must be one of {sorted(OUTPUT_WIDTHS)}, got {output!r}")
    require_training_dependencies()                     # the install hint before any work
    X = np.asarray(X, dtype=np.float64)
    centre = np.asarray(angle_centre_deg, dtype=np.float64)
    Y = regression_targets(targets, centre)
    if output == "rot6d":
        Y = np.hstack([Y[:, :4], angles_to_rot6d(np.asarray(targets, float)[:, 2:])[:, 2:]])
        # Joints that never turn give columns that are constant but for rounding (1e-17 in
        # the mirror images' matrices): standardised, that rounding would dominate the
        # held-out R^2 that stops the fit early (-2e12 in a first run). Hold them exactly.
        flat = Y.std(axis=0) < 1e-9
        Y[:, flat] = Y[:, flat].mean(axis=0)
    x_mean, x_scale = X.mean(axis=0), float(X.std(axis=0).mean())
    y_mean, y_scale = Y.mean(axis=0), Y.std(axis=0) + 1e-6
    Xz, Yz = (X - x_mean) / x_scale, (Y - y_mean) / y_scale
    seeds = [seed + m for m in range(members)]
    if workers == 1 or members == 1:
        results = (_fit_member(Xz, Yz, tuple(hidden), alpha, max_iter, s, input_noise)
                   for s in seeds)
    else:
        from joblib import Parallel, delayed
        # a generator, in seed order: each member is logged as soon as it and those before
        # it are done (a fit takes minutes)
        results = Parallel(n_jobs=min(workers, members), return_as="generator")(
            delayed(_fit_member)(Xz, Yz, tuple(hidden), alpha, max_iter, s, input_noise)
            for s in seeds)
    fitted = []
    for m, (layers, epochs, score, seconds) in enumerate(results):
        stopped = "max_iter reached" if epochs >= max_iter else "early stop"
        log(f"  limb network {m + 1}/{members}: {epochs} epochs ({stopped}), held-out "
            f"R^2 {score:.3f}, {seconds:.0f} s")
        fitted.append(layers)
    return LimbNet(fitted, x_mean, x_scale, y_mean, y_scale, centre, canonical_direction)


def _fit_member(Xz: np.ndarray, Yz: np.ndarray, hidden: tuple[int, ...], alpha: float,
                max_iter: int, seed: int, input_noise: float = 0.0
                ) -> tuple[list, int, float, float]:
    """One network on standardised inputs Xz (N, P) and targets Yz (N, O), on one thread:
    (its layers [(W, b), ...], epochs run, best held-out R^2, seconds)."""
    if input_noise > 0:
        return _fit_member_noisy(Xz, Yz, hidden, alpha, max_iter, seed, input_noise)
    _, ConvergenceWarning = _sklearn_classes()
    start = time.perf_counter()
    net = _network(hidden, alpha, seed, max_iter=max_iter, early_stopping=True)
    with warnings.catch_warnings(), threadpool_limits(1):
        warnings.simplefilter("ignore", ConvergenceWarning)  # max_iter reached is logged
        net.fit(Xz, Yz)
    return (list(zip(net.coefs_, net.intercepts_)), int(net.n_iter_),
            float(net.best_validation_score_), time.perf_counter() - start)


def _fit_member_noisy(Xz: np.ndarray, Yz: np.ndarray, hidden: tuple[int, ...], alpha: float,
                      max_iter: int, seed: int, input_noise: float
                      ) -> tuple[list, int, float, float]:
    """_fit_member with fresh input noise each epoch (fit_limb_net's input_noise):
    MLPRegressor.partial_fit epoch by epoch (the same Adam, minibatches and L2), with the
    early stopping MLPRegressor does itself: a tenth of the rows held out (clean), stop after
    its n_iter_no_change epochs without a gain of its tol in their R^2, keep the best epoch's
    layers."""
    start = time.perf_counter()
    rng = np.random.default_rng(seed)
    held = np.zeros(len(Xz), dtype=bool)
    held[rng.permutation(len(Xz))[:max(1, len(Xz) // 10)]] = True
    X_fit, Y_fit, X_held, Y_held = Xz[~held], Yz[~held], Xz[held], Yz[held]
    spread = input_noise * X_fit.std(axis=0)
    net = _network(hidden, alpha, seed)
    best, best_layers, stale, epoch = -np.inf, None, 0, 0
    with threadpool_limits(1):
        for epoch in range(1, max_iter + 1):
            net.partial_fit(X_fit + rng.standard_normal(X_fit.shape) * spread, Y_fit)
            score = float(net.score(X_held, Y_held))
            stale = 0 if score > best + net.tol else stale + 1
            if score > best:
                best = score
                best_layers = [(W.copy(), b.copy()) for W, b in zip(net.coefs_, net.intercepts_)]
            if stale >= net.n_iter_no_change:
                break
    return best_layers, epoch, best, time.perf_counter() - start


def _network(hidden: tuple[int, ...], alpha: float, seed: int, **options):
    """A member's MLPRegressor, as every fit makes it: Adam, minibatches of 256, learning rate
    1e-3, L2 alpha, early stopping after 10 epochs without gain (when it stops early)."""
    MLPRegressor, _ = _sklearn_classes()
    return MLPRegressor(hidden_layer_sizes=hidden, alpha=alpha, batch_size=256,
                        learning_rate_init=1e-3, n_iter_no_change=10, random_state=seed,
                        **options)


def _sklearn_classes():
    """scikit-learn's (MLPRegressor, ConvergenceWarning); ValueError with the install hint
    without it (the import is kept local: training needs scikit-learn, the tracker never
    does)."""
    try:
        from sklearn.exceptions import ConvergenceWarning
        from sklearn.neural_network import MLPRegressor
    except ImportError:
        raise ValueError("fitting limb networks needs scikit-learn: pip install -e '.[train]' "
                         "(or train with --limb-nets 0)") from None
    return MLPRegressor, ConvergenceWarning


def require_training_dependencies() -> None:
    """Raise the ValueError of :func:`_sklearn_classes` now when scikit-learn is missing, or
    one with the same hint when joblib cannot hand back results as they finish (1.3 or
    later; fit_limb_net's workers), so training stops before its slow steps rather than
    after them."""
    _sklearn_classes()
    import inspect

    from joblib import Parallel                         # scikit-learn's own dependency
    if "return_as" not in inspect.signature(Parallel).parameters:
        raise ValueError("fitting limb networks needs joblib 1.3 or later: "
                         "pip install -e '.[train]'")
