"""Training the default model from motion capture: data set -> codebook -> descriptors -> regressor.

Lives in ``tracker.offline`` because tracker is the one package allowed to use both
``sequences`` (renders of motion capture) and ``regressor`` (descriptors, regressors, model
files); nothing online imports it. scripts/train.py
is the command; this module holds the steps, each a function with cached results.
"""
from __future__ import annotations

import hashlib
import multiprocessing
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from regressor.angles import pose_angles, wrap_deg
from regressor.codebook import Codebook
from regressor.descriptor import (DescriptorSettings, descriptors_for_masks,
                                  fit_codebook_for_masks)
from regressor.pose_model import DEFAULT_AMBIGUITY_THRESHOLD, PoseModel, transform_descriptors
from regressor.rvm import RVMRegressor
from regressor.stacking import stack_frames
from sequences.dataset import Dataset

_CHUNK = 500                     # masks per worker task
_SHARED: dict = {}               # masks handed to forked workers (copy-on-write, not pickled)


def fit_dataset_codebook(dataset: Dataset, settings: DescriptorSettings, n_centres: int = 100,
                         n_masks: int = 2000, seed: int = 0) -> Codebook:
    """k-means codebook (n_centres x 60) on contexts of n_masks silhouettes drawn at random
    (seeded) from the data set, 50 contexts each."""
    rng = np.random.default_rng(seed)
    pick = np.sort(rng.choice(len(dataset), size=min(n_masks, len(dataset)), replace=False))
    return fit_codebook_for_masks((dataset.masks[i] for i in pick), settings,
                                  n_centres=n_centres, seed=seed)


def _descriptor_chunk(args) -> np.ndarray:
    start, stop, settings, codebook = args
    return descriptors_for_masks(_SHARED["masks"][start:stop], settings, codebook)


def dataset_descriptors(masks: np.ndarray, settings: DescriptorSettings, codebook: Codebook,
                        workers: int = 2,
                        progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """Descriptors (N, K) of masks (N, H, W) bool, computed by ``workers`` forked processes.
    progress(done, total) after each chunk of masks."""
    chunks = [(s, min(s + _CHUNK, len(masks)), settings, codebook)
              for s in range(0, len(masks), _CHUNK)]
    out = np.empty((len(masks), codebook.n_centres))
    _SHARED["masks"] = masks
    try:
        if workers > 1:
            with multiprocessing.get_context("fork").Pool(workers) as pool:
                for (start, stop, _, _), rows in zip(chunks, pool.imap(_descriptor_chunk, chunks)):
                    out[start:stop] = rows
                    if progress:
                        progress(stop, len(masks))
        else:
            for chunk in chunks:
                out[chunk[0]:chunk[1]] = _descriptor_chunk(chunk)
                if progress:
                    progress(chunk[1], len(masks))
    finally:
        _SHARED.clear()
    return out


def codebook_digest(codebook: Codebook, settings: DescriptorSettings) -> str:
    """Short digest of a codebook and descriptor settings (cache key)."""
    h = hashlib.sha256(np.ascontiguousarray(codebook.centres).tobytes())
    h.update(repr(sorted(settings.to_arrays().items(), key=lambda kv: kv[0])).encode())
    return h.hexdigest()[:12]


def cached_descriptors(cache_dir: str | Path, key: str, compute: Callable[[], tuple]) -> tuple:
    """(descriptors, codebook centres, codebook sigma) from cache_dir/descriptors-KEY.npz, or
    computed by compute() -> (X, codebook) and stored there."""
    path = Path(cache_dir) / f"descriptors-{key}.npz"
    if path.is_file():
        with np.load(path, allow_pickle=False) as z:
            return z["X"], Codebook(z["centres"], float(z["sigma"]))
    X, codebook = compute()
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, X=X, centres=codebook.centres, sigma=np.float64(codebook.sigma))
    return X, codebook


# ----------------------------------------------------------------------------- targets


def angle_centres(pose: np.ndarray) -> np.ndarray:
    """Circular mean (53,) in degrees of each angle of pose vectors (N, 55)."""
    rad = np.radians(pose[:, 2:])
    return np.degrees(np.arctan2(np.sin(rad).mean(axis=0), np.cos(rad).mean(axis=0)))


def regression_targets(pose: np.ndarray, centre_deg: np.ndarray) -> np.ndarray:
    """Targets (N, 55): heading (cos, sin) as is, angles as wrap(angle - centre) in degrees."""
    out = np.array(pose, dtype=np.float64, copy=True)
    out[:, 2:] = wrap_deg(out[:, 2:] - centre_deg)
    return out


def measurement_noise(predicted: np.ndarray, truth: np.ndarray, norm_threshold: float
                      ) -> tuple[np.ndarray, dict]:
    """Filter measurement covariance (54, 54) deg^2 from validation residuals of unambiguous
    frames (raw heading norm >= threshold), and facts about ambiguous frames: how much larger
    their residuals are (variance ratios for heading and joints), used to inflate R there."""
    residual = wrap_deg(pose_angles(predicted) - pose_angles(truth))
    norm = np.hypot(predicted[:, 0], predicted[:, 1])
    clear = norm >= norm_threshold
    if clear.sum() < 100:
        raise ValueError(f"only {clear.sum()} unambiguous validation frames; cannot estimate R")
    R = np.cov(residual[clear], rowvar=False)
    R += np.eye(len(R)) * 1e-6 * np.trace(R) / len(R)      # numerically positive definite
    facts = {"ambiguous_fraction": float(1 - clear.mean())}
    if (~clear).sum() >= 20:
        var_amb, var_clear = residual[~clear].var(axis=0), residual[clear].var(axis=0)
        facts["heading_variance_ratio"] = float(var_amb[0] / var_clear[0])
        facts["joint_variance_ratio"] = float(var_amb[1:].mean() / var_clear[1:].mean())
    return R, facts


def process_noise(pose: np.ndarray, sequence: np.ndarray, fps: float) -> np.ndarray:
    """Acceleration variances (54,) (deg/s^2)^2 of the true angles over consecutive frames of
    each sequence (second differences, wrapped, times fps^2)."""
    angles = pose_angles(pose)
    first = wrap_deg(angles[1:] - angles[:-1])
    same = sequence[1:] == sequence[:-1]
    accel = first[1:] - first[:-1]
    valid = same[1:] & same[:-1]
    return (accel[valid] * fps * fps).var(axis=0) + 1e-6


# ----------------------------------------------------------------------------- the whole job

#: Training trials whose views validate (never fitted): R comes from their residuals. One of
#: each kind of motion, so R reflects the mix the model will meet.
VALIDATION_TRIALS = ("02_02", "08_03", "05_02", "06_10", "09_04", "02_05")


@dataclass
class TrainingOptions:
    """Choices of the default model. stack_depth: frames stacked (k); n_fit: training rows
    (subsampled evenly in time from the training sequences) the kernel RVM sees; transform:
    descriptor transform; width_scale: kernel width knob (see regressor.basis); noise: the RVM's
    noise fraction (None: estimated); ambiguity_threshold: heading norm below which a frame is
    ambiguous; seed: everything random."""

    stack_depth: int = 3
    n_fit: int = 3000
    transform: str = "sqrt"
    width_scale: float = 1.0
    noise: float | None = None
    ambiguity_threshold: float = DEFAULT_AMBIGUITY_THRESHOLD
    seed: int = 0


def train_pose_model(dataset: Dataset, X: np.ndarray, codebook: Codebook,
                     settings: DescriptorSettings, options: TrainingOptions, fps: float,
                     log: Callable[[str], None] = print) -> tuple[PoseModel, dict]:
    """Fit the stacked kernel RVM on the data set's descriptors X (N, D) and derive the
    filter's noise models; returns the model and a report of validation figures."""
    trials = np.asarray(dataset.trial_of_sequence)[dataset.sequence]
    val = np.isin(trials, VALIDATION_TRIALS)
    if not val.any() or val.all():
        raise ValueError("validation trials must be a proper subset of the training trials")
    Xs = stack_frames(transform_descriptors(X, options.transform), options.stack_depth,
                      sequence_ids=dataset.sequence)
    train_rows = np.flatnonzero(~val)
    fit_rows = train_rows[np.linspace(0, len(train_rows) - 1,
                                      min(options.n_fit, len(train_rows))).astype(int)]
    centre = angle_centres(dataset.pose[~val])
    Y = regression_targets(dataset.pose, centre)
    log(f"fitting kernel RVM on {len(fit_rows)} of {len(train_rows)} training rows "
        f"(k = {options.stack_depth}, {Xs.shape[1]}-D input) ...")
    start = time.perf_counter()
    rvm = RVMRegressor(basis="gaussian", noise=options.noise, width_scale=options.width_scale)
    rvm.fit(Xs[fit_rows], Y[fit_rows])
    fit_seconds = time.perf_counter() - start
    log(f"  {rvm.n_basis_} relevance vectors, {fit_seconds:.1f} s")
    model = PoseModel(settings=settings, codebook=codebook, stack_depth=options.stack_depth,
                      transform=options.transform, basis="gaussian", width=rvm.width_,
                      centres=rvm.centres_, relevance=rvm.relevance_, coef=rvm.coef_,
                      intercept=rvm.intercept_, angle_centre_deg=centre,
                      measurement_covariance=np.eye(54), process_noise=np.ones(54),
                      ambiguity_threshold=options.ambiguity_threshold)
    val_rows = np.flatnonzero(val)
    predicted = model.predict_batch(Xs[val_rows])
    R, facts = measurement_noise(predicted, dataset.pose[val_rows], options.ambiguity_threshold)
    model.measurement_covariance = R
    model.process_noise = process_noise(dataset.pose[~val], dataset.sequence[~val], fps)
    errors = np.abs(wrap_deg(pose_angles(predicted) - pose_angles(dataset.pose[val_rows])))
    report = {"n_train_rows": int(len(train_rows)), "n_fit": int(len(fit_rows)),
              "n_validation_rows": int(len(val_rows)), "relevance_vectors": int(rvm.n_basis_),
              "fit_seconds": round(fit_seconds, 1),
              "validation_joint_error_deg": round(float(errors[:, 1:].mean()), 2),
              "validation_heading_rms_deg": round(float(np.sqrt((errors[:, 0] ** 2).mean())), 2),
              **{k: round(v, 3) for k, v in facts.items()}}
    return model, report
