"""What regressor.pose_model needs only for parts the shipped model lacks (single-regressor
files, a mixture's limb head, its sparse RVM experts' predictive variance) or only for
training and evaluation; imported on first use, so ``track`` never loads it.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .angles import POSE_DIM, wrap_deg
from .basis import gaussian_design
from .canonical_priors import PREFIX as CANONICAL_PRIOR_PREFIX
from .codebook import Codebook
from .descriptor import DescriptorSettings
from .pose_model import (_VARIANCE_PARTS, DEFAULT_AMBIGUITY_THRESHOLD, PoseModel,
                         PoseModelError, _description, _has_parts, _input_from_arrays)


@dataclass
class LimbHead:
    """A mixture's second set of expert weights: coef (R, 55) in the experts' row order,
    expert_intercept (E, 55), angle_centre_deg (53,) and canonical_direction (55,), the rule
    its targets' members were chosen by (sequences.pose_conversions.canonical_member)."""

    coef: np.ndarray
    expert_intercept: np.ndarray
    angle_centre_deg: np.ndarray
    canonical_direction: np.ndarray


def single_model_from_arrays(path: Path, a) -> PoseModel:
    """A single regressor's model (model_kind MODEL_KIND) from its file's parts a."""
    if any(name.startswith(("limbs_", "limb_net_", "side_net_", CANONICAL_PRIOR_PREFIX))
           for name in a.parts):
        raise PoseModelError(f"{path}: invalid model: only a mixture can carry a limb head, "
                             f"limb network, side classifier or canonical priors")
    if any(name.startswith("heading_index_") for name in a.parts):
        raise PoseModelError(f"{path}: invalid model: only a mixture can carry a heading "
                             "index")
    settings = DescriptorSettings.from_arrays(a)
    codebook = Codebook.from_arrays(a)
    return PoseModel(
        settings=settings, codebook=codebook, stack_depth=int(a["stack_depth"]),
        transform=str(a["transform"]), basis=str(a["basis"]),
        width=None if np.isnan(a["width"]) else float(a["width"]),
        centres=None if a["centres"].size == 0 else a["centres"].astype(np.float64),
        relevance=a["relevance"].astype(np.int64), coef=a["coef"].astype(np.float64),
        intercept=a["intercept"].astype(np.float64),
        angle_centre_deg=a["angle_centre_deg"].astype(np.float64),
        measurement_covariance=a["measurement_covariance"].astype(np.float64),
        process_noise=a["process_noise"].astype(np.float64),
        ambiguity_threshold=float(a.get("ambiguity_threshold", DEFAULT_AMBIGUITY_THRESHOLD)),
        description=_description(a), **_input_from_arrays(a))


def limb_head_from_arrays(a, n_rows: int, n_experts: int) -> LimbHead | None:
    """A file's limb head (None when it has none), its shapes checked against the experts'
    n_rows centres and n_experts; PoseModelError-ready ValueError otherwise."""
    names = ("limbs_coef", "limbs_expert_intercept", "limbs_angle_centre_deg",
             "limbs_canonical_direction")
    if not _has_parts(a, names, "limb head"):
        return None
    head = LimbHead(*(a[n].astype(np.float64) for n in names))
    if head.coef.shape != (n_rows, POSE_DIM) \
            or head.expert_intercept.shape != (n_experts, POSE_DIM) \
            or head.angle_centre_deg.shape != (POSE_DIM - 2,) \
            or head.canonical_direction.shape != (POSE_DIM,):
        raise ValueError("limb head shapes do not match the experts")
    if not all(np.isfinite(x).all() for x in (head.coef, head.expert_intercept,
                                               head.angle_centre_deg, head.canonical_direction)):
        raise ValueError("limb head has non-finite values")
    if np.any(np.abs(head.angle_centre_deg) > 180.0) \
            or not abs(np.linalg.norm(head.canonical_direction) - 1.0) < 1e-6:
        raise ValueError("limb head centres must be angles in [-180, 180] and its direction a "
                         "unit vector")
    return head


def limb_head_poses(model: PoseModel, X: np.ndarray, gate: np.ndarray | None) -> np.ndarray:
    """A mixture's limb head's canonical poses (N, 55) for the regressor's input X (N, P), each
    row by its most probable expert (gate (N, E) the mixture's probabilities; None: evaluated)."""
    if gate is None:
        gate = model.mixture.predict_proba(X)
    top = gate.argmax(axis=1)
    head, experts = model.limb_head, model.mixture.experts_
    offsets = np.cumsum([0] + [len(e.centres_) for e in experts])
    out = np.empty((len(X), POSE_DIM))
    for e in np.unique(top):
        rows = np.flatnonzero(top == e)
        out[rows] = (gaussian_design(X[rows], experts[e].centres_, experts[e].width_)
                     @ head.coef[offsets[e]:offsets[e + 1]] + head.expert_intercept[e])
    out[:, 2:] = wrap_deg(out[:, 2:] + head.angle_centre_deg)
    return out


def rvm_variance(a, experts: list, offsets: np.ndarray) -> float | None:
    """Give sparse RVM experts their stored posterior covariance and kernel means (for the
    predictive variance) and return the variance calibration; None when the file has none."""
    if not _has_parts(a, _VARIANCE_PARTS, "sparse RVM predictive variance"):
        return None
    sizes = np.diff(offsets)
    sigma, phi_mean = a["mixture_expert_sigma"], a["mixture_expert_phi_mean"]
    calibration = np.asarray(a["mixture_variance_calibration"])
    if sigma.shape != (int((sizes ** 2).sum()),) or phi_mean.shape != (int(offsets[-1]),) \
            or calibration.shape != ():
        raise ValueError("sparse RVM variance parts do not match the experts' sizes")
    if not calibration > 0:
        raise ValueError("the variance calibration must be positive")
    starts = np.concatenate([[0], np.cumsum(sizes ** 2)])
    for e, ex in enumerate(experts):
        R = int(sizes[e])
        ex.sigma_ = sigma[starts[e]:starts[e + 1]].astype(np.float64).reshape(R, R)
        ex.phi_mean_ = phi_mean[offsets[e]:offsets[e + 1]].astype(np.float64)
    return float(calibration)


def regress(model: PoseModel, X: np.ndarray) -> np.ndarray:
    """Raw poses (N, 55) from the regressor's input X (N, P): the single regressor's, or the
    mixture's gate-weighted answer."""
    if model.mixture is not None:
        Y = model.mixture.predict(X)
    elif model.basis == "gaussian":
        Y = gaussian_design(X, model.centres, model.width) @ model.coef + model.intercept
    else:
        Y = X[:, model.relevance] @ model.coef + model.intercept
    Y[:, 2:] = wrap_deg(Y[:, 2:] + model.angle_centre_deg)
    return Y


def gives_variance(model: PoseModel) -> bool:
    """Whether the model's experts give a predictive variance (sparse RVMs that keep their
    posterior covariance). Never imports regressor.sparse_rvm: a model without sparse RVM
    experts has not loaded it."""
    module = sys.modules.get("regressor.sparse_rvm")
    return model.mixture is not None and all(
        module is not None and isinstance(e, module.SparseRVMRegressor) and hasattr(e, "sigma_")
        for e in model.mixture.experts_)


def predict_batch(model: PoseModel, stacked: np.ndarray) -> np.ndarray:
    """Raw poses (N, 55) from stacked, transformed descriptors (N, k*D): the regressor's
    single answer (a mixture's gate-weighted one), for training and evaluation."""
    return regress(model, model._stacked(stacked))


def predict_limbs(model: PoseModel, stacked: np.ndarray) -> np.ndarray | None:
    """Canonical poses (N, 55) for the limbs from stacked descriptors (N, k*D), as
    PoseModel.hypotheses gives them, for training and evaluation. None without limbs."""
    return model._limbs(model._stacked(stacked)) if model.has_limbs else None


def predict_variance(model: PoseModel, stacked: np.ndarray) -> np.ndarray:
    """Predictive variance (N,) deg^2 of :func:`predict_batch`'s pose for stacked descriptors
    (N, k*D): the experts' variance of a new observation, averaged over the 53 body angles
    (regressor.sparse_rvm), for training's calibration. Needs :func:`gives_variance`."""
    if not gives_variance(model):
        raise PoseModelError("this model's experts give no predictive variance "
                             "(only sparse RVM experts do)")
    _, std = model.mixture.predict(model._stacked(stacked), return_std=True)
    return (std[:, 2:] ** 2).mean(axis=1)
