"""Training the default model from motion capture: data set -> codebook -> descriptors -> regressor.

Lives in ``tracker.offline`` because tracker is the one package allowed to use both
``sequences`` (renders of motion capture) and ``regressor`` (descriptors, regressors, model
files); nothing online imports it. scripts/train.py
is the command; this module holds the steps, each a function with cached results.
"""
from __future__ import annotations

import hashlib
import json
import multiprocessing
import os
import time
import warnings
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
from threadpoolctl import threadpool_limits

from regressor.angles import POSE_DIM, pose_angles, regression_targets, wrap_deg
from regressor.codebook import Codebook
from regressor.heading_index import build_heading_index
from regressor.descriptor import (DescriptorSettings, SilhouetteError, descriptor_and_mirror,
                                  descriptor_for_mask, descriptors_for_masks,
                                  fit_codebook_for_masks)
from regressor.layout import layouts_for_masks, silhouette_layout
from regressor.limb_net import (MAX_MEMBERS, LimbNet, fit_limb_net,
                               require_training_dependencies)
from regressor.side_classifier import facing_camera, fit_side_classifier
from regressor.pose_model import (DEFAULT_AMBIGUITY_THRESHOLD, LimbHead, PoseModel,
                                  frame_descriptors, transform_descriptors)
from regressor.rvm import RVMRegressor
from regressor.stacking import stack_frames
from sequences.dataset import Dataset
from sequences.measures import body_angle_error, constant_error, skill, top_angle_correlation
from sequences.mask_noise import MaskNoise, degrade_all
from sequences.pose_vector import canonical_member, flip_odd_part, heading_deg, image_mirror

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


# ----------------------------------------------------------------------------- noise-aware masks
# (issue 9: train on silhouettes that look like the tracker's own; see sequences.mask_noise)


def extractor_cleaner(canvas: np.ndarray, shape: tuple[int, int]) -> np.ndarray | None:
    """The tracker's own mask cleaning and splitting on a foreground canvas (uint8, 255 =
    foreground): clean_mask, then person_masks; the largest person's crop (bool) or None."""
    from ..silhouettes import clean_mask, person_masks
    people = person_masks(clean_mask(canvas), (shape[1], shape[0]))
    return people[0].mask if people else None


def noisy_masks(masks, seed: int, noise=None, start: int = 0) -> list[np.ndarray]:
    """Video-like versions (sequences.mask_noise.degrade, with the extractor's cleaning) of
    masks[i], i = 0.., each seeded by (seed, start + i)."""
    return degrade_all(masks, seed, noise or MaskNoise(), extractor_cleaner, start=start)


def video_like_masks(masks, seed: int, start: int = 0, degrade: bool = True) -> list:
    """The masks the model learns from: noisy_masks of masks (hand noise on plain renders),
    or with degrade=False the masks themselves (already video-like: the data set's realistic
    masks, cut out of rendered video by the tracker's extractor)."""
    return noisy_masks(masks, seed, start=start) if degrade else list(masks)


def _pooled_rows(masks: np.ndarray, task, args: tuple, width: int, workers: int,
                 progress: Callable[[int, int], None] | None) -> np.ndarray:
    """Rows (N, width), task((start, stop, *args)) -> rows start:stop, over chunks of masks
    in ``workers`` forked processes (the masks are shared copy-on-write, not pickled)."""
    chunks = [(s, min(s + _CHUNK, len(masks)), *args) for s in range(0, len(masks), _CHUNK)]
    out = np.empty((len(masks), width))
    _SHARED["masks"] = masks
    try:
        with multiprocessing.get_context("fork").Pool(max(1, workers)) as pool:
            for (start, stop, *_), rows in zip(chunks, pool.imap(task, chunks)):
                out[start:stop] = rows
                if progress:
                    progress(stop, len(masks))
    finally:
        _SHARED.clear()
    return out


def _noisy_layout_chunk(args) -> np.ndarray:
    start, stop, grid, seed, degrade = args
    return layouts_for_masks(video_like_masks(_SHARED["masks"][start:stop], seed, start, degrade),
                             grid)


def noisy_dataset_layouts(masks: np.ndarray, grid: int, seed: int = 0, workers: int = 2,
                          progress: Callable[[int, int], None] | None = None,
                          degrade: bool = True) -> np.ndarray:
    """Layouts (N, grid^2) (regressor.layout) of the same video-like masks as
    noisy_dataset_inputs (same seeds and degrade, so row i's layout and descriptor describe one
    mask), by ``workers`` forked processes; for a cache that has the descriptors but not the
    layouts."""
    return _pooled_rows(masks, _noisy_layout_chunk, (grid, seed, bool(degrade)), grid * grid,
                        workers, progress)


def _noisy_inputs_chunk(args) -> np.ndarray:
    start, stop, settings, codebook, seed, grid, mirror, degrade = args
    rows = []
    for i, mask in enumerate(video_like_masks(_SHARED["masks"][start:stop], seed, start,
                                              degrade)):
        try:
            own, reflected = (descriptor_and_mirror(mask, settings, codebook) if mirror
                              else (descriptor_for_mask(mask, settings, codebook), None))
        except SilhouetteError as err:
            raise type(err)(f"mask {start + i}: {err}") from err
        parts = [own] + ([silhouette_layout(mask, grid)] if grid else [])
        if mirror:
            parts += [reflected] + ([silhouette_layout(mask[:, ::-1], grid)] if grid else [])
        rows.append(np.concatenate(parts))
    return np.array(rows)


def noisy_dataset_inputs(masks: np.ndarray, settings: DescriptorSettings, codebook: Codebook,
                         grid: int = 0, mirror: bool = False, seed: int = 0, workers: int = 2,
                         progress: Callable[[int, int], None] | None = None,
                         degrade: bool = True) -> dict[str, np.ndarray]:
    """The video-like masks' inputs in one pass (each mask degraded and its shape contexts
    computed once, by ``workers`` forked processes; reproducible whatever their number):
    {"histograms": (N, K) (descriptors_for_masks of noisy_masks(masks, seed)), "layouts":
    (N, grid^2) with grid > 0 (equal to noisy_dataset_layouts), and with mirror
    "mirror_histograms" (N, K), "mirror_layouts" (N, grid^2): the same video-like masks'
    mirror images (flipped left to right), described as the tracker describes a frame's
    mirror (regressor.descriptor.descriptor_and_mirror)}. degrade=False: the masks are already
    video-like (realistic ones) and are described as they are (video_like_masks).
    Raises DegenerateSilhouetteError naming the first unusable mask's index."""
    K, cells = codebook.n_centres, int(grid) ** 2 if grid else 0
    widths = {"histograms": K, "layouts": cells}
    if mirror:
        widths.update(mirror_histograms=K, mirror_layouts=cells)
    rows = _pooled_rows(masks, _noisy_inputs_chunk,
                        (settings, codebook, seed, int(grid), bool(mirror), bool(degrade)),
                        sum(widths.values()), workers, progress)
    out, at = {}, 0
    for name, width in widths.items():
        if width:       # own arrays, not views that would keep all the rows alive
            out[name] = np.ascontiguousarray(rows[:, at:at + width])
        at += width
    return out


def cached_layouts(cache_dir: str | Path, key: str, grid: int,
                   compute: Callable[[], np.ndarray]) -> np.ndarray:
    """Layouts (N, grid^2) from cache_dir/layouts-KEY-gGRID.npz, or compute() and store them."""
    path = Path(cache_dir) / f"layouts-{key}-g{grid}.npz"
    cached = _load_cache(path, ("L",))
    if cached is not None:
        return cached["L"]
    L = compute()
    _save_cache(path, L=L.astype(np.float32))
    return L


def _load_cache(path: Path, names: tuple[str, ...]) -> dict | None:
    """The arrays ``names`` of a cache file, or None when there is none; a file that cannot
    be read (cut off by an interrupted run before writes became atomic, or damaged) is
    reported in one warning and computed again."""
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            return {name: z[name] for name in names}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        warnings.warn(f"cache file {path} is unreadable ({type(exc).__name__}: {exc}); "
                      f"computing it again")
        return None


def _save_cache(path: Path, **arrays) -> None:
    """Write a cache file whole or not at all: beside it first, then renamed over it, so an
    interrupted run never leaves a cut-off file that later runs would trip over."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f"{path.stem}.partial-{os.getpid()}.npz")
    try:
        np.savez_compressed(partial, **arrays)
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)


def block_spread(B: np.ndarray) -> float:
    """Root mean squared distance of rows B (N, d) from their mean: a block's scale as a
    Gaussian kernel sees it."""
    B = np.asarray(B, dtype=np.float64)
    return float(np.sqrt(((B - B.mean(axis=0)) ** 2).sum(axis=1).mean()))


def fit_projection(X: np.ndarray, components: int, max_rows: int = 15000,
                   seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Principal directions of rows X (N, d): (mean (d,), projection (d, P)), P = components,
    from at most max_rows rows drawn at random (seeded)."""
    X = np.asarray(X, dtype=np.float64)
    rows = X if len(X) <= max_rows else X[np.sort(np.random.default_rng(seed).choice(
        len(X), max_rows, replace=False))]
    mean = rows.mean(axis=0)
    _, _, vt = np.linalg.svd(rows - mean, full_matrices=False)
    return mean, vt[:min(components, len(vt))].T.copy()


def fit_noisy_codebook(dataset: Dataset, settings: DescriptorSettings, n_centres: int = 100,
                       n_masks: int = 2000, seed: int = 0) -> Codebook:
    """As fit_dataset_codebook, on video-like versions of the drawn masks (hand noise; realistic
    masks, video-like already, take fit_dataset_codebook)."""
    rng = np.random.default_rng(seed)
    pick = np.sort(rng.choice(len(dataset), size=min(n_masks, len(dataset)), replace=False))
    masks = [noisy_masks(dataset.masks[i:i + 1], seed, start=int(i))[0] for i in pick]
    return fit_codebook_for_masks(masks, settings, n_centres=n_centres, seed=seed)


def codebook_digest(codebook: Codebook, settings: DescriptorSettings) -> str:
    """Short digest of a codebook and descriptor settings (cache key)."""
    h = hashlib.sha256(np.ascontiguousarray(codebook.centres).tobytes())
    h.update(repr(sorted(settings.to_arrays().items(), key=lambda kv: kv[0])).encode())
    return h.hexdigest()[:12]


def cached_descriptors(cache_dir: str | Path, key: str, compute: Callable[[], tuple]) -> tuple:
    """(descriptors, codebook centres, codebook sigma) from cache_dir/descriptors-KEY.npz, or
    computed by compute() -> (X, codebook) and stored there."""
    path = Path(cache_dir) / f"descriptors-{key}.npz"
    cached = _load_cache(path, ("X", "centres", "sigma"))
    if cached is not None:
        return cached["X"], Codebook(cached["centres"], float(cached["sigma"]))
    X, codebook = compute()
    _save_cache(path, X=X, centres=codebook.centres, sigma=np.float64(codebook.sigma))
    return X, codebook


# ----------------------------------------------------------------------------- targets


def angle_centres(pose: np.ndarray) -> np.ndarray:
    """Circular mean (53,) in degrees of each angle of pose vectors (N, 55)."""
    rad = np.radians(pose[:, 2:])
    return np.degrees(np.arctan2(np.sin(rad).mean(axis=0), np.cos(rad).mean(axis=0)))


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


def validation_mask(dataset: Dataset) -> np.ndarray:
    """(N,) bool: the rows of VALIDATION_TRIALS (never fitted)."""
    trials = np.asarray(dataset.trial_of_sequence)[dataset.sequence]
    val = np.isin(trials, VALIDATION_TRIALS)
    if not val.any() or val.all():
        raise ValueError("validation trials must be a proper subset of the training trials")
    return val


def _stacked_rows(dataset: Dataset, X: np.ndarray, transform: str, stack_depth: int,
                  layouts: np.ndarray | None, layout_weight: float) -> np.ndarray:
    """Every row's stacked descriptor (N, k*D): regressor.pose_model.frame_descriptors of the
    histograms X (N, K) and layouts (N, grid^2) or None, stacked within each sequence."""
    return stack_frames(frame_descriptors(X, transform, layouts, layout_weight), stack_depth,
                        sequence_ids=dataset.sequence)


def reversed_in_sequence(sequence: np.ndarray) -> np.ndarray:
    """Row permutation (N,) that reverses the order of the rows within each sequence
    (sequence (N,): label per row, a new sequence wherever it changes), sequences kept in
    place. It is its own inverse."""
    sequence = np.asarray(sequence)
    starts = np.r_[0, np.flatnonzero(sequence[1:] != sequence[:-1]) + 1, len(sequence)]
    order = np.arange(len(sequence))
    for start, stop in zip(starts[:-1], starts[1:]):
        order[start:stop] = order[start:stop][::-1]
    return order


def _time_reversed_rows(dataset: Dataset, X: np.ndarray, transform: str, stack_depth: int,
                        layouts: np.ndarray | None, layout_weight: float) -> np.ndarray:
    """Every row's stacked descriptor as if its sequence were played backwards (N, k*D): row
    t holds [x_t, x_{t+1}, ..., x_{t+k-1}] (frames past a sequence's end replaced by its
    last), the input a body moving the other way through the same poses gives."""
    order = reversed_in_sequence(dataset.sequence)
    frames = frame_descriptors(X, transform, layouts, layout_weight)
    return stack_frames(frames[order], stack_depth,
                        sequence_ids=np.asarray(dataset.sequence)[order])[order]


def _training_arrays(dataset: Dataset, X: np.ndarray, transform: str, stack_depth: int,
                     layouts: np.ndarray | None = None, layout_weight: float = 0.0,
                     pose: np.ndarray | None = None):
    """What every regressor is fitted on: (validation mask (N,) bool: rows of
    VALIDATION_TRIALS, never fitted; stacked per-frame descriptors (N, k*D)
    (regressor.pose_model.frame_descriptors of the histograms X and the layouts); the training
    rows' circular mean angles (53,) deg; regression targets (N, 55)). pose: the target poses
    (N, 55) when not the data set's own (canonical members)."""
    val = validation_mask(dataset)
    Xs = _stacked_rows(dataset, X, transform, stack_depth, layouts, layout_weight)
    pose = dataset.pose if pose is None else pose
    centre = angle_centres(pose[~val])
    return val, Xs, centre, regression_targets(pose, centre)


#: MixtureOptions.canonical's choices.
CANONICAL_RULES = ("none", "limbs", "facing")


def canonical_direction(pose: np.ndarray, max_rows: int = 20000, seed: int = 0) -> np.ndarray:
    """The direction (55,) unit, that sequences.pose_vector.canonical_member projects on: the
    first principal direction (about zero) of the poses' flip-odd parts (N, 55 -> at most
    max_rows drawn, seeded), so that the members of a pair differ most along it and few poses
    sit near the boundary where the choice changes (1 in 9 training rows within 5 units).
    Its sign makes the largest component positive."""
    rows = np.asarray(pose, dtype=np.float64)
    if len(rows) > max_rows:
        rows = rows[np.sort(np.random.default_rng(seed).choice(len(rows), max_rows, replace=False))]
    _, _, Vt = np.linalg.svd(flip_odd_part(rows), full_matrices=False)
    u = Vt[0]
    return u if u[np.argmax(np.abs(u))] > 0 else -u


def train_pose_model(dataset: Dataset, X: np.ndarray, codebook: Codebook,
                     settings: DescriptorSettings, options: TrainingOptions, fps: float,
                     log: Callable[[str], None] = print) -> tuple[PoseModel, dict]:
    """Fit the stacked kernel RVM on the data set's descriptors X (N, D) and derive the
    filter's noise models; returns the model and a report of validation figures."""
    val, Xs, centre, Y = _training_arrays(dataset, X, options.transform, options.stack_depth)
    train_rows = np.flatnonzero(~val)
    fit_rows = train_rows[np.linspace(0, len(train_rows) - 1,
                                      min(options.n_fit, len(train_rows))).astype(int)]
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


# ----------------------------------------------------------------------------- mixture of experts
# (issue 9: a mixture of kernel experts on all the training rows; regressor.mixture)


def descriptor_cache_key(config, views: dict | None, noisy: bool) -> str:
    """Cache key of a data set's descriptors: render settings, views per trial, noise."""
    text = json.dumps({"config": config.digest(), "views": views or {}, "noisy": noisy,
                       "noise": repr(MaskNoise()) if noisy else ""}, sort_keys=True)
    return "v2-" + hashlib.sha256(text.encode()).hexdigest()[:12]


@dataclass
class MixtureOptions:
    """Choices of the mixture model (regressor.mixture.MixtureRegressor). stack_depth: k;
    expert: "sparse_rvm" (each expert a sparse RVM over n_centres candidate kernels, fitted on
    all its rows: regressor.sparse_rvm; it gives each frame's predictive variance, which
    calibrate_variance turns into a scale of the filter's R) or "dls" (damped least squares on
    n_centres kernels with ridge lam);
    n_experts, overlap, n_centres, width_scale, lam: the experts; gate_*: the gate;
    partition: what k-means splits into experts: "pose" (partition_space, with heading_scale
    and standardise), "descriptor" (standardised stacked descriptors), "joint" (both) or
    "input" (the regressor's input as it is: with a projection, principal components keep
    their own variances, where standardising would blow up the noisy last ones);
    top_experts: experts evaluated per frame. layout_grid: the layout block (regressor.layout;
    0: shape contexts only, the paper's descriptor); components: principal directions the
    stacked input is projected on (0: none). canonical: fit each pose's canonical member of
    {pose, front/back flip} instead of the pose itself (the tracker's front/back chain then
    picks the member, limbs included): "none"; "limbs", the side of canonical_direction (the
    flip-odd parts' first principal direction: in profile, which leg is forward); "facing",
    the member facing the camera's half (heading cosine >= 0: the choice changes only in
    profile, where the heading itself passes through 90 degrees). limb_head: also fit the
    same experts on each pose's canonical member by that rule (regressor.pose_model.LimbHead;
    the tracker's limb filter takes the member that agrees with its decided heading); "none"
    for no limb head; only for a model whose own targets are not canonical. "facing" was
    chosen on the five validation videos through ``track`` (filtered corr8 02_02 / 08_03 /
    05_02 / 09_04 / 02_05 without 0.489 / 0.646 / 0.014 / 0.309 / 0.328, with 0.613 / 0.702 /
    0.014 / 0.313 / 0.335; 2026-12-01). heading_index_*: the nearest-neighbour heading
    (regressor.heading_index; rows 0: none): that many training rows drawn at random, their
    first dims input components, k neighbours, used where the folded heading is within
    limit_deg of facing the camera or its back (chosen there on the validation videos); it
    needs the projection (components >= heading_index_dims). limb_net_*: with a limb head,
    fit it as an ensemble of that many neural networks (regressor.limb_net; hidden layer
    sizes, L2 alpha) on the training rows (regressor.limb_net.fit_limb_net holds a tenth out
    for early stopping) instead of a second set of expert weights (0: the
    experts' weights). 4 networks (512, 256) were chosen on the five validation videos
    through ``track`` (filtered corr8 mean 0.392 with the experts' limb head; 2 / 3 / 4
    networks 0.418 / 0.423 / 0.430) and the 28 validation renders (0.361 -> 0.427 with 4).
    8 since 2026-12-02 (int8 weights made room in the 10 MB file; regressor.limb_net):
    corr8 of the canonical member on the 6 validation trials' own rows 1 / 2 / 4 / 6 / 8
    networks 0.585 (mean of 8 single seeds) / 0.623 / 0.647 / 0.654 / 0.659; the shipped
    model retrained with 8, through ``track`` on the five validation videos: filtered corr8
    mean 0.450 -> 0.481 (all five higher); on the 28 validation renders 0.554 / 0.575 ->
    0.561 / 0.630 (filtered / smoothed), heading RMS 38.5 / 34.4 -> 36.4 / 28.5 there and
    26.2 -> 36.8 on the videos, where 05_02's whole-track front/back decision went the other
    way (21 -> 74 deg). The joints' R scaled by 0.25 / 0.5 / 1 / 2 with the 8 (28 renders):
    corr8 0.548 / 0.556 / 0.561 / 0.557, so unchanged.
    limb_net_noise, limb_net_epochs: fresh Gaussian noise on the networks' inputs each epoch
    (a fraction of each input's spread) and the most epochs per network (regressor.limb_net
    .fit_limb_net's input_noise and max_iter); noise 0.5 was measured and not adopted (its
    docstring), so 0 and 200.
    limb_net_mirror: fit them on every training row's mirror image too (the masks flipped
    left to right, their poses sequences.pose_vector.image_mirror; train_mixture_model's
    ``mirrored``): the training motions are not left/right symmetric (handedness), and a
    network that has seen both sides follows new trials better. One network (512, 256), the
    canonical member's corr8 on the 6 validation trials' own rows, mean over trials
    (2026-12-02, one-off drivers): without 0.552 / 0.556 (two seeds), with 0.584 / 0.583.
    On by default, so train_mixture_model then needs ``mirrored`` (scripts/train.py makes
    and caches it, noisy_dataset_inputs: the same video-like masks mirrored, described as the
    tracker describes a frame's mirror image); pass limb_net_mirror=False to fit without.
    limb_net_output: what the networks regress, "euler" (the 53 angles about their centres)
    or "rot6d" (each joint's rotation as 6 numbers; regressor.rotation6d, where the model
    retrained with it is measured: no better on validation, so "euler").
    limb_net_reversed: the share of training rows (drawn at random) also given to the
    networks as if their sequence were played backwards (the stacked input [x_t, x_t+1,
    x_t+2], same pose; and their mirror images' likewise with limb_net_mirror): the training
    motions are mostly forwards, and a network that has only seen them reads a backward walk
    worse. One network (512, 256) on stop 37's video-like rows (6 validation trials, limbs at
    the true heading, corr8 forwards / played backwards; 2026-12-04, one-off driver
    /work/tmp/s39/reverse_probe.py): share 0 0.571 / 0.463 and 0.565 / 0.454 (two seeds),
    0.3 0.557 / 0.537, 1.0 0.551 / 0.549. The default recipe (train.py --experts 24
    --centres 400) retrained with 0.3, against the same recipe and caches with 0 (28
    validation renders, limbs at the true heading, corr8 forwards / played backwards; 12
    validation videos through ``track``, corr8 filtered / smoothed): 0.623 / 0.666 against
    0.624 / 0.586, videos 0.415 / 0.474 against 0.406 / 0.469; but the shipped file (an
    earlier build of the recipe with 0) scores 0.446 / 0.475 on those videos and its chain's
    heading is better on the renders (30.3 against 37.8 degrees), and the networks see 1.3
    times the rows (the fit took 2591 s against the rebuild's 1622, partly sharing the cores
    with evaluations), nearer the 60-minute training limit: 0 stays the default
    (docs/accuracy.md, 2026-12-04).
    side_classifier*: with limbs, fit a front/back side classifier (regressor.side_classifier,
    these hidden layer sizes) on the training rows: the tracker's chain then carries the
    limbs' canonical member and its flip (tracker.hypotheses.canonical_hypotheses).

    Chosen on the validation trials (issue 9, one-off drivers on the cached training rows,
    correlation of the 8 most-moving angles over the 6 validation trials; kernel ridge on 2,000
    centres unless said): shape contexts alone 0.394, with the 24 x 24 layout 0.452 (k = 3);
    projected on 200 directions: layout 24 x 24 0.454, 16 x 16 0.456, 12 x 12 0.447; the
    mixture of 24 experts on the 16 x 16 / 200 input 0.461 partitioned as "input", 0.368 as
    "descriptor" (standardised)."""

    stack_depth: int = 3
    transform: str = "sqrt"
    expert: str = "sparse_rvm"
    n_experts: int = 12
    overlap: float = 0.2
    n_centres: int = 400
    width_scale: float = 0.25
    lam: float = 0.01
    gate_centres: int = 300
    gate_width_scale: float = 0.5
    gate_l2: float = 1e-4
    partition: str = "input"
    layout_grid: int = 16
    components: int = 200
    heading_scale: float = 3.0
    standardise: bool = True
    top_experts: int = 2
    ambiguity_threshold: float = 0.5
    canonical: str = "none"
    limb_head: str = "facing"
    heading_index_rows: int = 16000
    heading_index_dims: int = 50
    heading_index_k: int = 20
    heading_index_limit_deg: float = 45.0
    limb_net_members: int = 8
    limb_net_hidden: tuple[int, ...] = (512, 256)
    limb_net_alpha: float = 1e-3
    limb_net_noise: float = 0.0
    limb_net_epochs: int = 200
    limb_net_mirror: bool = True
    limb_net_output: str = "euler"
    limb_net_reversed: float = 0.0
    side_classifier: bool = True
    side_classifier_hidden: tuple[int, ...] = (256, 64)
    seed: int = 0


def partition_space(targets: np.ndarray, heading_scale: float,
                    angle_std: np.ndarray | None = None) -> np.ndarray:
    """The pose embedding the mixture partitions: regression targets (N, 55) with the
    heading's (cos, sin) times heading_scale, angles (degrees about their centres) divided by
    angle_std (53,) (their spread over the training rows; None: by 1, degrees as they are).
    Standardised angles keep the few wide-ranging angles (climbing, dance) from deciding the
    partition alone; the heading weight then sets how much experts split by viewpoint."""
    Z = np.array(targets, dtype=np.float64, copy=True)
    Z[:, :2] *= heading_scale
    if angle_std is not None:
        Z[:, 2:] /= np.maximum(angle_std, 1e-3)
    return Z


def mixture_space(options: MixtureOptions, Xs: np.ndarray, Y: np.ndarray,
                  train_rows: np.ndarray) -> np.ndarray:
    """The rows (N, dZ) k-means partitions into experts (MixtureOptions.partition): pose
    (partition_space), standardised stacked descriptors scaled to the pose block's total
    variance, or both side by side."""
    Z = partition_space(Y, options.heading_scale,
                        Y[train_rows, 2:].std(axis=0) if options.standardise else None)
    if options.partition == "pose":
        return Z
    if options.partition == "input":
        return np.asarray(Xs, dtype=np.float64)
    mean, std = Xs[train_rows].mean(axis=0), Xs[train_rows].std(axis=0) + 1e-9
    S = (Xs - mean) / std * np.sqrt(Z.shape[1] / Xs.shape[1])
    return S if options.partition == "descriptor" else np.hstack([Z, S])


def angle_measures(predicted: np.ndarray, truth: np.ndarray, constant_deg: np.ndarray,
                   n_moving: int = 8) -> dict:
    """err53 (mean |wrapped error| of the 53 joint angles, deg), const (the same for the
    constant pose constant_deg (53,)), skill = 1 - err/const, corr8 (mean correlation with the
    truth of the n_moving angles that move most in the truth)."""
    constant = np.concatenate([[1.0, 0.0], constant_deg])
    err, const = body_angle_error(predicted, truth), constant_error(truth, constant)
    corr = top_angle_correlation(predicted, truth, n_moving)["mean"]
    return {"err53": round(err, 3), "const": round(const, 3), "skill": round(skill(err, const), 3),
            "corr8": round(corr, 3)}


#: train.py's --expert choices and the regressor.mixture expert each names.
EXPERT_CHOICES = {"sparse_rvm": "sparse_rvm", "dls": "ridge"}


def calibrate_variance(predicted: np.ndarray, truth: np.ndarray, R: np.ndarray,
                       variance: np.ndarray) -> tuple[float, dict]:
    """The factor c that makes each frame's R_t = R x c x variance_t (variance (N,): the
    experts' predictive variance, PoseModel.predict_variance) calibrated on held-out rows:
    the mean over rows of z_t^T R_t^-1 z_t / 54 is 1 for the raw residuals z_t (N, 54) deg of
    predicted (N, 55) against truth (N, 55). Also returns the mean z^2 before (R alone, c x
    variance = 1) and of the experts' own variance taken as is (z^2 / variance_t in
    mean-angle-variance units), for the report."""
    z = wrap_deg(pose_angles(predicted) - pose_angles(truth))
    q = np.einsum("ni,ij,nj->n", z, np.linalg.inv(R), z) / z.shape[1]
    v = np.maximum(np.asarray(variance, float), 1e-12)
    c = float(np.mean(q / v))
    return c, {"variance_calibration": c, "z2_fixed_R": float(q.mean()),
               "z2_rvm_variance_raw": float(np.mean((z[:, 1:] ** 2).mean(1) / v))}


def train_mixture_model(dataset: Dataset, X: np.ndarray, codebook: Codebook,
                        settings: DescriptorSettings, options: MixtureOptions, fps: float,
                        log: Callable[[str], None] = print,
                        layouts: np.ndarray | None = None,
                        mirrored: tuple[np.ndarray, np.ndarray | None] | None = None,
                        workers: int = 1) -> tuple[PoseModel, dict]:
    """Fit the mixture of experts on every training row's stacked descriptor (validation
    trials excluded) and derive the filter's noise models on the validation trials; returns
    the model and a report of validation figures. layouts (N, layout_grid^2): the layouts of
    the masks X describes (noisy_dataset_layouts), needed when options.layout_grid > 0.
    mirrored: (histograms (N, D), layouts (N, layout_grid^2) or None) of the same masks
    flipped left to right, needed for limb networks with options.limb_net_mirror. workers:
    experts and limb networks fitted at once (regressor.mixture, regressor.limb_net
    .fit_limb_net; the arrays do not depend on it)."""
    from regressor.mixture import MixtureRegressor
    if options.canonical not in CANONICAL_RULES:
        raise ValueError(f"canonical {options.canonical!r} is not one of {CANONICAL_RULES}")
    if options.limb_head not in CANONICAL_RULES:
        raise ValueError(f"limb_head {options.limb_head!r} is not one of {CANONICAL_RULES}")
    if options.limb_head != "none" and options.canonical != "none":
        raise ValueError("a model fitted on canonical members takes no limb head "
                         "(limb_head must be 'none')")
    grid = int(options.layout_grid)
    fit = ~validation_mask(dataset)
    weight = 0.0
    if grid:
        if layouts is None or np.shape(layouts) != (len(X), grid * grid):
            raise ValueError(f"layout_grid {grid} needs layouts of shape ({len(X)}, {grid * grid})")
        # The layout block scaled to the histogram block's spread, so the kernel weighs both.
        weight = (block_spread(transform_descriptors(X[fit], options.transform))
                  / max(block_spread(layouts[fit]), 1e-12))
    direction = truth = None
    if options.canonical != "none":
        direction, truth = _canonical_targets(options.canonical, dataset.pose, fit,
                                              options.seed, "canonical members", log)
    val, Xs, centre, Y = _training_arrays(dataset, X, options.transform, options.stack_depth,
                                          layouts if grid else None, weight, pose=truth)
    truth = dataset.pose if truth is None else truth
    if not 0 <= options.limb_net_members <= MAX_MEMBERS:
        raise ValueError(f"limb_net_members must be in 0..{MAX_MEMBERS}, got "
                         f"{options.limb_net_members}")
    use_net = options.limb_head != "none" and options.limb_net_members > 0
    mirror = use_net and options.limb_net_mirror
    if mirror and (mirrored is None or np.shape(mirrored[0]) != np.shape(X)
                   or (grid and np.shape(mirrored[1]) != (len(X), grid * grid))):
        raise ValueError("limb networks fitted on mirror images (limb_net_mirror) need the "
                         "mirrored masks' histograms and layouts, shaped as X and layouts")
    if use_net or (options.side_classifier and options.limb_head != "none"):
        require_training_dependencies()
    train_rows, val_rows = np.flatnonzero(~val), np.flatnonzero(val)
    projection_mean = projection = None
    Xin = Xs
    if options.components:
        projection_mean, projection = fit_projection(Xs[train_rows], options.components,
                                                     seed=options.seed)
        Xin = (Xs - projection_mean) @ projection
    Z = mixture_space(options, Xin, Y, train_rows)
    log(f"fitting a mixture of {options.n_experts} experts on all {len(train_rows)} training "
        f"rows (k = {options.stack_depth}, {Xs.shape[1]}-D input"
        f"{f' projected to {Xin.shape[1]}' if projection is not None else ''}) ...")
    start = time.perf_counter()
    if options.expert not in EXPERT_CHOICES:
        raise ValueError(f"expert {options.expert!r} is not one of {EXPERT_CHOICES}")
    if options.expert != "dls" and options.limb_head != "none" and not use_net:
        raise ValueError("a limb head of expert weights (limb_net_members 0) needs dls experts")
    mixture = MixtureRegressor(
        expert=EXPERT_CHOICES[options.expert],
        n_experts=options.n_experts, overlap=options.overlap, n_centres=options.n_centres,
        width_scale=options.width_scale, lam=options.lam, gate_centres=options.gate_centres,
        gate_width_scale=options.gate_width_scale, gate_l2=options.gate_l2,
        top_experts=options.top_experts, seed=options.seed)
    head_direction = head_truth = None
    targets = Y
    if options.limb_head != "none":
        # The same experts (centres depend on the inputs only) with a second set of weights:
        # one fit on both target sets, split afterwards (ridge columns are independent).
        head_direction, head_truth = _canonical_targets(
            options.limb_head, dataset.pose, fit, options.seed,
            f"limb head ({options.limb_head})", log)
        head_centre = angle_centres(head_truth[~val])
        if not use_net:
            targets = np.hstack([Y, regression_targets(head_truth, head_centre)])
    # A sparse RVM's steps factor R x R matrices (R <= n_centres): on the shared 2-core
    # machine one BLAS thread fits an expert about 3x faster than two (docs/rvm_experts.md).
    with threadpool_limits(limits=1 if options.expert == "sparse_rvm" else None,
                           user_api="blas"):
        mixture.fit(Xin[train_rows], targets[train_rows], Z[train_rows], log=log,
                    workers=workers)
    limb_head = limb_net = None
    if use_net:
        log(f"fitting {options.limb_net_members} limb networks "
            f"{'x'.join(map(str, options.limb_net_hidden))} on the {len(train_rows)} training "
            f"rows (a tenth of them held out for early stopping) ...")
        inputs, targets_net = Xin[train_rows], head_truth[train_rows]
        if mirror:
            # Each training row's mirror image: its masks' descriptors, stacked and projected
            # as the row's own, and the canonical member of its mirrored pose by the same rule.
            Xs_m = _stacked_rows(dataset, mirrored[0], options.transform, options.stack_depth,
                                 mirrored[1] if grid else None, weight)[train_rows]
            if projection is not None:
                Xs_m = (Xs_m - projection_mean) @ projection
            inputs = np.vstack([inputs, Xs_m])
            targets_net = np.vstack([targets_net, canonical_member(
                image_mirror(dataset.pose[train_rows]), head_direction)])
            log(f"  and their {len(train_rows)} mirror images")
        if options.limb_net_reversed > 0:
            inputs, targets_net = _with_time_reversed(
                dataset, X, layouts, mirrored, options, weight, train_rows, projection_mean,
                projection, head_direction, inputs, targets_net, mirror, log)
        limb_net = fit_limb_net(inputs, targets_net, head_centre,
                                head_direction, members=options.limb_net_members,
                                hidden=options.limb_net_hidden, alpha=options.limb_net_alpha,
                                seed=options.seed, workers=workers,
                                input_noise=options.limb_net_noise,
                                output=options.limb_net_output,
                                max_iter=options.limb_net_epochs, log=log)
        # As the file will hold it (int8 weights): the report and the front/back priors
        # learned from this model then measure the networks that are shipped. What the
        # int8 weights change is reported (limb_net_int8_max_deg).
        fitted_net, limb_net = limb_net, LimbNet.from_arrays(limb_net.to_arrays())
        int8_max_deg = float(np.abs(wrap_deg(limb_net.predict(Xin[val_rows])[:, 2:]
                                             - fitted_net.predict(Xin[val_rows])[:, 2:])).max())
    elif head_truth is not None:
        coef, intercept = split_expert_outputs(mixture, POSE_DIM)
        limb_head = LimbHead(coef, intercept, head_centre, head_direction)
    side_classifier = None
    train_heading = heading_deg(dataset.pose[train_rows])
    front = facing_camera(train_heading)
    if options.side_classifier and (head_truth is None or front.all() or not front.any()):
        log("no side classifier: it needs a limb head or networks and training poses facing "
            "both halves")
    elif options.side_classifier:
        log(f"fitting the side classifier {'x'.join(map(str, options.side_classifier_hidden))} "
            f"on the {len(train_rows)} training rows ...")
        side_classifier = fit_side_classifier(
            Xin[train_rows], train_heading,
            hidden=options.side_classifier_hidden, seed=options.seed, log=log)
    heading_index = None
    if options.heading_index_rows:
        if projection is None or options.heading_index_dims > Xin.shape[1]:
            raise ValueError(f"a heading index compares the first {options.heading_index_dims} "
                             f"principal components of the input: it needs components >= that "
                             f"(got {options.components}; or no index: heading_index_rows 0)")
        heading_index = build_heading_index(
            Xin[train_rows], train_heading, options.heading_index_rows,
            options.heading_index_dims, options.heading_index_k,
            options.heading_index_limit_deg, seed=options.seed)
    fit_seconds = time.perf_counter() - start
    log(f"  fitted in {fit_seconds:.1f} s")
    model = PoseModel(settings=settings, codebook=codebook, stack_depth=options.stack_depth,
                      transform=options.transform, basis="gaussian", width=None, centres=None,
                      relevance=np.zeros(0, np.int64), coef=np.zeros((0, 55)),
                      intercept=np.zeros(55), angle_centre_deg=centre,
                      measurement_covariance=np.eye(54), process_noise=np.ones(54),
                      mixture=mixture, layout_grid=grid, layout_weight=weight,
                      projection=projection, projection_mean=projection_mean,
                      canonical_direction=direction, limb_head=limb_head,
                      limb_net=limb_net, side_classifier=side_classifier)
    # R from the experts' own heading: its heading entry is mostly front/back confusions,
    # which the tracker's chain, not the filter, handles.
    predicted = model.predict_batch(Xs[val_rows])
    model.heading_index = heading_index          # its neighbours give each frame's novelty
    # A canonical model's error is measured against the canonical members, as its output is
    # the chain's hypothesis, not yet the decision.
    R, facts = measurement_noise(predicted, truth[val_rows], options.ambiguity_threshold)
    model.measurement_covariance = R
    if options.expert == "sparse_rvm":
        variance = model.predict_variance(Xs[val_rows])
        model.variance_calibration, z2 = calibrate_variance(predicted, truth[val_rows], R,
                                                            variance)
        facts.update(z2)
    model.process_noise = process_noise(dataset.pose[~val], dataset.sequence[~val], fps)
    errors = np.abs(wrap_deg(pose_angles(predicted) - pose_angles(truth[val_rows])))
    gate_val = mixture.predict_proba(Xin[val_rows]).argmax(axis=1)
    true_val = np.argmin(((Z[val_rows][:, None] - mixture.partition_centres_[None]) ** 2
                          ).sum(-1), axis=1)
    report = {"n_train_rows": int(len(train_rows)), "n_fit": int(len(train_rows)),
              "n_validation_rows": int(len(val_rows)), "experts": int(len(mixture.experts_)),
              "expert_rows": [int(r) for r in mixture.expert_rows_],
              "fit_seconds": round(fit_seconds, 1),
              "validation_joint_error_deg": round(float(errors[:, 1:].mean()), 2),
              "validation_heading_rms_deg": round(float(np.sqrt((errors[:, 0] ** 2).mean())), 2),
              "validation_gate_accuracy": round(float((gate_val == true_val).mean()), 3),
              "layout_weight": round(weight, 4),
              "validation": angle_measures(predicted, truth[val_rows], centre),
              "canonical": options.canonical, "limb_head": options.limb_head,
              "limb_net_members": options.limb_net_members if use_net else 0,
              **({"limb_net_int8_max_deg": round(int8_max_deg, 3)} if use_net else {}),
              "side_classifier": side_classifier is not None,
              **{k: (round(v, 3) if isinstance(v, float) else v) for k, v in facts.items()}}
    if model.has_limbs:
        # The head's member picked by the true heading: what the tracker gets when its chain
        # decides the heading right (an upper bound, hence the name).
        from tracker.hypotheses import pick_member
        members = pick_member(model.predict_limbs(Xs[val_rows]), heading_deg(truth[val_rows]))
        report["validation_limb_head_at_true_heading"] = angle_measures(members, truth[val_rows],
                                                                        centre)
    return model, report


def _canonical_targets(rule: str, pose: np.ndarray, fit: np.ndarray, seed: int, what: str,
                       log: Callable[[str], None]) -> tuple[np.ndarray, np.ndarray]:
    """(the canonical_member direction (55,) of a CANONICAL_RULES rule, "limbs" (learned on
    the fitted rows ``fit`` (N,) bool) or "facing"; every pose's member (N, 55)), logging how
    many rows the rule flips under the label ``what``."""
    direction = (canonical_direction(pose[fit], seed=seed) if rule == "limbs"
                 else np.eye(POSE_DIM)[0])
    members = canonical_member(pose, direction)
    log(f"{what}: {np.mean(np.any(members != pose, axis=1)):.1%} of rows flipped")
    return direction, members


def _with_time_reversed(dataset: Dataset, X: np.ndarray, layouts, mirrored, options,
                        weight: float, train_rows: np.ndarray, projection_mean, projection,
                        head_direction, inputs: np.ndarray, targets: np.ndarray, mirror: bool,
                        log) -> tuple[np.ndarray, np.ndarray]:
    """The limb networks' rows (inputs) and targets with a share (options.limb_net_reversed,
    drawn with options.seed) of the training rows added as if their sequences were played
    backwards, same targets, and the same rows' mirror images when those are fitted (see
    MixtureOptions)."""
    pick = (np.random.default_rng(options.seed).random(len(train_rows))
            < options.limb_net_reversed)
    rows = train_rows[pick]
    grid = int(options.layout_grid)
    sources = [(X, layouts, dataset.pose[rows])]
    if mirror:
        sources.append((mirrored[0], mirrored[1], image_mirror(dataset.pose[rows])))
    blocks, goals = [inputs], [targets]
    for histograms, grids, pose in sources:
        played_back = _time_reversed_rows(dataset, histograms, options.transform,
                                          options.stack_depth, grids if grid else None,
                                          weight)[rows]
        if projection is not None:
            played_back = (played_back - projection_mean) @ projection
        blocks.append(played_back)
        goals.append(canonical_member(pose, head_direction))
    log(f"  and {len(rows)} of them played backwards"
        f"{' (and their mirror images)' if mirror else ''}")
    return np.vstack(blocks), np.vstack(goals)


def split_expert_outputs(mixture, n_outputs: int) -> tuple[np.ndarray, np.ndarray]:
    """Cut a fitted mixture of DampedKernelRegressor experts back to its first n_outputs
    outputs; returns the rest: (coef (R, K - n_outputs) with the experts' rows concatenated
    in order, intercepts (E, K - n_outputs)). Only for ridge experts: their centres depend on
    the inputs alone, so the cut experts are what fitting the first outputs alone gives."""
    from regressor.mixture import DampedKernelRegressor
    if not all(isinstance(e, DampedKernelRegressor) for e in mixture.experts_):
        raise ValueError("only a mixture of DampedKernelRegressor experts can be split")
    if mixture.n_outputs_ <= n_outputs:
        raise ValueError(f"the mixture has {mixture.n_outputs_} outputs, not more than "
                         f"{n_outputs}")
    coefs, intercepts = [], []
    for expert in mixture.experts_:
        coefs.append(expert.coef_[:, n_outputs:])
        intercepts.append(expert.intercept_[n_outputs:])
        expert.coef_ = np.ascontiguousarray(expert.coef_[:, :n_outputs])
        expert.intercept_ = expert.intercept_[:n_outputs].copy()
    mixture.n_outputs_ = n_outputs
    return np.vstack(coefs), np.vstack(intercepts)
