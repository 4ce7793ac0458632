"""Several same-shaped ReLU stacks (regressor.relu_layers) run as one batched stack, for the
limb networks' mean on a single row (regressor.limb_net.LimbNet.predict; loaded on first use).
"""
from __future__ import annotations

import numpy as np


def stacked_members(members) -> list | None:
    """Several stacks of the same shapes, each with at least one hidden layer (float32,
    as_float32_layers), as one: the first layer's weights side by side (n_in, M * n_1) with
    its biases (M * n_1,), every later layer's as (M, n_i, n_o) with biases (M, 1, n_o);
    None when the shapes differ or there is no hidden layer. The members' mean
    (forward_mean) then costs a few numpy calls instead of M times as many."""
    shapes = {tuple((W.shape, b.shape) for W, b in layers) for layers in members}
    if len(shapes) != 1 or len(members[0]) < 2:
        return None
    first = (np.concatenate([layers[0][0] for layers in members], axis=1),
             np.concatenate([layers[0][1] for layers in members]))
    later = [(np.stack([layers[i][0] for layers in members]),
              np.stack([layers[i][1] for layers in members])[:, None, :])
             for i in range(1, len(members[0]))]
    return [first, *later]


def forward_mean(x: np.ndarray, stacked: list) -> np.ndarray:
    """The mean over members of their outputs (N, n_out) for inputs x (N, n_in) (already
    standardised), from stacked_members' arrays: what averaging forward() over the members
    gives, up to float32 rounding; float64 (N, n_out)."""
    (W, b), later = stacked[0], stacked[1:]
    members = len(later[0][0])
    h = np.maximum(x @ W + b, 0.0).reshape(len(x), members, W.shape[1] // members)
    h = h.transpose(1, 0, 2)
    for i, (W, b) in enumerate(later):
        h = np.matmul(h, W) + b                         # (M, N, n_o)
        if i < len(later) - 1:
            h = np.maximum(h, 0.0)
    return h.mean(axis=0, dtype=np.float64)
