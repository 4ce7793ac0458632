"""Fitting the limb networks (regressor.limb_net.LimbNet): scikit-learn's MLPRegressor per
member (the ``train`` extra), its layers kept as plain arrays. Training only; ``track`` loads
regressor.limb_net alone.
"""
from __future__ import annotations

import time
import warnings
from typing import Callable

import numpy as np
from threadpoolctl import threadpool_limits

from .mixture_fit import regression_targets
from .limb_net import MAX_LAYERS, MAX_MEMBERS, OUTPUT_WIDTHS, LimbNet
from .rotation6d import angles_to_rot6d


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
