"""A trained pose model: silhouette -> descriptor -> stacked descriptors -> 55-D pose.

One object and one file hold what the tracker needs from training (PoseModel's fields). A
frame's descriptor (D values): the transformed histogram of shape contexts, then, when
layout_grid > 0, the silhouette's layout (regressor.layout) times layout_weight (which balances
the two blocks' spreads). k frames are stacked (k*D) and, with a projection, centred and
projected onto P principal directions. Poses: regressor/angles.py.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .angles import N_ANGLES, POSE_DIM, wrap_deg
from .codebook import Codebook, CodebookError
from .descriptor import (DescriptorSettings, DescriptorSettingsError, descriptor_and_mirror,
                         descriptor_for_mask)
from .layout import MAX_GRID, silhouette_layout
from .mixture import DampedKernelRegressor, MixtureRegressor, SoftmaxGate
from .model_file import ModelFileError, load_model
from .errors import SilhouettePoseError
from .estimator import PoseEstimates
from .heading_index import HeadingIndex
from .limb_net import LimbNet
from .canonical_priors import CanonicalPriors
from .side_classifier import SideClassifier

if TYPE_CHECKING:
    from .optional_parts import LimbHead

DEFAULT_MODEL_PATH = Path(__file__).resolve().parent / "models" / "default_model.npz"
TRANSFORMS = ("none", "sqrt")      # sqrt: Hellinger-like, tames the dominant histogram bins
MODEL_KIND = "silhouette-pose"
#: Ambiguity threshold of model files that do not store theirs (all older files used it).
DEFAULT_AMBIGUITY_THRESHOLD = 0.5
#: Training frame rate when a model's description does not say (DatasetConfig.fps).
DEFAULT_TRAINING_FPS = 30.0
#: A model's described training rate must lie in this range (frames/s).
MIN_TRAINING_FPS, MAX_TRAINING_FPS = 1.0, 1000.0
MIXTURE_KIND = "silhouette-pose-mixture"    # its parts: docs/code_notes/model.md


class PoseModelError(SilhouettePoseError, ValueError):
    """A model file that is missing, unreadable, tampered with or inconsistent."""


#: Novelty above which a frame is unlike the training silhouettes (about 1 % of training rows
#: are; docs/accuracy.md). ``track`` counts such frames (the JSON's "unfamiliar_frames").
UNFAMILIAR_NOVELTY = 1.0


@dataclass
class PoseModel:
    """A trained model (module docstring); D = descriptor_length, k = stack_depth, R basis
    functions, P = input_length. centres (R, P) Gaussian kernel centres or None (linear basis:
    relevance (R,) kept inputs); coef (R, 55); intercept (55,); angle_centre_deg (53,): the
    regressor predicts wrap(angle - centre), so angles near +-180 stay continuous; layout_grid
    0: no layout block; projection (k*D, P), projection_mean (k*D,) or None (P = k*D). A
    mixture's optional parts: limb_head or limb_net (canonical limbs), heading_index (novelty),
    side_classifier (needs limbs), canonical_priors; variance_calibration: factor on
    regressor.optional_parts.predict_variance, or None. The other fields, and all the tracker
    calls: regressor.estimator.PoseEstimator.
    """

    settings: DescriptorSettings
    codebook: Codebook
    stack_depth: int
    transform: str
    basis: str
    width: float | None
    centres: np.ndarray | None
    relevance: np.ndarray
    coef: np.ndarray
    intercept: np.ndarray
    angle_centre_deg: np.ndarray
    measurement_covariance: np.ndarray
    process_noise: np.ndarray
    ambiguity_threshold: float = DEFAULT_AMBIGUITY_THRESHOLD
    description: dict = field(default_factory=dict)
    mixture: MixtureRegressor | None = None     # when set, it regresses instead of coef
    layout_grid: int = 0
    layout_weight: float = 0.0
    projection: np.ndarray | None = None
    projection_mean: np.ndarray | None = None
    canonical_direction: np.ndarray | None = None
    limb_head: LimbHead | None = None
    heading_index: HeadingIndex | None = None
    limb_net: LimbNet | None = None
    side_classifier: SideClassifier | None = None
    canonical_priors: CanonicalPriors | None = None
    variance_calibration: float | None = None

    @property
    def descriptor_length(self) -> int:
        """D, the length of one frame's descriptor."""
        return self.codebook.n_centres + self.layout_grid ** 2

    @property
    def input_length(self) -> int:
        """What the regressor sees per row: P with a projection, else k*D."""
        if self.projection is not None:
            return int(self.projection.shape[1])
        return self.stack_depth * self.descriptor_length

    def describe(self, mask: np.ndarray) -> np.ndarray:
        """Descriptor (D,) of a silhouette mask (H, W) bool (PoseEstimator.describe)."""
        histogram = descriptor_for_mask(mask, self.settings, self.codebook)
        return self._descriptors(histogram[None], [mask])[0]

    def _descriptors(self, histograms: np.ndarray, masks) -> np.ndarray:
        """Descriptors (n, D) of n masks (H, W) from their shape-context histograms (n, K)."""
        layouts = (np.array([silhouette_layout(m, self.layout_grid) for m in masks])
                   if self.layout_grid else None)
        return frame_descriptors(histograms, self.transform, layouts, self.layout_weight)

    def describe_with_mirror(self, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(describe(mask), the descriptor of the mask flipped left to right), (D,) each, the edge
        sampled once (regressor.descriptor.descriptor_and_mirror). Raises as describe."""
        flipped = np.asarray(mask)[:, ::-1]
        histograms = np.array(descriptor_and_mirror(mask, self.settings, self.codebook))
        own, mirror = self._descriptors(histograms, (mask, flipped))
        return own, mirror

    @property
    def training_fps(self) -> float:
        """Frame rate (frames/s) the stacked input was learned at: the description's data set
        fps, else DEFAULT_TRAINING_FPS (regressor.stacking.stack_step)."""
        dataset = (self.description.get("dataset") if isinstance(self.description, dict)
                   else None)
        fps = dataset.get("fps") if isinstance(dataset, dict) else None
        return (float(fps) if isinstance(fps, (int, float)) and np.isfinite(fps) and fps > 0
                else DEFAULT_TRAINING_FPS)

    @property
    def limbs_see_mirror(self) -> bool:
        """Whether the limb networks were fitted on mirror images too (the description's
        limb_net_mirror option): the tracker then uses the mirror images' limbs as well."""
        options = (self.description.get("options") if isinstance(self.description, dict)
                   else None)
        return (self.limb_net is not None and isinstance(options, dict)
                and options.get("limb_net_mirror") is True)

    def _stacked(self, stacked) -> np.ndarray:
        """stacked (N, k*D) as the regressor's float input (N, input_length), projected when
        the model has a projection; PoseModelError naming the expected shape."""
        X = np.asarray(stacked, dtype=np.float64)
        if X.ndim != 2 or X.shape[1] != self.stack_depth * self.descriptor_length:
            raise PoseModelError(f"stacked descriptors must be (N, {self.stack_depth} x "
                                 f"{self.descriptor_length}), got {X.shape}")
        if self.projection is not None:
            X = (X - self.projection_mean) @ self.projection
        return X

    def hypotheses(self, stacked: np.ndarray, m: int = 1, mirrored: np.ndarray | None = None,
                   novelty: bool = True) -> PoseEstimates:
        """PoseEstimator.hypotheses for stacked descriptors (N, k*D), the input projected and the
        gate evaluated once; novelty: the heading index's (NaN without one)."""
        X = self._stacked(stacked)
        rows = (self.heading_index.novelty(X) if novelty and self.heading_index is not None
                else np.full(len(X), np.nan))
        if self.mixture is None:
            from .optional_parts import regress
            return PoseEstimates(regress(self, X)[:, None], np.ones((len(X), 1)), novelty=rows)
        gate = self.mixture.predict_proba(X)
        poses, prob = self.mixture.predict_hypotheses(X, m, proba=gate)
        poses[..., 2:] = wrap_deg(poses[..., 2:] + self.angle_centre_deg)
        limbs, mirror_limbs = self._limbs_of(X, gate, mirrored)
        front = (self.side_classifier.front_probability(X) if self.gives_canonical_pairs
                 else None)
        return PoseEstimates(poses, prob, limbs, mirror_limbs, front, rows)

    def _limbs_of(self, X: np.ndarray, gate: np.ndarray, mirrored: np.ndarray | None
                  ) -> tuple[np.ndarray | None, np.ndarray | None]:
        """(limbs (N, 55), the mirror images' limbs (N, 55) or None), or (None, None) without
        limbs; X (N, input_length), gate (N, E), mirrored (N, k*D) or None."""
        if not self.has_limbs:
            return None, None
        if mirrored is None:
            return self._limbs(X, gate), None
        X_mirror = self._stacked(mirrored)
        if X_mirror.shape != X.shape:
            raise PoseModelError(f"the mirror images' stacked descriptors must be shaped as "
                                 f"the frames' {X.shape}, got {X_mirror.shape}")
        both = self._limbs(np.vstack([X, X_mirror]))
        return both[:len(X)], both[len(X):]

    @property
    def has_limbs(self) -> bool:
        """Whether the model gives canonical limbs (a limb network or a mixture's limb head)."""
        return self.limb_net is not None or (self.limb_head is not None
                                             and self.mixture is not None)

    @property
    def gives_canonical_pairs(self) -> bool:
        """Whether the tracker's front/back chain carries the canonical limbs and their flips
        (a mixture with limbs and a side classifier; tracker.tracks.hypotheses)."""
        return (self.side_classifier is not None and self.mixture is not None
                and self.has_limbs)

    def _limbs(self, X: np.ndarray, gate: np.ndarray | None = None) -> np.ndarray:
        """Canonical poses (N, 55) of the limbs from X (N, input_length): the limb network's,
        else the limb head's by each row's most probable expert (gate (N, E) or None)."""
        if self.limb_net is not None:
            return self.limb_net.predict(X)
        from .optional_parts import limb_head_poses
        return limb_head_poses(self, X, gate)

    def summary(self) -> dict:
        """Plain facts for metadata and logs."""
        if self.mixture is not None:
            experts = self.mixture.experts_
            kind = {"basis": "mixture", "experts": len(experts),
                    "n_basis": int(sum(len(e.centres_) for e in experts))}
        else:
            kind = {"basis": self.basis, "n_basis": int(len(self.coef))}
        return {**kind, "stack_depth": self.stack_depth, "transform": self.transform,
                "training": self.description}


def transform_descriptors(X: np.ndarray, transform: str) -> np.ndarray:
    """Descriptors (..., D) -> transformed for regression ("none" or "sqrt")."""
    if transform == "sqrt":
        return np.sqrt(np.maximum(X, 0.0))
    return np.asarray(X, dtype=np.float64)


def frame_descriptors(histograms: np.ndarray, transform: str, layouts: np.ndarray | None = None,
                      layout_weight: float = 0.0) -> np.ndarray:
    """Per-frame descriptors (N, D) as PoseModel.describe makes them: shape-context histograms
    (N, D_h) transformed, then layouts (N, G^2) times layout_weight (None: histograms only)."""
    H = transform_descriptors(histograms, transform)
    if layouts is None:
        return H
    return np.hstack([H, float(layout_weight) * np.asarray(layouts, dtype=np.float64)])


def _input_from_arrays(a) -> dict:
    """PoseModel keyword arguments for the input parts of a file (absent: none)."""
    grid = int(a["layout_grid"]) if "layout_grid" in a else 0
    out = {"layout_grid": grid,
           "layout_weight": float(a["layout_weight"]) if "layout_weight" in a else 0.0}
    if "projection" in a:
        if a["projection"].ndim != 2:
            raise ValueError(f"projection must be 2-D, got shape {a['projection'].shape}")
        out["projection"] = a["projection"].astype(np.float64)
        out["projection_mean"] = (a["projection_mean"].astype(np.float64)
                                  if "projection_mean" in a else None)
    if "canonical_direction" in a:
        out["canonical_direction"] = a["canonical_direction"].astype(np.float64)
    return out


def load_pose_model(path: str | Path = DEFAULT_MODEL_PATH) -> PoseModel:
    """Read and validate a model file; PoseModelError (one line, naming the file) if it is
    missing, not a model, from another version, tampered with, or inconsistent."""
    path = Path(path)
    try:
        a = load_model(path)
        if str(a.get("model_kind", "")) == MIXTURE_KIND:
            model = _mixture_from_arrays(path, a)
            _validate(path, model)
            return model
        if str(a.get("model_kind", "")) != MODEL_KIND:
            raise PoseModelError(f"{path}: not a silhouette-pose model file")
        from .optional_parts import single_model_from_arrays
        model = single_model_from_arrays(path, a)
    except PoseModelError:
        raise
    except ModelFileError as exc:
        raise PoseModelError(str(exc)) from exc
    except KeyError as exc:
        raise PoseModelError(f"{path}: malformed model file: part {exc.args[0]!r} is "
                             f"missing") from exc
    except (ValueError, TypeError, CodebookError, DescriptorSettingsError) as exc:
        raise PoseModelError(f"{path}: malformed model file ({exc})") from exc
    _validate(path, model)
    return model


def _validate(path: Path, m: PoseModel) -> None:
    """PoseModelError for what regressor.model_file's checks (finite parts, the basis, shapes
    that agree with one another) leave open."""
    D, k = m.descriptor_length, m.stack_depth
    R = len(m.coef)
    kD = m.input_length
    checks = [
        (0 <= m.layout_grid <= MAX_GRID, f"layout grid {m.layout_grid} out of range 0..{MAX_GRID}"),
        (not m.layout_grid or (np.isfinite(m.layout_weight) and m.layout_weight > 0),
         "the layout weight must be > 0"),
        (m.projection is None or (1 <= m.projection.shape[1] <= k * D
                                  and m.projection_mean is not None
                                  and m.projection_mean.shape == (k * D,)),
         f"the projection must be ({k * D}, P) with a ({k * D},) mean"),
        (1 <= k <= 16, f"stack depth {k} out of range 1..16"),
        (m.transform in TRANSFORMS, f"unknown descriptor transform {m.transform!r}"),
        (m.coef.ndim == 2 and m.coef.shape[1] == POSE_DIM and R >= 1,
         f"weights must be (R, {POSE_DIM}), got {m.coef.shape}"),
        (m.angle_centre_deg.shape == (POSE_DIM - 2,), "angle centres must be (53,)"),
        (m.measurement_covariance.shape == (N_ANGLES, N_ANGLES),
         "measurement covariance must be (54, 54)"),
        (m.process_noise.shape == (N_ANGLES,), "process noise must be (54,)"),
    ]
    if m.basis == "gaussian":
        checks += [(m.centres is not None and m.centres.shape == (R, kD),
                    f"kernel centres must be ({R}, {kD})"),
                   (m.width is not None and m.width > 0, "kernel width must be > 0")]
    else:
        checks += [(m.relevance.shape == (R,) and m.relevance.min() >= 0
                    and m.relevance.max() < kD, "kept features out of range")]
    checks.append((0.0 <= m.ambiguity_threshold <= 1.0, "ambiguity threshold must be in [0, 1]"))
    dataset = m.description.get("dataset") if isinstance(m.description, dict) else None
    fps = dataset.get("fps") if isinstance(dataset, dict) else None
    # The tracker stacks frames by this rate: a tiny one takes minutes and gigabytes.
    checks.append((fps is None or (isinstance(fps, (int, float)) and not isinstance(fps, bool)
                                   and MIN_TRAINING_FPS <= fps <= MAX_TRAINING_FPS),
                   f"the description's data set fps {fps!r} is not a frame rate in "
                   f"{MIN_TRAINING_FPS:g}..{MAX_TRAINING_FPS:g}"))
    checks.append((m.codebook.centres.shape[1] == m.settings.context_size,
                   f"the codebook's centres have {m.codebook.centres.shape[1]} columns, the "
                   f"descriptor settings' shape contexts {m.settings.context_size} bins"))
    for ok, problem in checks:
        if not ok:
            raise PoseModelError(f"{path}: invalid model: {problem}")
    if np.any(np.linalg.eigvalsh(m.measurement_covariance) <= 0) or np.any(m.process_noise < 0):
        raise PoseModelError(f"{path}: invalid model: noise models are not positive")


#: The most neighbours a model file's heading index may ask for (the shipped one: 20).
MAX_HEADING_NEIGHBOURS = 1000


def _description(a) -> dict:
    """The file's training description, a JSON object; else a PoseModelError-ready ValueError."""
    description = json.loads(str(a["description"]))
    if not isinstance(description, dict):
        raise ValueError(f"the description must be a JSON object, not "
                         f"{type(description).__name__}")
    return description


def _heading_index_from_arrays(a, input_length: int) -> HeadingIndex | None:
    """A file's heading index or None, checked against the input length; else a ValueError."""
    if not _has_parts(a, ("heading_index_inputs", "heading_index_folded_deg", "heading_index_k",
                          "heading_index_limit_deg"), "heading index"):
        if "heading_index_typical_distance" in a:
            raise ValueError("heading index is incomplete")
        return None
    inputs = a["heading_index_inputs"].astype(np.float32)
    folded = a["heading_index_folded_deg"].astype(np.float64)
    k, limit = np.asarray(a["heading_index_k"]), np.asarray(a["heading_index_limit_deg"])
    if k.shape != () or not np.issubdtype(k.dtype, np.integer) or limit.shape != () \
            or not np.issubdtype(limit.dtype, np.floating):
        raise ValueError("heading index k must be one integer and its limit one number")
    k, limit = int(k), float(limit)
    if not 1 <= k <= MAX_HEADING_NEIGHBOURS:      # (an index of fewer rows uses them all)
        raise ValueError(f"heading index k = {k} must be within 1..{MAX_HEADING_NEIGHBOURS}")
    if inputs.ndim != 2 or not 1 <= inputs.shape[1] <= input_length or len(inputs) < 1 \
            or folded.shape != (len(inputs),):
        raise ValueError("heading index shapes do not match the regressor's input")
    if not (np.isfinite(inputs).all() and np.isfinite(folded).all()) \
            or np.any(np.abs(folded) > 90.0):
        raise ValueError("heading index must hold finite inputs and folded headings within "
                         "+-90 degrees")
    index = HeadingIndex(inputs, folded, k, limit)     # which checks k and the limit
    if "heading_index_typical_distance" in a:        # older files compute it
        typical = np.asarray(a["heading_index_typical_distance"])
        if typical.shape != () or not np.issubdtype(typical.dtype, np.floating):
            raise ValueError("heading index typical distance must be one number")
        index.remember_typical_distance(float(typical))
    return index


def _has_parts(a, names: tuple[str, ...], what: str) -> bool:
    """Whether a model file holds the optional block of parts ``names`` (all or none of them;
    a partial block is a PoseModelError-ready ValueError naming ``what``)."""
    present = [n in a for n in names]
    if any(present) and not all(present):
        raise ValueError(f"{what} is incomplete")
    return all(present)


def _gate_from_arrays(a, kD: int, E: int, fail) -> SoftmaxGate:
    """The mixture's softmax gate from its file's parts, checked against kD inputs, E experts."""
    gate_centres = a["mixture_gate_centres"].astype(np.float64)
    G = len(gate_centres)
    weights = a["mixture_gate_weights"].astype(np.float64)
    mean, std = a["mixture_gate_feature_mean"], a["mixture_gate_feature_std"]
    if gate_centres.ndim != 2 or gate_centres.shape[1] != kD or weights.shape != (G + 1, E) \
            or mean.shape != (G,) or std.shape != (G,) or np.any(std <= 0) \
            or not float(a["mixture_gate_width"]) > 0:
        fail("gate parts have inconsistent shapes")
    gate = SoftmaxGate(n_centres=G)
    gate.centres_, gate.width_ = gate_centres, float(a["mixture_gate_width"])
    gate.feature_mean_, gate.feature_std_ = mean.astype(np.float64), std.astype(np.float64)
    gate.weights_, gate.n_classes_, gate.n_features_in_ = weights, E, kD
    return gate


def _check_parts(fail, kD: int, limb_head, limb_net, side_classifier, canonical_priors,
                 canonical: bool) -> None:
    """The parts beside the experts fit together and take kD inputs; canonical: the model
    was fitted on canonical members."""
    if canonical_priors is not None and side_classifier is None:
        fail("canonical priors need a side classifier")
    if side_classifier is not None and limb_net is None and limb_head is None:
        fail("a side classifier needs the model's limbs")
    if side_classifier is not None and side_classifier.input_length != kD:
        fail(f"the side classifier takes {side_classifier.input_length} inputs, the regressor "
             f"{kD}")
    if limb_net is not None and limb_head is not None:
        fail("a model carries a limb head or a limb network, not both")
    if limb_net is not None and limb_net.input_length != kD:
        fail(f"the limb network takes {limb_net.input_length} inputs, the regressor {kD}")
    if (limb_head is not None or limb_net is not None) and canonical:
        fail("a model fitted on canonical members takes no limb head or network")


def _mixture_from_arrays(path: Path, a) -> PoseModel:
    """Rebuild a mixture model from its file's parts, checking their shapes agree."""
    def fail(problem: str):
        raise PoseModelError(f"{path}: invalid model: {problem}")

    settings = DescriptorSettings.from_arrays(a)
    codebook = Codebook.from_arrays(a)
    k = int(a["stack_depth"])
    inputs = _input_from_arrays(a)
    kD = (inputs["projection"].shape[1] if inputs.get("projection") is not None
          else k * (codebook.n_centres + inputs["layout_grid"] ** 2))
    centres = a["centres"].astype(np.float64)
    coef = a["coef"].astype(np.float64)
    offsets = a["mixture_expert_offsets"].astype(np.int64)
    width = a["mixture_expert_width"].astype(np.float64)
    intercept = a["mixture_expert_intercept"].astype(np.float64)
    E = len(width)
    if E < 1 or offsets.shape != (E + 1,) or offsets[0] != 0 or offsets[-1] != len(coef) \
            or np.any(np.diff(offsets) < 1):
        fail("expert offsets do not split the centres into experts")
    if intercept.shape != (E, POSE_DIM) or np.any(width <= 0) or centres.shape != (len(coef), kD):
        fail("expert widths, offsets or centres have inconsistent shapes")
    gate = _gate_from_arrays(a, kD, E, fail)
    partition = a["mixture_partition_centres"].astype(np.float64)
    if partition.ndim != 2 or len(partition) != E:
        fail("partition centres must have one row per expert")
    params = json.loads(str(a["mixture_params"]))
    mix = MixtureRegressor(**params)
    mix.experts_ = []
    for e in range(E):
        ex = DampedKernelRegressor(n_centres=int(offsets[e + 1] - offsets[e]))
        ex.centres_ = centres[offsets[e]:offsets[e + 1]]
        ex.coef_ = coef[offsets[e]:offsets[e + 1]]
        ex.width_, ex.intercept_, ex.n_features_in_ = float(width[e]), intercept[e], kD
        mix.experts_.append(ex)
    mix.gate_, mix.partition_centres_ = gate, partition
    mix.expert_rows_ = np.zeros(E, np.int64)
    calibration = None
    if "mixture_expert_kind" in a:
        try:
            mix.experts_, mix.expert_rows_, calibration = _rvm_experts(a, mix.experts_, offsets)
        except ValueError as exc:
            fail(str(exc))
    rvm = "mixture_expert_kind" in a
    if (mix.expert == "sparse_rvm") != rvm:
        fail(f"mixture_params names {mix.expert!r} experts, the file holds "
             f"{'sparse RVM' if rvm else 'damped least squares'} experts")
    mix.top_experts = int(a["mixture_top_experts"])
    mix.n_features_in_, mix.n_outputs_ = kD, POSE_DIM
    try:
        limb_head = None
        if any(name.startswith("limbs_") for name in a.keys()):
            from .optional_parts import limb_head_from_arrays
            limb_head = limb_head_from_arrays(a, len(coef), E)
        heading_index = _heading_index_from_arrays(a, kD)
        limb_net = LimbNet.from_arrays(a)
        side_classifier = SideClassifier.from_arrays(a)
        canonical_priors = CanonicalPriors.from_arrays(a)
    except ValueError as exc:
        fail(str(exc))
    _check_parts(fail, kD, limb_head, limb_net, side_classifier, canonical_priors,
                 "canonical_direction" in a)
    return PoseModel(
        settings=settings, codebook=codebook, stack_depth=k, transform=str(a["transform"]),
        basis="gaussian", width=float(a["width"]), centres=centres,
        relevance=a["relevance"].astype(np.int64), coef=coef, intercept=np.zeros(POSE_DIM),
        angle_centre_deg=a["angle_centre_deg"].astype(np.float64),
        measurement_covariance=a["measurement_covariance"].astype(np.float64),
        process_noise=a["process_noise"].astype(np.float64),
        ambiguity_threshold=float(a.get("ambiguity_threshold", DEFAULT_AMBIGUITY_THRESHOLD)),
        description=_description(a), mixture=mix, limb_head=limb_head,
        heading_index=heading_index, limb_net=limb_net, side_classifier=side_classifier,
        canonical_priors=canonical_priors, variance_calibration=calibration, **inputs)


_RVM_PARTS = ("mixture_expert_kind", "mixture_expert_beta", "mixture_expert_rows",
              "mixture_expert_y_scale")
_VARIANCE_PARTS = ("mixture_expert_sigma", "mixture_expert_phi_mean",
                   "mixture_variance_calibration")


def _rvm_experts(a, experts: list, offsets: np.ndarray
                 ) -> tuple[list, np.ndarray, float | None]:
    """(sparse RVM experts built on the damped least squares ones read from the shared parts,
    rows (E,), variance calibration or None); a PoseModelError-ready ValueError."""
    if not _has_parts(a, _RVM_PARTS, "sparse RVM experts") or \
            str(a["mixture_expert_kind"]) != "rvm":
        raise ValueError("mixture_expert_kind must be 'rvm' with all the sparse RVM parts")
    E, sizes = len(experts), np.diff(offsets)
    beta, rows, y_scale = a["mixture_expert_beta"], a["mixture_expert_rows"], \
        a["mixture_expert_y_scale"]
    if beta.shape != (E,) or rows.shape != (E,) or y_scale.shape != (E, POSE_DIM):
        raise ValueError("sparse RVM expert parts do not match the experts' sizes")
    if np.any(beta <= 0) or np.any(rows < 1) or np.any(y_scale <= 0):
        raise ValueError("sparse RVM noise precisions, rows and output scales must be positive")
    from .sparse_rvm import SparseRVMRegressor
    out = []
    for e, dls in enumerate(experts):
        ex, R = SparseRVMRegressor(n_candidates=int(sizes[e])), int(sizes[e])
        ex.centres_, ex.width_, ex.n_features_in_ = dls.centres_, dls.width_, dls.n_features_in_
        ex.coef_, ex.intercept_ = dls.coef_, dls.intercept_
        ex.candidates_, ex.relevance_ = dls.centres_, np.arange(R, dtype=np.int64)
        ex.beta_, ex.n_train_, ex.y_scale_ = float(beta[e]), int(rows[e]), y_scale[e].astype(float)
        ex.noise_, ex._y_1d = ex.y_scale_ ** 2 / ex.beta_, False
        out.append(ex)
    calibration = None
    if any(name in a for name in _VARIANCE_PARTS):
        from .optional_parts import rvm_variance
        calibration = rvm_variance(a, out, offsets)
    return out, rows.astype(np.int64), calibration
