"""Writing model files: one versioned, checksummed .npz, no pickle (regressor.model_file reads
them): save_model writes named parts, save_pose_model a PoseModel's. Training writes models;
``track`` only reads them (regressor.pose_model.load_pose_model).
"""
from __future__ import annotations

import json
import os
import tempfile
from dataclasses import asdict
from pathlib import Path
from typing import Mapping

import numpy as np

from .angles import POSE_DIM
from .canonical_priors import PARTS as PRIOR_PARTS, PREFIX as PRIORS_PREFIX, CanonicalPriors
from .codebook import Codebook
from .descriptor import DescriptorSettings
from .heading_index import HeadingIndex
from .limb_net import PREFIX as LIMB_NET_PREFIX, LimbNet
from .mixture import DampedKernelRegressor, SoftmaxGate
from .model_file import _RESERVED, FORMAT_VERSION, ModelFileError, _validate, checksum
from .optional_parts import LimbHead
from .pose_model import MIXTURE_KIND, MODEL_KIND, PoseModel, PoseModelError
from .side_classifier import PREFIX as SIDE_PREFIX, SideClassifier


def _as_array(name: str, value) -> np.ndarray:
    if isinstance(value, dict):
        value = json.dumps(value, sort_keys=True)
    a = np.asarray(value)
    if a.dtype.kind not in "biufU":
        raise ModelFileError(f"part {name!r} has dtype {a.dtype}; only numbers and strings can "
                             f"be stored")
    return a


def save_model(path: str | Path, parts: Mapping | None = None, /, **more) -> Path:
    """Validate the parts (name -> array, number, str, or a JSON-able dict for
    ``description``) and write them to ``path`` (.npz) with FORMAT_VERSION and a checksum.
    The file is written to a temporary name and renamed, so a crash never leaves half a
    model."""
    path = Path(path)
    merged = {**(dict(parts) if parts is not None else {}), **more}
    bad = [k for k in merged if k in _RESERVED]
    if bad:
        raise ModelFileError(f"{path}: part names {bad} are reserved")
    arrays = {k: _as_array(k, v) for k, v in merged.items()}
    _validate(str(path), arrays)
    out = dict(arrays, format_version=np.int64(FORMAT_VERSION), checksum=np.str_(checksum(arrays)))
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".npz", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez_compressed(fh, **out)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def quantised_int8(W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A weight matrix W (n_in, n_out) of finite floats as int8 values q in -127..127 and one
    float32 scale per output column (n_out,), W ~ q * scale: a quarter of float32's file
    space. Each column's scale is its largest |weight| / 127 in float32 (1 for a column that
    is zero in float32, stored as zeros), so every column keeps 8 bits of its own range;
    ValueError for anything but a matrix of finite floats."""
    W = np.asarray(W, dtype=np.float64)
    if W.ndim != 2 or not np.isfinite(W).all():
        raise ValueError(f"quantised weights come from a matrix of finite floats, got shape "
                         f"{W.shape}")
    scale = (np.abs(W).max(axis=0) / 127.0).astype(np.float32)
    scale[scale == 0] = 1.0             # an all-zero column (or one float32 cannot hold): q is 0
    q = np.clip(np.round(W / scale.astype(np.float64)), -127, 127)
    return q.astype(np.int8), scale


def codebook_arrays(codebook: Codebook) -> dict:
    """A codebook's file parts: codebook_centres (K, D) float64, codebook_sigma () float64."""
    return {"codebook_centres": codebook.centres.copy(),
            "codebook_sigma": np.array(codebook.sigma)}


def settings_arrays(settings: DescriptorSettings) -> dict:
    """Descriptor settings' file parts: a 0-d array per setting, named descriptor_ + field."""
    return {f"descriptor_{k}": np.array(v) for k, v in asdict(settings).items()}


def limb_net_arrays(net: LimbNet) -> dict:
    """A limb network's file parts (regressor.limb_net.LimbNet.from_arrays reads them): each
    weight matrix as int8 with a float32 scale per output column (``S{m}_{i}``,
    quantised_int8). Older files hold float16 weights and no scales."""
    p = LIMB_NET_PREFIX
    out = {f"{p}shape": np.array([len(net.members), len(net.members[0])], np.int64),
           f"{p}input_mean": net.input_mean, f"{p}input_scale": np.float64(net.input_scale),
           f"{p}output_mean": net.output_mean, f"{p}output_scale": net.output_scale,
           f"{p}angle_centre_deg": net.angle_centre_deg,
           f"{p}canonical_direction": net.canonical_direction}
    for m, layers in enumerate(net.members):
        for i, (W, b) in enumerate(layers):
            out[f"{p}W{m}_{i}"], out[f"{p}S{m}_{i}"] = quantised_int8(W)
            out[f"{p}b{m}_{i}"] = b.astype(np.float32)
    return out


def side_classifier_arrays(clf: SideClassifier) -> dict:
    """A side classifier's file parts (SideClassifier.from_arrays reads them); weights float16."""
    p = SIDE_PREFIX
    out = {f"{p}layers": np.int64(len(clf.layers)), f"{p}input_mean": clf.input_mean,
           f"{p}input_scale": np.float64(clf.input_scale)}
    for i, (W, b) in enumerate(clf.layers):
        out[f"{p}W{i}"], out[f"{p}b{i}"] = W.astype(np.float16), b.astype(np.float32)
    return out


def canonical_priors_arrays(priors: CanonicalPriors) -> dict:
    """Canonical priors' file parts (float64; CanonicalPriors.from_arrays reads them)."""
    return {f"{PRIORS_PREFIX}{name}": np.asarray(getattr(priors, name), dtype=np.float64)
            for name in PRIOR_PARTS}


def _is_sparse_rvm(expert) -> bool:
    """isinstance(expert, SparseRVMRegressor), importing regressor.sparse_rvm."""
    from .sparse_rvm import SparseRVMRegressor
    return isinstance(expert, SparseRVMRegressor)


def save_pose_model(path: str | Path, model: PoseModel) -> None:
    """Write the model as one versioned, checksummed .npz (no pickle)."""
    if model.mixture is not None:
        if model.limb_head is not None and model.limb_net is not None:
            raise PoseModelError("a model carries a limb head or a limb network, not both")
        if model.side_classifier is not None and not model.has_limbs:
            raise PoseModelError("a side classifier needs the model's limbs")
        if model.canonical_priors is not None and model.side_classifier is None:
            raise PoseModelError("canonical priors need the model's side classifier")
        try:
            arrays = _mixture_arrays(model)
        except ValueError as exc:
            raise PoseModelError(f"cannot save the model: {exc}") from None
        save_model(path, arrays)
        return
    if model.limb_head is not None:
        raise PoseModelError("only a mixture model can carry a limb head")
    if model.heading_index is not None:
        raise PoseModelError("only a mixture model can carry a heading index")
    if model.limb_net is not None:
        raise PoseModelError("only a mixture model can carry a limb network")
    if model.side_classifier is not None or model.canonical_priors is not None:
        raise PoseModelError("only a mixture model can carry a side classifier or canonical "
                             "priors")
    arrays = {
        **codebook_arrays(model.codebook), **settings_arrays(model.settings),
        "model_kind": np.str_(MODEL_KIND),
        "stack_depth": np.int64(model.stack_depth),
        "transform": np.str_(model.transform), "basis": np.str_(model.basis),
        "width": np.float64(np.nan if model.width is None else model.width),
        "centres": (np.zeros((0, 0)) if model.centres is None else model.centres),
        "relevance": np.asarray(model.relevance, dtype=np.int64),
        "coef": model.coef, "intercept": model.intercept,
        "angle_centre_deg": model.angle_centre_deg,
        "measurement_covariance": model.measurement_covariance,
        "process_noise": model.process_noise,
        "ambiguity_threshold": np.float64(model.ambiguity_threshold),
        "description": np.str_(json.dumps(model.description, sort_keys=True)),
        **_input_arrays(model),
    }
    save_model(path, arrays)


def _input_arrays(model: PoseModel) -> dict:
    """The file parts of the input's layout block and projection (none for models without)."""
    out = {}
    if model.layout_grid:
        out.update(layout_grid=np.int64(model.layout_grid),
                   layout_weight=np.float64(model.layout_weight))
    if model.projection is not None:
        out.update(projection=np.asarray(model.projection, dtype=np.float32),
                   projection_mean=np.asarray(model.projection_mean, dtype=np.float64))
    if model.canonical_direction is not None:
        out["canonical_direction"] = np.asarray(model.canonical_direction, dtype=np.float64)
    return out


def _mixture_arrays(model: PoseModel) -> dict:
    mix = model.mixture
    experts = mix.experts_
    rvm = all(_is_sparse_rvm(e) for e in experts)
    if not rvm and not all(isinstance(e, DampedKernelRegressor) for e in experts):
        raise PoseModelError("only mixtures of DampedKernelRegressor or SparseRVMRegressor "
                             "experts can be saved")
    offsets = np.cumsum([0] + [len(e.centres_) for e in experts]).astype(np.int64)
    gate = mix.gate_
    if not isinstance(gate, SoftmaxGate):
        raise PoseModelError("only mixtures with a softmax gate can be saved (a neighbour gate "
                             "keeps every training row)")
    return {
        **codebook_arrays(model.codebook), **settings_arrays(model.settings),
        "model_kind": np.str_(MIXTURE_KIND),
        "stack_depth": np.int64(model.stack_depth), "transform": np.str_(model.transform),
        "basis": np.str_("gaussian"),
        "width": np.float64(np.median([e.width_ for e in experts])),
        "centres": np.vstack([e.centres_ for e in experts]).astype(np.float16),
        "relevance": np.arange(offsets[-1], dtype=np.int64),
        "coef": np.vstack([e.coef_ for e in experts]).astype(np.float32),
        "intercept": np.zeros(POSE_DIM),
        "angle_centre_deg": model.angle_centre_deg,
        "measurement_covariance": model.measurement_covariance,
        "process_noise": model.process_noise,
        "ambiguity_threshold": np.float64(model.ambiguity_threshold),
        "description": np.str_(json.dumps(model.description, sort_keys=True)),
        **_input_arrays(model),
        "mixture_expert_offsets": offsets,
        "mixture_expert_width": np.array([e.width_ for e in experts], dtype=np.float64),
        "mixture_expert_intercept": np.vstack([e.intercept_ for e in experts]),
        "mixture_partition_centres": np.asarray(mix.partition_centres_, dtype=np.float64),
        "mixture_gate_centres": gate.centres_.astype(np.float16),
        "mixture_gate_width": np.float64(gate.width_),
        "mixture_gate_feature_mean": gate.feature_mean_,
        "mixture_gate_feature_std": gate.feature_std_,
        "mixture_gate_weights": gate.weights_,
        "mixture_top_experts": np.int64(mix.top_experts),
        "mixture_params": np.str_(json.dumps(mix.get_params(), sort_keys=True)),
        **(_rvm_expert_arrays(model) if rvm else {}),
        **_limb_head_arrays(model.limb_head),
        **_heading_index_arrays(model.heading_index),
        **(limb_net_arrays(model.limb_net) if model.limb_net is not None else {}),
        **(side_classifier_arrays(model.side_classifier)
           if model.side_classifier is not None else {}),
        **(canonical_priors_arrays(model.canonical_priors)
           if model.canonical_priors is not None else {}),
    }


def _rvm_expert_arrays(model: PoseModel) -> dict:
    """The parts only sparse RVM experts have (module comment above); their predictive
    variance's only when the model keeps it (variance_calibration set)."""
    experts = model.mixture.experts_
    out = {"mixture_expert_kind": np.str_("rvm"),
           "mixture_expert_beta": np.array([e.beta_ for e in experts], dtype=np.float64),
           "mixture_expert_rows": np.array([e.n_train_ for e in experts], dtype=np.int64),
           "mixture_expert_y_scale": np.vstack([e.y_scale_ for e in experts])}
    if model.variance_calibration is None:
        return out
    return {**out,
            "mixture_expert_sigma": np.concatenate([e.sigma_.ravel() for e in experts]
                                                   ).astype(np.float32),
            "mixture_expert_phi_mean": np.concatenate([e.phi_mean_ for e in experts]),
            "mixture_variance_calibration": np.float64(model.variance_calibration)}


def _limb_head_arrays(head: LimbHead | None) -> dict:
    """The file parts of a limb head (coef float32, as the main head's), none without one."""
    if head is None:
        return {}
    return {"limbs_coef": np.asarray(head.coef, dtype=np.float32),
            "limbs_expert_intercept": np.asarray(head.expert_intercept, dtype=np.float64),
            "limbs_angle_centre_deg": np.asarray(head.angle_centre_deg, dtype=np.float64),
            "limbs_canonical_direction": np.asarray(head.canonical_direction, dtype=np.float64)}


def _heading_index_arrays(index: HeadingIndex | None) -> dict:
    """The file parts of a heading index (inputs float16, as the experts' centres), none
    without one."""
    if index is None:
        return {}
    inputs = np.asarray(index.inputs, dtype=np.float16)
    # novelty's scale, as the index read back from the file (float16 inputs) computes it:
    # stored, so that loading the model does not take 0.35 s to recompute it. An index that
    # already holds those inputs (a loaded model saved again) knows it.
    stored = (index if np.array_equal(index.inputs, inputs.astype(np.float32))
              else HeadingIndex(inputs, index.folded_deg, index.k, index.limit_deg))
    typical = stored.typical_distance()
    return {"heading_index_inputs": inputs,
            "heading_index_folded_deg": np.asarray(index.folded_deg, dtype=np.float32),
            "heading_index_k": np.int64(index.k),
            "heading_index_limit_deg": np.float64(index.limit_deg),
            # unknown (NaN) for an index of k rows or fewer: not stored, as for older files
            **({"heading_index_typical_distance": np.float64(typical)}
               if np.isfinite(typical) else {})}
