"""The front/back hypotheses of a model without limb networks and a side classifier: each
expert's pose and its flip, weighed by how often the raw pose is the nearer one
(tracker.tracks.hypotheses; loaded only for such models, not the shipped one)."""
from __future__ import annotations

import numpy as np

from regressor.angles import heading_norm
from sequences.pose_vector import front_back_flip
from tracker.tracks.hypotheses import _FLOOR, Hypotheses, _table

#: P(the raw pose is nearer the truth than its flip | raw heading norm in
#: [RAW_NEARER_NORM_EDGES[b], next edge)), and overall; learned on validation renders by
#: scripts/learn_hypothesis_priors.py ("nearer": smaller mean absolute error, 54 angles).
RAW_NEARER_NORM_EDGES = (0.0, 0.2, 0.4, 0.6, 0.8, 1.0)
RAW_NEARER_BY_NORM = (0.672, 0.617, 0.646, 0.703, 0.744, 0.688)
RAW_NEARER_OVERALL = 0.681


def deaveraged_heading(poses: np.ndarray) -> np.ndarray:
    """Poses (m, 55) with the heading the regressor was averaging towards: unsure of a view or
    its flip it outputs about p (cos h, sin h) + (1 - p) (-cos h, sin h), cos shrinking. Each
    heading takes |cos| = sqrt(1 - sin^2) back in proportion to the lost norm (norm kept)."""
    out = np.array(poses, dtype=np.float64, copy=True)
    c, s = out[:, 0], out[:, 1]
    n = np.hypot(c, s)
    w = np.clip(n, 0.0, 1.0)
    s_unit = s / np.maximum(n, 1.0)
    c_unit = np.where(c < 0, -1.0, 1.0) * np.sqrt(np.maximum(0.0, 1.0 - s_unit ** 2))
    h = np.arctan2(w * s + (1 - w) * s_unit, w * c + (1 - w) * c_unit)
    out[:, 0], out[:, 1] = n * np.cos(h), n * np.sin(h)
    return out


def with_flips(poses: np.ndarray, gate: np.ndarray, limbs: np.ndarray | None = None
               ) -> Hypotheses:
    """Each pose (m, 55) with gate probability (m,) -> 2m hypotheses (pose, flip, pose, ...),
    headings de-averaged, evidence from RAW_NEARER_BY_NORM; raw stays the regressor's first
    pose; limbs (55,) the limb head's pose or None, passed on."""
    raw = poses[0]
    poses = deaveraged_heading(poses)
    p_raw = _table(RAW_NEARER_NORM_EDGES, RAW_NEARER_BY_NORM, heading_norm(poses))
    ratio = np.stack([p_raw / RAW_NEARER_OVERALL, (1 - p_raw) / (1 - RAW_NEARER_OVERALL)], 1)
    both = np.stack([poses, front_back_flip(poses)], axis=1).reshape(-1, poses.shape[-1])
    evidence = np.log(np.maximum(gate, _FLOOR))[:, None] + np.log(ratio)
    return Hypotheses(both, evidence.reshape(-1), raw, limbs)
