"""Which half the body faces: a small neural network on the regressor's input (issue 10).

A silhouette cannot tell a body from its front/back flip (sequences.pose_vector.front_back_flip)
by its outline alone, but the limbs' shapes (knees bend forwards, feet point forwards) carry
some of it. The side classifier is a ReLU network that says, from the regressor's projected
input (the same input the limb networks take), how probable it is that the body faces the
camera's half (|heading| <= 90 deg). The tracker's front/back chain uses it as per-frame
evidence for the limb network's canonical member against its flip (tracker.tracks.hypotheses,
"Canonical hypotheses"), through a table that calibrates it on validation renders: on its
own held-out training rows it is right 9 times in 10, on video-like renders about 7 in 10.

Tried and not adopted (2026-12-02, one-off drivers): on the 6 validation trials' own rows the
shipped classifier is right on 77.4 % of rows (63 % within 20 degrees of profile); L2 alpha
0.1 gives 78.2 %, three such networks averaged 80.8 % (log loss 1.13 -> 0.83), a linear
logistic regression 60.6 %, and early stopping on whole held-out trials stops after the first
epoch (their log loss rises from then on while the accuracy still climbs). But on the 28
validation renders the front/back chain is tuned on, the three gave 69.4 % against 68.8 %, and
through the chain (their own priors learned) the filtered / smoothed heading went 32.7 / 26.6
-> 34.8 / 32.5 degrees and corr8 0.546 -> 0.534 (alpha 0.1 alone: 37.3 / 33.5, 0.521).
Fitted on the training rows' mirror images too (as the limb networks are; the label does not
change under a left/right mirror): 79.0 % on the validation rows, but 61.9 % on the 28 renders
(68.8 % without), and through the chain 38.5 / 34.4 -> 47.8 / 45.9 degrees: not adopted.

A :class:`SideClassifier` is plain arrays (no pickle): ReLU hidden layers and a linear output
(one logit), inputs standardised by a mean and one scale. Stored under "side_net_" in a
mixture model's file (weights as float16).
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .relu_layers import (as_float32_layers, check_parts, forward, standardised,
                          typical_inputs)

PREFIX = "side_net_"
MAX_LAYERS = 8


@dataclass
class SideClassifier:
    """layers [(W (n_in, n_out), b (n_out,)), ...]: ReLU hidden layers, the last linear to one
    logit; input_mean (P,) and input_scale (scalar) standardise the regressor's input X
    (N, P)."""

    layers: list[tuple[np.ndarray, np.ndarray]]
    input_mean: np.ndarray
    input_scale: float

    def __post_init__(self):
        self.layers = as_float32_layers(self.layers, "side classifier")
        self.input_mean = np.asarray(self.input_mean, dtype=np.float64)
        self.input_scale = float(self.input_scale)
        problem = self._problem()
        if problem:
            raise ValueError(f"invalid side classifier: {problem}")

    def _problem(self) -> str | None:
        """The first inconsistency of the parts, or None."""
        if not 1 <= len(self.layers) <= MAX_LAYERS:
            return f"it must have 1..{MAX_LAYERS} layers"
        if self.input_mean.ndim != 1 or len(self.input_mean) < 1:
            return f"input mean has shape {self.input_mean.shape}"
        n_in = len(self.input_mean)
        for i, (W, b) in enumerate(self.layers):
            if W.ndim != 2 or W.shape[0] != n_in or b.shape != (W.shape[1],):
                return f"layer {i} has shape {W.shape} / {b.shape} after {n_in} values"
            n_in = W.shape[1]
        if n_in != 1:
            return f"it gives {n_in} values, not one logit"
        arrays = [self.input_mean, *(a for layer in self.layers for a in layer)]
        if not all(np.isfinite(a).all() for a in arrays) or not np.isfinite(self.input_scale):
            return "non-finite values"
        if not self.input_scale > 0:
            return "the input scale must be positive"
        if any(W.shape[1] < 1 for W, _ in self.layers):
            return "a layer has no units"
        # absurd but finite parts (a tiny scale, a huge mean) overflow on typical inputs
        with np.errstate(all="ignore"):
            if not np.isfinite(self._logits(typical_inputs(self.input_mean))).all():
                return "it gives non-finite values on typical inputs"
        return None

    @property
    def input_length(self) -> int:
        """P, the length of the regressor's input the classifier takes."""
        return len(self.input_mean)

    def front_probability(self, X: np.ndarray) -> np.ndarray:
        """P(the body faces the camera's half, |heading| <= 90 deg) (N,) from the regressor's
        inputs X (N, P). Inputs the network cannot evaluate (non-finite, or beyond float32's
        range) give 0.5: no evidence either way."""
        with np.errstate(all="ignore"):
            logit = np.nan_to_num(self._logits(X), nan=0.0)
            return 1.0 / (1.0 + np.exp(-np.clip(logit, -50.0, 50.0)))

    def _logits(self, X: np.ndarray) -> np.ndarray:
        """The network's output (N,) (log-odds of facing the camera's half)."""
        h = standardised(X, self.input_mean, self.input_scale)
        return forward(h, self.layers)[:, 0].astype(np.float64)

    def to_arrays(self, prefix: str = PREFIX) -> dict:
        """The file parts, keyed by ``prefix``; weights as float16."""
        out = {f"{prefix}layers": np.int64(len(self.layers)),
               f"{prefix}input_mean": self.input_mean,
               f"{prefix}input_scale": np.float64(self.input_scale)}
        for i, (W, b) in enumerate(self.layers):
            out[f"{prefix}W{i}"] = W.astype(np.float16)
            out[f"{prefix}b{i}"] = b.astype(np.float32)
        return out

    @classmethod
    def from_arrays(cls, a, prefix: str = PREFIX) -> "SideClassifier | None":
        """The classifier in a file's parts a (mapping), None when it has none; ValueError
        when it is incomplete or inconsistent."""
        if f"{prefix}layers" not in a:
            if any(str(k).startswith(prefix) for k in a.keys()):
                raise ValueError("side classifier is incomplete")
            return None
        n = np.asarray(a[f"{prefix}layers"])
        if n.shape != () or not np.issubdtype(n.dtype, np.integer) \
                or not 1 <= int(n) <= MAX_LAYERS:
            raise ValueError(f"side classifier layers must be one integer in 1..{MAX_LAYERS}")
        needed = [f"{prefix}input_mean", f"{prefix}input_scale"] + \
            [f"{prefix}{s}{i}" for i in range(int(n)) for s in ("W", "b")]
        scale = check_parts(a, needed, prefix, f"{prefix}layers", "side classifier",
                            "layers do not declare")
        return cls([(a[f"{prefix}W{i}"], a[f"{prefix}b{i}"]) for i in range(int(n))],
                   a[f"{prefix}input_mean"], scale)


def facing_camera(heading_deg: np.ndarray) -> np.ndarray:
    """The classifier's label (N,) bool: the heading (N,) degrees is in the camera's half
    (|heading| <= 90)."""
    return np.abs(np.asarray(heading_deg, dtype=np.float64)) <= 90.0


def fit_side_classifier(X: np.ndarray, heading_deg: np.ndarray,
                        hidden: tuple[int, ...] = (128,), alpha: float = 1e-3,
                        max_iter: int = 200, seed: int = 0,
                        log: Callable[[str], None] = lambda message: None) -> SideClassifier:
    """Fit a :class:`SideClassifier` on inputs X (N, P) labelled by the true headings
    heading_deg (N,) (front: |heading| <= 90) with scikit-learn's MLPClassifier (Adam,
    minibatches of 256, L2 alpha, 10 % held out for early stopping after 10 epochs without
    gain; seeded). Needs scikit-learn (training only)."""
    if not 1 <= len(hidden) + 1 <= MAX_LAYERS:
        raise ValueError(f"a side classifier has 0..{MAX_LAYERS - 1} hidden layers, got "
                         f"{len(hidden)}")
    try:
        from sklearn.exceptions import ConvergenceWarning
        from sklearn.neural_network import MLPClassifier
    except ImportError:
        raise ValueError("fitting the side classifier needs scikit-learn: "
                         "pip install -e '.[train]'") from None
    X = np.asarray(X, dtype=np.float64)
    front = facing_camera(heading_deg).astype(int)
    if len(np.unique(front)) < 2:
        raise ValueError("the side classifier needs poses facing both halves")
    x_mean, x_scale = X.mean(axis=0), float(X.std(axis=0).mean())
    start = time.perf_counter()
    net = MLPClassifier(hidden_layer_sizes=tuple(hidden), alpha=alpha, batch_size=256,
                        max_iter=max_iter, early_stopping=True, n_iter_no_change=10,
                        random_state=seed)
    with warnings.catch_warnings():          # max_iter reached is reported below, not warned
        warnings.simplefilter("ignore", ConvergenceWarning)
        net.fit((X - x_mean) / x_scale, front)
    stopped = "max_iter reached" if net.n_iter_ >= max_iter else "early stop"
    log(f"  side classifier: {net.n_iter_} epochs ({stopped}), held-out accuracy "
        f"{net.best_validation_score_:.3f}, {time.perf_counter() - start:.0f} s")
    return SideClassifier(list(zip(net.coefs_, net.intercepts_)), x_mean, x_scale)
