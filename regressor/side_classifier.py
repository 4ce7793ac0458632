"""Which half the body faces (issue 10): an outline cannot tell a body from its front/back
flip, but the limbs' shapes (knees bend, feet point forwards) carry some of it. A ReLU network
on the regressor's input gives P(the body faces the camera's half, |heading| <= 90 deg), the
evidence for the limbs' canonical member against its flip (tracker.tracks.hypotheses). Parts
"side_net_" (weights float16); fitting: regressor.side_classifier_training, docs/tuning.md.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .relu_layers import (as_float32_layers, check_parts, forward, standardised,
                          typical_inputs)

PREFIX = "side_net_"
MAX_LAYERS = 8


@dataclass
class SideClassifier:
    """layers [(W (n_in, n_out), b (n_out,)), ...]: ReLU hidden layers, the last linear to one
    logit; input_mean (P,) and input_scale standardise the regressor's input X (N, P)."""

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
        """P(the body faces the camera's half) (N,) from the regressor's inputs X (N, P); 0.5
        (no evidence) where the network cannot evaluate them (non-finite, beyond float32)."""
        with np.errstate(all="ignore"):
            logit = np.nan_to_num(self._logits(X), nan=0.0)
            return 1.0 / (1.0 + np.exp(-np.clip(logit, -50.0, 50.0)))

    def _logits(self, X: np.ndarray) -> np.ndarray:
        """The network's output (N,) (log-odds of facing the camera's half)."""
        h = standardised(X, self.input_mean, self.input_scale)
        return forward(h, self.layers)[:, 0].astype(np.float64)

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
