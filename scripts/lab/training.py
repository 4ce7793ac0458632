"""Training the default model from motion capture: data set -> codebook -> descriptors -> regressor.

The steps that need both ``sequences`` (renders of motion capture, data sets, masks) and the
model: each a function with cached results; the fitting itself, arrays in and parts out, is
regressor.training. scripts/train.py is the command. Not installed: scripts/lab is the
research helpers' package beside the scripts (nothing ``track`` runs imports it).
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

from regressor.angles import POSE_DIM, pose_angles, wrap_deg
from regressor.codebook import Codebook
from regressor.descriptor import (DescriptorSettings, SilhouetteError, descriptor_and_mirror,
                                  descriptor_for_mask)
from regressor.descriptor_batch import descriptors_for_masks
from regressor.layout import silhouette_layout
from regressor.mixture_fit import regression_targets
from regressor.limb_net_training import require_training_dependencies
from regressor.model_writer import settings_arrays
from regressor.optional_parts import LimbHead, predict_batch, predict_limbs, predict_variance
from regressor.pose_model import (DEFAULT_AMBIGUITY_THRESHOLD, PoseModel,
                                  frame_descriptors, transform_descriptors)
from regressor.rvm import RVMRegressor
from regressor.stacking import stack_frames
from regressor.training import (MixtureOptions, angle_centres, block_spread, calibrate_variance,
                                fit_codebook_for_masks,
                                check_mixture_options, fit_experts, fit_heading_index_part,
                                fit_limb_networks, fit_projection, fit_side_classifier_part,
                                measurement_noise, mixture_space, process_noise,
                                split_expert_outputs, uses_limb_nets)
from sequences.dataset import Dataset
from sequences.measures import body_angle_error, constant_error, skill, top_angle_correlation
from sequences.mask_noise import MaskNoise, degrade_all
from sequences.pose_conversions import canonical_member, flip_odd_part
from sequences.pose_vector import heading_deg, image_mirror

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
    from tracker.video.silhouettes import clean_mask, person_masks
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


def layouts_for_masks(masks, grid: int) -> np.ndarray:
    """silhouette_layout of each mask: (N, grid * grid) float64."""
    rows = [silhouette_layout(m, grid) for m in masks]
    return np.array(rows, dtype=np.float64).reshape(len(rows), int(grid) ** 2)


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
    h.update(repr(sorted(settings_arrays(settings).items(), key=lambda kv: kv[0])).encode())
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




def canonical_direction(pose: np.ndarray, max_rows: int = 20000, seed: int = 0) -> np.ndarray:
    """The direction (55,) unit, that sequences.pose_conversions.canonical_member projects on: the
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
    predicted = predict_batch(model, Xs[val_rows])
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
    experts and limb networks fitted at once (the arrays do not depend on it)."""
    check_mixture_options(options)
    rows = _mixture_rows(dataset, X, options, layouts, mirrored, log)
    train_rows, val_rows, Xin = rows["train_rows"], rows["val_rows"], rows["Xin"]
    log(f"fitting a mixture of {options.n_experts} experts on all {len(train_rows)} training "
        f"rows (k = {options.stack_depth}, {rows['Xs'].shape[1]}-D input"
        f"{f' projected to {Xin.shape[1]}' if rows['projection'] is not None else ''}) ...")
    start = time.perf_counter()
    head_direction = head_truth = head_centre = None
    targets = rows["Y"]
    if options.limb_head != "none":
        head_direction, head_truth = _canonical_targets(
            options.limb_head, dataset.pose, ~rows["val"], options.seed,
            f"limb head ({options.limb_head})", log)
        head_centre = angle_centres(head_truth[~rows["val"]])
        if not uses_limb_nets(options):
            # The same experts (centres depend on the inputs only) with a second set of
            # weights: one fit on both target sets, split afterwards.
            targets = np.hstack([targets, regression_targets(head_truth, head_centre)])
    mixture = fit_experts(options, Xin[train_rows], targets[train_rows], rows["Z"][train_rows],
                          log, workers)
    parts = {"limb_head": None, "limb_net": None, "int8_max_deg": None}
    if uses_limb_nets(options):
        inputs, members = _limb_net_rows(dataset, X, layouts, mirrored, options, rows,
                                         head_truth, head_direction, log)
        parts["limb_net"], parts["int8_max_deg"] = fit_limb_networks(
            options, inputs, members, head_centre, head_direction, Xin[val_rows], log, workers)
    elif head_truth is not None:
        coef, intercept = split_expert_outputs(mixture, POSE_DIM)
        parts["limb_head"] = LimbHead(coef, intercept, head_centre, head_direction)
    train_heading = heading_deg(dataset.pose[train_rows])
    parts["side_classifier"] = fit_side_classifier_part(options, Xin[train_rows], train_heading,
                                                        head_truth is not None, log)
    parts["heading_index"] = fit_heading_index_part(options, Xin[train_rows], train_heading,
                                                    rows["projection"] is not None)
    fit_seconds = time.perf_counter() - start
    log(f"  fitted in {fit_seconds:.1f} s")
    return _validated_model(dataset, codebook, settings, options, fps, rows, mixture, parts,
                            fit_seconds)


def _mixture_rows(dataset: Dataset, X: np.ndarray, options: MixtureOptions, layouts,
                  mirrored, log: Callable[[str], None]) -> dict:
    """What train_mixture_model fits on, as a dict: val (N,) bool validation rows, train_rows
    and val_rows (indices), Xs (N, k*D) stacked descriptors, Xin (N, P) the regressor's input
    (projected when options.components), projection and projection_mean (or None), Z the
    partition space, Y (N, 55) targets about centre (53,) deg, truth (N, 55) the poses the
    targets come from, direction the canonical direction (or None), weight the layout block's."""
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
    mirror = uses_limb_nets(options) and options.limb_net_mirror
    if mirror and (mirrored is None or np.shape(mirrored[0]) != np.shape(X)
                   or (grid and np.shape(mirrored[1]) != (len(X), grid * grid))):
        raise ValueError("limb networks fitted on mirror images (limb_net_mirror) need the "
                         "mirrored masks' histograms and layouts, shaped as X and layouts")
    if uses_limb_nets(options) or (options.side_classifier and options.limb_head != "none"):
        require_training_dependencies()
    train_rows, val_rows = np.flatnonzero(~val), np.flatnonzero(val)
    projection_mean = projection = None
    Xin = Xs
    if options.components:
        projection_mean, projection = fit_projection(Xs[train_rows], options.components,
                                                     seed=options.seed)
        Xin = (Xs - projection_mean) @ projection
    return {"val": val, "train_rows": train_rows, "val_rows": val_rows, "Xs": Xs, "Xin": Xin,
            "projection": projection, "projection_mean": projection_mean, "weight": weight,
            "Z": mixture_space(options, Xin, Y, train_rows), "Y": Y, "centre": centre,
            "truth": truth, "direction": direction, "mirror": mirror}


def _limb_net_rows(dataset: Dataset, X: np.ndarray, layouts, mirrored, options: MixtureOptions,
                   rows: dict, head_truth: np.ndarray, head_direction: np.ndarray,
                   log: Callable[[str], None]) -> tuple[np.ndarray, np.ndarray]:
    """The limb networks' inputs (M, P) and canonical members (M, 55): the training rows, with
    their mirror images (options.limb_net_mirror) and a share played backwards
    (options.limb_net_reversed)."""
    train_rows, projection = rows["train_rows"], rows["projection"]
    log(f"fitting {options.limb_net_members} limb networks "
        f"{'x'.join(map(str, options.limb_net_hidden))} on the {len(train_rows)} training "
        f"rows (a tenth of them held out for early stopping) ...")
    inputs, members = rows["Xin"][train_rows], head_truth[train_rows]
    if rows["mirror"]:
        # Each training row's mirror image: its masks' descriptors, stacked and projected
        # as the row's own, and the canonical member of its mirrored pose by the same rule.
        Xs_m = _stacked_rows(dataset, mirrored[0], options.transform, options.stack_depth,
                             mirrored[1] if options.layout_grid else None,
                             rows["weight"])[train_rows]
        if projection is not None:
            Xs_m = (Xs_m - rows["projection_mean"]) @ projection
        inputs = np.vstack([inputs, Xs_m])
        members = np.vstack([members, canonical_member(
            image_mirror(dataset.pose[train_rows]), head_direction)])
        log(f"  and their {len(train_rows)} mirror images")
    if options.limb_net_reversed > 0:
        inputs, members = _with_time_reversed(
            dataset, X, layouts, mirrored, options, rows["weight"], train_rows,
            rows["projection_mean"], projection, head_direction, inputs, members,
            rows["mirror"], log)
    return inputs, members


def _validated_model(dataset: Dataset, codebook: Codebook, settings: DescriptorSettings,
                     options: MixtureOptions, fps: float, rows: dict, mixture, parts: dict,
                     fit_seconds: float) -> tuple[PoseModel, dict]:
    """The PoseModel of the fitted parts with its filter noise models from the validation
    rows (R from the experts' own heading, the variance calibration of sparse RVM experts,
    process noise from the training poses), and the report of validation figures."""
    val, val_rows, Xs = rows["val"], rows["val_rows"], rows["Xs"]
    truth, centre = rows["truth"], rows["centre"]
    model = PoseModel(settings=settings, codebook=codebook, stack_depth=options.stack_depth,
                      transform=options.transform, basis="gaussian", width=None, centres=None,
                      relevance=np.zeros(0, np.int64), coef=np.zeros((0, 55)),
                      intercept=np.zeros(55), angle_centre_deg=centre,
                      measurement_covariance=np.eye(54), process_noise=np.ones(54),
                      mixture=mixture, layout_grid=int(options.layout_grid),
                      layout_weight=rows["weight"], projection=rows["projection"],
                      projection_mean=rows["projection_mean"],
                      canonical_direction=rows["direction"], limb_head=parts["limb_head"],
                      limb_net=parts["limb_net"], side_classifier=parts["side_classifier"])
    # R from the experts' own heading: its heading entry is mostly front/back confusions,
    # which the tracker's chain, not the filter, handles.
    predicted = predict_batch(model, Xs[val_rows])
    model.heading_index = parts["heading_index"]     # its neighbours give each frame's novelty
    # A canonical model's error is measured against the canonical members, as its output is
    # the chain's hypothesis, not yet the decision.
    R, facts = measurement_noise(predicted, truth[val_rows], options.ambiguity_threshold)
    model.measurement_covariance = R
    if options.expert == "sparse_rvm":
        variance = predict_variance(model, Xs[val_rows])
        model.variance_calibration, z2 = calibrate_variance(predicted, truth[val_rows], R,
                                                            variance)
        facts.update(z2)
    model.process_noise = process_noise(dataset.pose[~val], dataset.sequence[~val], fps)
    report = _mixture_report(model, options, rows, mixture, parts, predicted, facts,
                             fit_seconds)
    return model, report


def _mixture_report(model: PoseModel, options: MixtureOptions, rows: dict, mixture,
                    parts: dict, predicted: np.ndarray, facts: dict, fit_seconds: float) -> dict:
    """train_mixture_model's report: sizes, validation errors (joints, heading, gate), the
    options that shape the model and the noise models' facts."""
    train_rows, val_rows, truth = rows["train_rows"], rows["val_rows"], rows["truth"]
    errors = np.abs(wrap_deg(pose_angles(predicted) - pose_angles(truth[val_rows])))
    gate_val = mixture.predict_proba(rows["Xin"][val_rows]).argmax(axis=1)
    true_val = np.argmin(((rows["Z"][val_rows][:, None] - mixture.partition_centres_[None]) ** 2
                          ).sum(-1), axis=1)
    use_net = parts["limb_net"] is not None
    report = {"n_train_rows": int(len(train_rows)), "n_fit": int(len(train_rows)),
              "n_validation_rows": int(len(val_rows)), "experts": int(len(mixture.experts_)),
              "expert_rows": [int(r) for r in mixture.expert_rows_],
              "fit_seconds": round(fit_seconds, 1),
              "validation_joint_error_deg": round(float(errors[:, 1:].mean()), 2),
              "validation_heading_rms_deg": round(float(np.sqrt((errors[:, 0] ** 2).mean())), 2),
              "validation_gate_accuracy": round(float((gate_val == true_val).mean()), 3),
              "layout_weight": round(rows["weight"], 4),
              "validation": angle_measures(predicted, truth[val_rows], rows["centre"]),
              "canonical": options.canonical, "limb_head": options.limb_head,
              "limb_net_members": options.limb_net_members if use_net else 0,
              **({"limb_net_int8_max_deg": round(parts["int8_max_deg"], 3)} if use_net else {}),
              "side_classifier": parts["side_classifier"] is not None,
              **{k: (round(v, 3) if isinstance(v, float) else v) for k, v in facts.items()}}
    if model.has_limbs:
        # The head's member picked by the true heading: what the tracker gets when its chain
        # decides the heading right (an upper bound, hence the name).
        from tracker.tracks.hypotheses import pick_member
        members = pick_member(predict_limbs(model, rows["Xs"][val_rows]),
                              heading_deg(truth[val_rows]))
        report["validation_limb_head_at_true_heading"] = angle_measures(
            members, truth[val_rows], rows["centre"])
    return report


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


