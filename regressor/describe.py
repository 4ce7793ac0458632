"""What a model file holds, as plain JSON: ``python -m regressor describe [MODEL]``.

Users ask what they are running: which regressor (and, for a mixture, each expert's kind and
size), which extra parts (limb networks, side classifier, heading index), what it was trained
on, and the settings that shape its input. Everything is read from the validated model
(regressor.pose_model.load_pose_model), nothing is assumed.
"""
from __future__ import annotations

from .pose_model import PoseModel

#: The name each regressor class is described by (the mission's terms: damped least squares
#: and relevance vector machines).
EXPERT_KINDS = {"DampedKernelRegressor": "damped_least_squares", "RVMRegressor": "rvm",
                "SparseRVMRegressor": "rvm"}


def describe_model(model: PoseModel) -> dict:
    """{"regressor": ..., "parts": ..., "training": ..., "settings": ...} of a loaded model."""
    return {"regressor": _regressor(model), "parts": _parts(model),
            "training": _training(model.description), "settings": _settings(model)}


def _expert(expert) -> dict:
    """One expert: its kind, basis and how many basis functions it keeps."""
    name = type(expert).__name__
    centres = getattr(expert, "centres_", None)
    kept = getattr(expert, "relevance_", centres)
    out = {"kind": EXPERT_KINDS.get(name, name), "basis": "gaussian",
           "basis_functions": int(len(kept)) if kept is not None else None}
    if out["kind"] == "rvm":
        out["relevance_vectors"] = out["basis_functions"]
    return out


def _regressor(model: PoseModel) -> dict:
    if model.mixture is None:
        # A single regressor is written by training's kernel-RVM path, which records its count.
        fitted_as_rvm = "relevance_vectors" in model.description.get("validation", {})
        out = {"kind": "rvm" if fitted_as_rvm else "damped_least_squares",
               "basis": model.basis, "basis_functions": int(len(model.coef)),
               "outputs": int(model.coef.shape[1])}
        if fitted_as_rvm:
            out["relevance_vectors"] = out["basis_functions"]
        return out
    mixture = model.mixture
    return {"kind": "mixture_of_experts", "gate": type(mixture.gate_).__name__,
            "experts_per_frame": int(mixture.top_experts),
            "experts": [_expert(e) for e in mixture.experts_],
            "basis_functions": int(sum(_expert(e)["basis_functions"] or 0
                                       for e in mixture.experts_))}


def _parts(model: PoseModel) -> dict:
    """The parts beside the regressor that the tracker uses, with their sizes."""
    parts = {}
    if model.limb_net is not None:
        parts["limb_networks"] = {"members": len(model.limb_net.members),
                                  "hidden": [int(W.shape[1]) for W, _ in
                                             model.limb_net.members[0][:-1]]}
    if model.side_classifier is not None:
        parts["side_classifier"] = {"hidden": [int(W.shape[1]) for W, _ in
                                               model.side_classifier.layers[:-1]]}
    if model.heading_index is not None:
        parts["heading_index"] = {"rows": int(len(model.heading_index.inputs)),
                                  "neighbours": model.heading_index.k}
    if model.limb_head is not None:
        parts["limb_head"] = {"basis_functions": int(len(model.limb_head.coef))}
    parts["front_back_priors"] = model.canonical_priors is not None
    return parts


def _training(description: dict) -> dict:
    """Sources with their sequence and frame counts (as the training recorded them), the
    held-out trials and the validation figures."""
    sources = description.get("sources")
    if not isinstance(sources, dict):       # models trained before sources were recorded
        trials = description.get("trials", [])
        sources = {"cmu": {"sequences": len(trials), "frames": None,
                           "rows": description.get("validation", {}).get("n_train_rows")}}
    validation = description.get("validation", {})
    return {"data": description.get("data"), "sources": sources,
            "held_out": description.get("held_out", []),
            "views_per_sequence": description.get("dataset", {}).get("views_per_trial"),
            "validation": validation.get("validation")}


def _settings(model: PoseModel) -> dict:
    s = model.settings
    return {"shape_context": {"angular_bins": s.n_angular, "radial_bins": s.n_radial,
                              "edge_points": s.n_points, "r_inner": s.r_inner,
                              "r_outer": s.r_outer},
            "codebook_centres": int(model.codebook.n_centres),
            "layout_grid": int(model.layout_grid), "stack_depth": int(model.stack_depth),
            "input_length": int(model.input_length), "transform": model.transform,
            "training_fps": float(model.training_fps)}
