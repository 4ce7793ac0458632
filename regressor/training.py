"""Fitting the model's parts from arrays: stacked inputs (N, D) and targets in, fitted parts out.

The experts and their gate, the limb networks, the side classifier and heading index, and the
filter's noise models (measurement and process noise, the experts' variance calibration).
scripts/lab/training.py prepares the arrays from rendered motion capture (data sets, masks,
validation trials) and calls these: regressor imports neither tracker nor sequences, so what
needs the body's geometry (canonical members, mirror images, headings) is computed there.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterable

import numpy as np
from threadpoolctl import threadpool_limits

from .angles import pose_angles, wrap_deg
from .basis import squared_distances
from .codebook import Codebook, CodebookError
from .descriptor import DescriptorSettings
from .descriptor_batch import contexts_for_masks
from .heading_index_training import build_heading_index
from .limb_net import MAX_MEMBERS, LimbNet
from .limb_net_training import fit_limb_net
from .model_writer import limb_net_arrays
from .side_classifier_training import facing_camera, fit_side_classifier


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


#: MixtureOptions.canonical's choices.
CANONICAL_RULES = ("none", "limbs", "facing")


@dataclass
class MixtureOptions:
    """Choices of the mixture model (regressor.mixture.MixtureRegressor).

    stack_depth: frames stacked (k); transform: descriptor transform. expert: "sparse_rvm"
    (each expert a sparse RVM over n_centres candidate kernels, fitted on all its rows; its
    predictive variance, calibrated by calibrate_variance, scales the filter's R per frame) or
    "dls" (damped least squares on n_centres kernels, ridge lam). n_experts, overlap,
    width_scale: the experts; gate_*: the gate; top_experts: experts evaluated per frame.
    partition: what k-means splits into experts: "pose" (partition_space, with heading_scale
    and standardise), "descriptor" (standardised stacked descriptors), "joint" (both) or
    "input" (the regressor's input as it is). layout_grid: the layout block (regressor.layout;
    0: shape contexts only); components: principal directions the stacked input is projected
    on (0: none). canonical: fit each pose's canonical member of {pose, front/back flip}
    instead of the pose ("none", "limbs": the side of the flip-odd parts' first principal
    direction, "facing": the member facing the camera's half). limb_head: also fit each pose's
    canonical member by that rule ("none" for no limb head; only for a model whose own targets
    are not canonical). heading_index_*: the nearest-neighbour heading (regressor.heading_index;
    rows 0: none; needs components >= heading_index_dims). limb_net_*: with a limb head, an
    ensemble of that many networks (regressor.limb_net; hidden sizes, L2 alpha, input noise,
    most epochs) instead of a second set of expert weights (0: the experts' weights);
    limb_net_mirror: fitted on every training row's mirror image too; limb_net_output:
    "euler" or "rot6d"; limb_net_reversed: the share of training rows also given as if played
    backwards. side_classifier*: with limbs, a front/back side classifier
    (regressor.side_classifier, these hidden sizes). How each default was chosen:
    docs/tuning.md, "regressor/training.py: MixtureOptions"."""

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


def split_expert_outputs(mixture, n_outputs: int) -> tuple[np.ndarray, np.ndarray]:
    """Cut a fitted mixture of DampedKernelRegressor experts back to its first n_outputs
    outputs; returns the rest: (coef (R, K - n_outputs) with the experts' rows concatenated
    in order, intercepts (E, K - n_outputs)). Only for ridge experts: their centres depend on
    the inputs alone, so the cut experts are what fitting the first outputs alone gives."""
    from .mixture import DampedKernelRegressor
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


def check_mixture_options(options: MixtureOptions) -> None:
    """ValueError naming the first inconsistent choice of options (before any fitting)."""
    for name in ("canonical", "limb_head"):
        if getattr(options, name) not in CANONICAL_RULES:
            raise ValueError(f"{name} {getattr(options, name)!r} is not one of {CANONICAL_RULES}")
    if options.limb_head != "none" and options.canonical != "none":
        raise ValueError("a model fitted on canonical members takes no limb head "
                         "(limb_head must be 'none')")
    if not 0 <= options.limb_net_members <= MAX_MEMBERS:
        raise ValueError(f"limb_net_members must be in 0..{MAX_MEMBERS}, got "
                         f"{options.limb_net_members}")


def uses_limb_nets(options: MixtureOptions) -> bool:
    """Whether the limbs come from networks (a limb head with limb_net_members > 0)."""
    return options.limb_head != "none" and options.limb_net_members > 0


def fit_experts(options: MixtureOptions, X: np.ndarray, Y: np.ndarray, Z: np.ndarray,
                log: Callable[[str], None] = print, workers: int = 1):
    """The mixture of experts (regressor.mixture.MixtureRegressor) fitted on inputs X (N, D),
    targets Y (N, K) and the partition space Z (N, dZ) (mixture_space)."""
    from .mixture import MixtureRegressor
    if options.expert not in EXPERT_CHOICES:
        raise ValueError(f"expert {options.expert!r} is not one of {EXPERT_CHOICES}")
    if options.expert != "dls" and options.limb_head != "none" and not uses_limb_nets(options):
        raise ValueError("a limb head of expert weights (limb_net_members 0) needs dls experts")
    mixture = MixtureRegressor(
        expert=EXPERT_CHOICES[options.expert],
        n_experts=options.n_experts, overlap=options.overlap, n_centres=options.n_centres,
        width_scale=options.width_scale, lam=options.lam, gate_centres=options.gate_centres,
        gate_width_scale=options.gate_width_scale, gate_l2=options.gate_l2,
        top_experts=options.top_experts, seed=options.seed)
    # A sparse RVM's steps factor R x R matrices (R <= n_centres): on the shared 2-core
    # machine one BLAS thread fits an expert about 3x faster than two (docs/rvm_experts.md).
    with threadpool_limits(limits=1 if options.expert == "sparse_rvm" else None,
                           user_api="blas"):
        mixture.fit(X, Y, Z, log=log, workers=workers)
    return mixture


def fit_limb_networks(options: MixtureOptions, X: np.ndarray, members: np.ndarray,
                      centre: np.ndarray, direction: np.ndarray, X_check: np.ndarray,
                      log: Callable[[str], None] = print, workers: int = 1
                      ) -> tuple[LimbNet, float]:
    """The limb networks fitted on inputs X (N, D) and canonical members (N, 55) about the
    angle centre (53,) deg, as the model file holds them (int8 weights), and the largest
    change (deg) the int8 weights make on the rows X_check (M, D)."""
    fitted = fit_limb_net(X, members, centre, direction, members=options.limb_net_members,
                          hidden=options.limb_net_hidden, alpha=options.limb_net_alpha,
                          seed=options.seed, workers=workers, input_noise=options.limb_net_noise,
                          output=options.limb_net_output, max_iter=options.limb_net_epochs,
                          log=log)
    # As the file will hold it: the report and the front/back priors learned from this model
    # then measure the networks that are shipped.
    shipped = LimbNet.from_arrays(limb_net_arrays(fitted))
    change = np.abs(wrap_deg(shipped.predict(X_check)[:, 2:] - fitted.predict(X_check)[:, 2:]))
    return shipped, float(change.max())


def fit_side_classifier_part(options: MixtureOptions, X: np.ndarray, heading: np.ndarray,
                             has_limbs: bool, log: Callable[[str], None] = print):
    """The front/back side classifier on inputs X (N, D) and true headings (N,) deg, or None
    when options turn it off, the model has no limbs or the poses face only one half."""
    if not options.side_classifier:
        return None
    front = facing_camera(heading)
    if not has_limbs or front.all() or not front.any():
        log("no side classifier: it needs a limb head or networks and training poses facing "
            "both halves")
        return None
    log(f"fitting the side classifier {'x'.join(map(str, options.side_classifier_hidden))} "
        f"on the {len(X)} training rows ...")
    return fit_side_classifier(X, heading, hidden=options.side_classifier_hidden,
                               seed=options.seed, log=log)


def fit_heading_index_part(options: MixtureOptions, X: np.ndarray, heading: np.ndarray,
                           projected: bool):
    """The nearest-neighbour heading index on projected inputs X (N, P) and headings (N,) deg,
    or None when options.heading_index_rows is 0."""
    if not options.heading_index_rows:
        return None
    if not projected or options.heading_index_dims > X.shape[1]:
        raise ValueError(f"a heading index compares the first {options.heading_index_dims} "
                         f"principal components of the input: it needs components >= that "
                         f"(got {options.components}; or no index: heading_index_rows 0)")
    return build_heading_index(X, heading, options.heading_index_rows,
                               options.heading_index_dims, options.heading_index_k,
                               options.heading_index_limit_deg, seed=options.seed)


# ----------------------------------------------------------------------------- the codebook


def _kmeans_plus_plus(x: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """k-means++ seeding: k rows of x (k, D), each drawn with probability ~ squared distance to
    the nearest centre drawn so far."""
    n = len(x)
    chosen = np.empty(k, dtype=np.int64)
    chosen[0] = rng.integers(n)
    nearest = squared_distances(x, x[chosen[:1]])[:, 0]
    for j in range(1, k):  # k steps, each vectorized over all points
        total = nearest.sum()
        chosen[j] = rng.choice(n, p=nearest / total) if total > 0 else rng.integers(n)
        nearest = np.minimum(nearest, squared_distances(x, x[chosen[j : j + 1]])[:, 0])
    return x[chosen].copy()


def kmeans(x: np.ndarray, k: int, seed: int, max_iter: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """Seeded k-means (k-means++ then Lloyd) on rows of x.

    x: (N, D) float, N >= k. seed: integer seed of numpy's default Generator.
    Returns (centres (k, D) float64, labels (N,) int64). An empty cluster is re-seeded with the
    point farthest from its centre, so all k centres are distinct data-supported points/means.
    Stops when no label changes, or after max_iter iterations.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2 or len(x) < k or k < 1:
        raise CodebookError(f"k-means needs (N, D) data with N >= k = {k}, got shape {x.shape}")
    rng = np.random.default_rng(seed)
    centres = _kmeans_plus_plus(x, k, rng)
    labels = np.full(len(x), -1, dtype=np.int64)
    for _ in range(max_iter):
        d2 = squared_distances(x, centres)
        new_labels = d2.argmin(axis=1)
        if np.array_equal(new_labels, labels):
            break
        labels = new_labels
        counts = np.bincount(labels, minlength=k)
        dims = x.shape[1]
        flat = (labels[:, None] * dims + np.arange(dims)).ravel()
        sums = np.bincount(flat, weights=x.ravel(), minlength=k * dims).reshape(k, dims)
        empty = np.flatnonzero(counts == 0)
        centres = sums / np.maximum(counts, 1)[:, None]
        if len(empty):
            far = np.argsort(-d2[np.arange(len(x)), labels], kind="stable")[: len(empty)]
            centres[empty] = x[far]
    return centres, labels


def fit_codebook(
    contexts: np.ndarray,
    n_centres: int = 100,
    seed: int = 0,
    max_samples: int = 20000,
    max_iter: int = 100,
) -> Codebook:
    """Fit a codebook to shape contexts pooled from many silhouettes.

    contexts: (M, D) float, one context per row (each row sums to 1).
    n_centres: K. seed: integer seed (subsampling and k-means++). max_samples: at most this many
        rows (drawn without replacement) are clustered, for speed.
    sigma is set to the root-mean-square distance from the clustered rows to their nearest centre,
    so votes fall off on the scale at which contexts actually scatter around the centres.
    Returns a Codebook with centres (K, D).
    """
    contexts = np.asarray(contexts, dtype=np.float64)
    if contexts.ndim != 2 or not np.all(np.isfinite(contexts)):
        raise CodebookError(f"contexts must be a finite (M, D) array, got shape {contexts.shape}")
    if len(contexts) < n_centres:
        raise CodebookError(f"need at least n_centres = {n_centres} contexts to fit a codebook, got {len(contexts)}")
    rng = np.random.default_rng(seed)
    if len(contexts) > max_samples:
        contexts = contexts[np.sort(rng.choice(len(contexts), size=max_samples, replace=False))]
    centres, labels = kmeans(contexts, n_centres, seed=int(rng.integers(2**31)), max_iter=max_iter)
    residual = ((contexts - centres[labels]) ** 2).sum(axis=1)
    sigma = float(np.sqrt(residual.mean()))
    if not sigma > 0:
        raise CodebookError("all contexts coincide with a centre; give more varied contexts or fewer centres")
    return Codebook(centres, sigma)


def fit_codebook_for_masks(
    masks: Iterable[np.ndarray],
    settings: DescriptorSettings,
    n_centres: int = 100,
    seed: int = 0,
    per_mask: int | None = 50,
    max_samples: int = 20000,
    progress: Callable[[int], None] | None = None,
) -> Codebook:
    """Fit a codebook (K = n_centres) on contexts pooled from training silhouettes.

    per_mask contexts are kept per silhouette and at most max_samples are clustered; the same
    masks, settings and seed give identical centres. Returns a Codebook with centres
    (n_centres, settings.context_size).
    """
    contexts = contexts_for_masks(masks, settings, per_mask=per_mask, seed=seed, progress=progress)
    return fit_codebook(contexts, n_centres=n_centres, seed=seed, max_samples=max_samples)
