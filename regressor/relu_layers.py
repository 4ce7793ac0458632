"""Stacks of ReLU layers kept as plain arrays (no pickle): the checks and the forward pass that
the limb networks (regressor.limb_net) and the side classifier (regressor.side_classifier)
share. A stack is a list of (W (n_in, n_out), b (n_out,)); every layer but the last is
followed by a ReLU."""
from __future__ import annotations

import numpy as np

_FLOAT32_MAX = float(np.finfo(np.float32).max)


def as_float32_layers(layers, what: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """The layers as float32 arrays; ValueError naming ``what`` when a weight is not finite
    or beyond float32's range (the cast would turn it into inf)."""
    for W, b in layers:
        if not all(np.all(np.abs(np.asarray(a, dtype=np.float64)) <= _FLOAT32_MAX)
                   for a in (W, b)):
            raise ValueError(f"invalid {what}: weights out of float32 range or not finite")
    return [(np.asarray(W, dtype=np.float32), np.asarray(b, dtype=np.float32))
            for W, b in layers]


#: Stored int8 scales must stay under this, so -128 * scale is finite in float32. (A scale
#: below the smallest normal float32 is fine: it holds a column of tiny weights.)
_MAX_SCALE = _FLOAT32_MAX / 128.0


def dequantised_int8(q, scale, what: str) -> np.ndarray:
    """The float32 weights (n_in, n_out) of regressor.model_writer.quantised_int8's parts q
    (n_in, n_out) int8 and scale (n_out,) float32; ValueError naming ``what`` when q is not a
    matrix of int8 or the scales are not one float32 per column in (0, _MAX_SCALE]."""
    q, scale = np.asarray(q), np.asarray(scale)
    if q.dtype != np.int8:
        raise ValueError(f"{what}: quantised weights must hold int8, not {q.dtype}")
    if q.ndim != 2:
        raise ValueError(f"{what}: quantised weights must be 2-D, got shape {q.shape}")
    if scale.dtype != np.float32 or scale.shape != (q.shape[1],):
        raise ValueError(f"{what}'s scales must be {q.shape[1]} float32 values, one per "
                         f"column, got {scale.dtype} {scale.shape}")
    if not np.all((scale > 0) & (scale <= _MAX_SCALE)):
        raise ValueError(f"{what}'s scales must be positive finite floats up to "
                         f"{_MAX_SCALE:.3g}")
    return q.astype(np.float32) * scale


def standardised(X: np.ndarray, mean: np.ndarray, scale: float) -> np.ndarray:
    """Inputs X (N, P) as a stack takes them: (X - mean) / scale, float32 (N, P)."""
    return ((np.asarray(X, dtype=np.float64) - mean) / scale).astype(np.float32)


def forward(x: np.ndarray, layers) -> np.ndarray:
    """The stack's output for inputs x (N, n_in) (already standardised): (N, n_out)."""
    h = x
    for W, b in layers[:-1]:
        h = np.maximum(h @ W + b, 0.0)
    W, b = layers[-1]
    return h @ W + b


def check_parts(a, needed: list[str], prefix: str, header: str, what: str,
                declarer: str, int8_parts: tuple[str, ...] = ()) -> float:
    """Check a file's parts a (mapping) for ``what`` (e.g. "limb network"): every needed part
    present and floats (int8_parts: int8), no other part under ``prefix`` but ``header`` (which
    declares the others, by ``declarer``), ``{prefix}input_scale`` one number, which is
    returned. ValueError naming the first problem."""
    missing = [k for k in needed if k not in a]
    if missing:
        raise ValueError(f"{what} is incomplete (no {missing[0]})")
    extra = sorted(k for k in map(str, a.keys())
                   if k.startswith(prefix) and k not in needed and k != header)
    if extra:
        raise ValueError(f"{what} has a part its {declarer} ({extra[0]})")
    for k in int8_parts:
        if np.asarray(a[k]).dtype != np.int8:
            raise ValueError(f"{what} part {k} must hold int8, not {np.asarray(a[k]).dtype}")
    for k in needed:
        if k not in int8_parts and np.asarray(a[k]).dtype.kind != "f":
            raise ValueError(f"{what} part {k} must hold floats, not {np.asarray(a[k]).dtype}")
    scale = np.asarray(a[f"{prefix}input_scale"])
    if scale.shape != ():
        raise ValueError(f"{what} input scale must be one number")
    return float(scale)


def typical_inputs(input_mean: np.ndarray) -> np.ndarray:
    """Probe inputs (3, P) like the regressor's: zeros, ones and the mean itself. A stack with
    absurd but finite parts (a tiny scale, a huge mean) overflows on them: loaders refuse it."""
    return np.vstack([np.zeros_like(input_mean), np.ones_like(input_mean), input_mean])
