"""Learning the front/back hypotheses' priors (tracker/hypotheses.py) from data.

- regressor_flip_statistics: from a model's raw outputs on rendered validation trials, how
  often the raw pose is nearer the truth than its front/back flip, as a function of the
  (cos, sin) norm, and how often that changes from one frame to the next (the HMM's switching
  probability: a true heading change of ~180 degrees within a frame does not happen, so the
  only switches are the regressor's).
- canonical_statistics, learn_canonical_priors: for a model with limbs and a side classifier,
  the canonical chain's priors (regressor.canonical_priors; tracker.tracks.hypotheses CANONICAL_*)
  on the validation renders.
- choose_weights: the exponent per frame of the regressor's evidence (consecutive frames'
  evidence is correlated), by replaying the tracker over the validation trials rendered as
  spirals and from a fixed camera, forwards and time-reversed.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from regressor.angles import heading_norm, pose_angles, wrap_deg
from regressor.canonical_priors import CanonicalPriors
from sequences.bvh import read_bvh
from sequences.pose_vector import front_back_flip
from regressor.stacking import stack_frames
from sequences.spiral import spiral_walk
from tracker.tracks.hypotheses import DEFAULT_EXPERTS, FrontBackTracker, chain_options
from tracker.tracks.proposals import propose_sequence
from tracker.pipeline import kalman_factory
from lab.evaluation import CameraOptions, cmu_motion, render_silhouettes


def raw_is_nearer(raw: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """(T,) bool: raw pose (T, 55) is nearer the truth than its front/back flip (mean absolute
    wrapped error over the 54 angles)."""
    t = pose_angles(truth)
    err = np.abs(wrap_deg(pose_angles(raw) - t)).mean(axis=1)
    err_flip = np.abs(wrap_deg(pose_angles(front_back_flip(raw)) - t)).mean(axis=1)
    return err <= err_flip


def video_like(masks: np.ndarray, on: bool = True, seed: int = 0) -> list | np.ndarray:
    """The rendered masks (T, H, W) as the tracker's extractor gives them from video
    (lab.training.noisy_masks, as the model was trained on), or as they are when
    on is False. Priors learned on crisp renders would describe inputs the model never sees
    in use: the layout block reads their open gaps differently (docs/accuracy.md)."""
    if not on:
        return masks
    from lab.training import noisy_masks
    return noisy_masks(masks, seed)


def regressor_flip_statistics(model, bvh_files, spiral_deg_per_s: float = 30.0,
                              frames: int | None = 300,
                              norm_edges=(0.0, 0.2, 0.4, 0.6, 0.8, 1.0, np.inf),
                              n_experts: int = DEFAULT_EXPERTS, video: bool = True) -> dict:
    """The model's raw outputs on each BVH rendered as a spiral walk (all headings): per norm
    bin the fraction of frames whose raw pose is nearer the truth than its flip, and the rate
    per frame at which that changes (the switching probability). For a mixture each of the
    top n_experts experts' poses (PoseModel.hypotheses) counts as a raw pose, as
    each gets its own evidence in tracker.tracks.hypotheses; switches are counted per expert slot
    (slot i at t -> slot i at t + 1) and pooled. video: describe video-like masks
    (video_like)."""
    nearer, norms, pairs = [], [], []
    for path in bvh_files:
        motion = cmu_motion(path, spiral_deg_per_s)
        if frames is not None:
            motion = replace(motion, euler_deg=motion.euler_deg[:frames],
                             root_position=motion.root_position[:frames])
        masks, truth, _ = render_silhouettes(motion, CameraOptions())
        for raw in _slot_poses(model, video_like(masks, video), n_experts):
            ok = raw_is_nearer(raw, truth)
            nearer.append(ok)
            norms.append(heading_norm(raw))
            pairs.append(np.stack([ok[:-1], ok[1:]], axis=1))
    ok, n, pair = np.concatenate(nearer), np.concatenate(norms), np.concatenate(pairs)
    was_raw, was_flip = pair[:, 0], ~pair[:, 0]
    edges = np.asarray(norm_edges, float)
    which = np.clip(np.searchsorted(edges, n, side="right") - 1, 0, len(edges) - 2)
    return {"frames": int(len(ok)), "raw_nearer": float(ok.mean()),
            "switch_rate": float((pair[:, 0] != pair[:, 1]).mean()),
            "p_raw_to_flip": float((~pair[was_raw, 1]).mean()),
            "p_flip_to_raw": float(pair[was_flip, 1].mean()) if was_flip.any() else None,
            "norm_edges": edges.tolist(),
            "raw_nearer_per_bin": [float(ok[which == b].mean()) if (which == b).any() else None
                                   for b in range(len(edges) - 1)],
            "frames_per_bin": np.bincount(which, minlength=len(edges) - 1).tolist()}


def _slot_poses(model, masks, n_experts: int) -> list[np.ndarray]:
    """Raw poses (T, 55) per expert slot: the top n_experts of a mixture, else the one pose."""
    X = np.array([model.describe(m) for m in masks])
    poses = model.hypotheses(stack_frames(X, model.stack_depth), n_experts, novelty=False).poses
    return [poses[:, i] for i in range(poses.shape[1])]


def validation_renders(model, bvh_files, spiral_deg_per_s: float = 30.0,
                       frames: int | None = 600, camera: CameraOptions = CameraOptions(),
                       n_experts: int = DEFAULT_EXPERTS, video: bool = True) -> dict[str, dict]:
    """Each BVH rendered as a spiral walk and from the fixed camera, as recorded and
    time-reversed (a forward walk played backwards is a backward walk): name ->
    {"hypotheses": the model's Hypotheses frame by frame, "image_track": (T, 2), "truth":
    (T, 55)}. video: the model sees video-like masks (video_like)."""
    renders = {}
    for path in bvh_files:
        for spiral in (spiral_deg_per_s, None):
            for reverse in (False, True):
                motion = read_bvh(path, fps=camera.fps)
                if reverse:
                    motion = replace(motion, euler_deg=motion.euler_deg[::-1].copy(),
                                     root_position=motion.root_position[::-1].copy())
                if spiral:
                    motion = spiral_walk(motion, spiral)
                if frames is not None:
                    motion = replace(motion, euler_deg=motion.euler_deg[:frames],
                                     root_position=motion.root_position[:frames])
                masks, truth, image_track = render_silhouettes(motion, camera)
                name = f"{Path(path).stem} {'spiral' if spiral else 'fixed'}" \
                       f"{' reversed' if reverse else ''}"
                renders[name] = {"hypotheses": propose_sequence(model, video_like(masks, video),
                                                                n_experts),
                                 "image_track": image_track, "truth": truth}
    return renders


def top_experts(render: dict, n_experts: int) -> dict:
    """A validation render with only the hypotheses of its top n_experts experts (the first
    2 n_experts: each pose and its flip). The gate probabilities are not renormalised over
    the n_experts, which changes every state's evidence by the same amount per frame, so
    the tracker's posteriors are as if the model had been asked for n_experts."""
    k = 2 * n_experts
    return {**render, "hypotheses": [replace(h, poses=h.poses[:k], log_evidence=h.log_evidence[:k])
                                     for h in render["hypotheses"]]}


def canonical_statistics(renders: dict) -> dict:
    """The canonical chain's priors (regressor.canonical_priors.CanonicalPriors: the switch
    probabilities, by_front and its overall rate) from
    validation_renders of a model with limbs and a side classifier (canonical hypotheses,
    which keep the classifier's probability). The true member: the nearer the truth over the
    54 angles (raw_is_nearer)."""
    from tracker.tracks.hypotheses import CANONICAL_FRONT_EDGES, bin_index, member_probability
    leave, count = np.zeros(2), np.zeros(2)
    canonical_true, p_member = [], []
    for render in renders.values():
        hyps = render["hypotheses"]
        if not all(h.canonical and h.front is not None for h in hyps):
            raise ValueError("canonical statistics need a model with limbs and a side classifier")
        member = np.array([h.poses[0] for h in hyps])
        true = raw_is_nearer(member, render["truth"])          # the member, not its flip
        state = (~true).astype(int)
        for s in (0, 1):                    # frames in state s, and those followed by the other
            count[s] += np.sum(state[:-1] == s)
            leave[s] += np.sum((state[:-1] == s) & (state[1:] != s))
        p_member.append(member_probability(member, [h.front for h in hyps]))
        canonical_true.append(true)

    def table(edges, x, y):
        b = bin_index(edges, x)
        return [round(float(y[b == k].mean()), 3) if np.any(b == k) else None
                for k in range(len(edges))], [int(np.sum(b == k)) for k in range(len(edges))]
    canonical_true, p_member = np.concatenate(canonical_true), np.concatenate(p_member)
    by_front, n_front = table(CANONICAL_FRONT_EDGES, p_member, canonical_true)
    return {"switch_probability": [round(float(leave[0] / max(count[0], 1)), 3),
                                   round(float(leave[1] / max(count[1], 1)), 3)],
            "by_front": by_front, "frames_by_front": n_front,
            "canonical_overall": round(float(canonical_true.mean()), 3)}


def prior_files(bvh_dir: str | Path, check: bool = True) -> list[Path]:
    """The BVH files the priors are learned on: the training's validation trials and 07_12
    (held out of training), each rendered four ways by validation_renders: 28 renders.
    check: ValueError naming the first that is missing."""
    from lab.training import VALIDATION_TRIALS
    files = [Path(bvh_dir) / f"{t}.bvh" for t in VALIDATION_TRIALS + ("07_12",)]
    if not check:
        return files
    missing = [f for f in files if not f.is_file()]
    if missing:
        raise ValueError(f"learning the canonical priors needs {missing[0]}")
    return files


def learn_canonical_priors(model, bvh_files) -> tuple[CanonicalPriors, dict]:
    """The canonical chain's priors for a model with limbs and a side classifier, learned on
    validation_renders of bvh_files (prior_files), and canonical_statistics' dict they came
    from (with each bin's frame count)."""
    from tracker.tracks.hypotheses import CANONICAL_FRONT_EDGES
    if not model.gives_canonical_pairs:
        raise ValueError("canonical priors need a model with limbs and a side classifier")
    stats = canonical_statistics(validation_renders(model, bvh_files))
    return priors_from_statistics(stats, CANONICAL_FRONT_EDGES), stats


#: Probabilities learned as 0 or 1 are taken as this far from them.
_FLOOR = 1e-3


def priors_from_statistics(stats: dict, front_edges) -> CanonicalPriors:
    """The priors from canonical_statistics' dict with the edges its table was binned by. A
    bin without frames (None) takes the overall rate: no evidence either way. Overall and
    switch rates of 0 or 1 (a member always right or always wrong on the renders, a state
    never left) are taken as 0.001 and 0.999: no evidence is ever certain, and neither state
    is unreachable."""
    overall = float(np.clip(stats["canonical_overall"], _FLOOR, 1.0 - _FLOOR))
    return CanonicalPriors(switch=tuple(float(np.clip(p, _FLOOR, 1.0 - _FLOOR))
                                        for p in stats["switch_probability"]),
                           front_edges=tuple(front_edges),
                           by_front=[overall if p is None else p for p in stats["by_front"]],
                           overall=overall)


def replay_heading_rms(model, render: dict, camera: CameraOptions = CameraOptions(),
                       **tracker_options) -> float:
    """Filtered heading RMS (deg) of FrontBackTracker (with tracker_options, e.g.
    evidence_weight) over one of validation_renders' sequences."""
    bank = FrontBackTracker(kalman_factory(model), camera.fps, keep_history=False,
                            **{**chain_options(model), **tracker_options})
    filtered = np.array([bank.step(h).filtered for h in render["hypotheses"]])
    err = wrap_deg(pose_angles(filtered)[:, 0] - pose_angles(render["truth"])[:, 0])
    return float(np.sqrt(np.mean(err ** 2)))


def choose_weights(model, renders: dict, evidence_weights=(0.4, 0.6, 0.8, 1.0, 2.0, 3.0)
                   ) -> tuple[float, dict]:
    """The evidence_weight with the lowest mean filtered heading RMS over renders
    (validation_renders); and every weight -> per-sequence RMS table."""
    table = {ew: {name: replay_heading_rms(model, r, evidence_weight=ew)
                  for name, r in renders.items()} for ew in evidence_weights}
    best = min(table, key=lambda k: np.mean(list(table[k].values())))
    return best, table
