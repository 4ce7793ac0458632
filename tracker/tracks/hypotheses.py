"""Front/back hypotheses carried over time: which of the regressor's poses is the true one.
A silhouette cannot tell a body from its reflection in depth (pose_vector.front_back_flip). Each
frame gives K hypotheses: the pose and its flip (per expert for a mixture), or the limbs'
canonical member and its flip. A hidden Markov model over them, one Kalman filter per state (a
GPB / IMM filter bank; its recursion: docs/tuning.md), gives the most probable state's filtered
pose, or the Viterbi path RTS-smoothed."""
from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from regressor.angles import heading_norm, wrap_deg
from regressor.canonical_priors import CanonicalPriors
from regressor.estimator import PoseEstimates, PoseEstimator
from regressor.hypothesis_path import most_probable_path
from regressor.pose_model import DEFAULT_TRAINING_FPS
from sequences.pose_vector import front_back_flip, heading_deg
from tracker.tracks.mirror_limbs import mirror_mean

#: (P(raw -> flip), P(flip -> raw)) per frame at 30 fps (scripts/learn_hypothesis_priors.py).
SWITCH_PROBABILITY = (0.117, 0.248)
EVIDENCE_WEIGHT = 1.0                    # exponent per frame of the regressor's evidence
CLOSE_PROBABILITY = 0.2                  # the runner-up is reported from this probability on

#: (P(canonical -> flip), P(flip -> canonical)) per frame, for a model without its own priors.
CANONICAL_SWITCH_PROBABILITY = (0.025, 0.041)
#: EVIDENCE_WEIGHT for the canonical chain: above 1, since a flip's filter, restarted from
#: the member's every frame, scores a few nats below it and weaker evidence never catches up.
CANONICAL_EVIDENCE_WEIGHT = 2.0
#: P(the canonical member is the true one | the side classifier's probability for it in
#: [CANONICAL_FRONT_EDGES[b], next edge)), and overall: the classifier is over-confident.
CANONICAL_FRONT_EDGES = (0.0, 0.1, 0.3, 0.5, 0.7, 0.9)
DEFAULT_CANONICAL_PRIORS = CanonicalPriors(
    switch=CANONICAL_SWITCH_PROBABILITY, front_edges=CANONICAL_FRONT_EDGES,
    by_front=(0.407, 0.634, 0.608, 0.633, 0.654, 0.797), overall=0.624)
#: Experts asked of a mixture model (more added wrong headings more often than right ones).
DEFAULT_EXPERTS = 1
_FLOOR = 1e-3                            # no evidence is ever certain
#: members_over_time's evidence (how near each member's heading is) and step variance (deg^2,
#: the 53 angles' summed squared step per frame); only their ratio matters (docs/tuning.md).
MEMBER_HEADING_SD_DEG = 30.0
MEMBER_STEP_VARIANCE = 400.0


@dataclass
class Hypotheses:
    """One frame's candidates: poses (K, 55), log_evidence (K,) log likelihood ratios, raw (55,)
    the regressor's pose, limbs (55,) the canonical member or None; canonical: the poses are it
    and its flip; front: the side classifier's P(facing the camera's half)."""

    poses: np.ndarray
    log_evidence: np.ndarray
    raw: np.ndarray
    limbs: np.ndarray | None = None
    canonical: bool = False
    front: float | None = None


def pick_member(limbs: np.ndarray, heading_deg) -> np.ndarray:
    """Of each canonical pose (55,) or (T, 55) and its flip, the one whose heading is nearer
    heading_deg (scalar or (T,), degrees), as limbs."""
    limbs = np.asarray(limbs, dtype=np.float64)
    h = np.radians(np.asarray(heading_deg, dtype=np.float64))
    direction = np.stack([np.cos(h), np.sin(h)], axis=-1)
    flips = front_back_flip(limbs)
    keep = (limbs[..., :2] * direction).sum(-1) >= (flips[..., :2] * direction).sum(-1)
    return np.where(np.asarray(keep)[..., None], limbs, flips)


def bin_index(edges, x) -> np.ndarray:
    """The bin b of each x with edges[b] <= x < edges[b + 1], clipped to the first and last."""
    b = np.searchsorted(edges, np.asarray(x, float), side="right") - 1
    return np.clip(b, 0, len(edges) - 1)


def _table(edges, values, x) -> np.ndarray:
    """values[bin_index(edges, x)] (one value per edge), clipped away from 0 and 1."""
    return np.clip(np.asarray(values)[bin_index(edges, x)], _FLOOR, 1.0 - _FLOOR)


def canonical_hypotheses(raw: np.ndarray, limbs: np.ndarray, front: float,
                         priors: CanonicalPriors = DEFAULT_CANONICAL_PRIORS) -> Hypotheses:
    """The limbs' canonical member (55,) and its flip, weighed by the side classifier's
    probability ``front`` that the body faces the camera's half (calibrated: priors.by_front).
    Their heading norm is raw's (55,), for the filters' R inflation and the ambiguous flag."""
    limbs = np.asarray(limbs, dtype=np.float64)
    pair = np.stack([limbs, front_back_flip(limbs)])
    unit = pair[:, :2] / np.maximum(np.linalg.norm(pair[:, :2], axis=1, keepdims=True), 1e-9)
    pair[:, :2] = unit * heading_norm(raw)
    q = _table(priors.front_edges, priors.by_front, member_probability(pair[0], front))
    evidence = np.log([q / priors.overall, (1 - q) / (1 - priors.overall)])
    return Hypotheses(pair, evidence, np.asarray(raw, float), limbs, canonical=True,
                      front=float(front))


def member_probability(members: np.ndarray, front) -> np.ndarray:
    """The side classifier's probability (...) for each canonical member (..., 55) from its
    probability front (...) that the body faces the camera's half (cos >= 0)."""
    front = np.asarray(front, dtype=np.float64)
    return np.where(np.asarray(members)[..., 0] >= 0, front, 1.0 - front)


def canonical_priors(estimator: PoseEstimator) -> CanonicalPriors:
    """The estimator's canonical priors (PoseModel.canonical_priors), else the default."""
    return estimator.canonical_priors or DEFAULT_CANONICAL_PRIORS


def chain_options(estimator: PoseEstimator) -> dict:
    """FrontBackTracker's switch, evidence_weight and reference_fps for the estimator."""
    canonical = estimator.gives_canonical_pairs
    switch = canonical_priors(estimator).switch if canonical else SWITCH_PROBABILITY
    weight = CANONICAL_EVIDENCE_WEIGHT if canonical else EVIDENCE_WEIGHT
    return {"switch": switch, "evidence_weight": weight, "reference_fps": estimator.training_fps}


def hypotheses_from(estimates: PoseEstimates,
                    priors: CanonicalPriors = DEFAULT_CANONICAL_PRIORS) -> list[Hypotheses]:
    """Each row's hypotheses from a model's answer: with limbs and the side classifier's
    front probability, :func:`canonical_hypotheses` (limbs first averaged with the mirror
    images' when given); else each expert's pose and its flip (flip_hypotheses)."""
    poses, gate, limbs = estimates.poses, estimates.probabilities, estimates.limbs
    if limbs is not None and estimates.mirror_limbs is not None:
        limbs = mirror_mean(limbs, estimates.mirror_limbs)
    if estimates.front is not None and limbs is not None:
        return [canonical_hypotheses(p[0], lb, f, priors)
                for p, lb, f in zip(poses, limbs, estimates.front)]
    from tracker.tracks.flip_hypotheses import with_flips   # models without a side classifier
    limbs = [None] * len(poses) if limbs is None else limbs
    return [with_flips(np.asarray(p, float), np.asarray(g, float), lb)
            for p, g, lb in zip(poses, gate, limbs)]


def transition_matrix(K: int, switch=SWITCH_PROBABILITY) -> np.ndarray:
    """A (K, K) over states k = 2 i + f (expert slot i, flipped f): the flip part from switch,
    the slot part uniform (experts are listed by gate probability, not by identity)."""
    a, b = switch
    flip = np.array([[1 - a, a], [b, 1 - b]])
    m = K // 2
    return np.kron(np.full((m, m), 1.0 / m), flip)


@functools.lru_cache(maxsize=32)
def _log_transitions(K: int, switch: tuple[float, float]) -> np.ndarray:
    """log transition_matrix(K, switch), made once per (K, switch) (read-only: shared)."""
    log_A = np.log(transition_matrix(K, switch))
    log_A.flags.writeable = False
    return log_A


@dataclass
class Decision:
    """One frame's most probable state's filtered pose (55,), ambiguous flag, index and
    probability; the runner-up's pose (55,) and probability from CLOSE_PROBABILITY on."""

    filtered: np.ndarray
    ambiguous: bool
    state: int
    probability: float
    runner_up: np.ndarray | None = None
    runner_up_probability: float | None = None


@dataclass
class _Frame:
    poses: np.ndarray            # (K, 55)
    evidence: np.ndarray         # (K,) log
    link: np.ndarray | None      # (K, K) log A + innovation log-likelihoods, None at t = 0
    raw: np.ndarray              # (55,) the regressor's own pose (limb input without a head)
    limbs: np.ndarray | None     # (55,) the limb head's pose (before picking), or None


@dataclass
class FrontBackTracker:
    """Per-track front/back (and expert) hypotheses over time (see the module docstring).
    filter_factory: fps -> a pose filter (tracker.pipeline.FilterFactory); switch (P(raw -> flip),
    P(flip -> raw)) and evidence_weight: per frame at reference_fps; keep_history: keep every frame
    for viterbi_path/smoothed; limb_filter_factory: fps -> a filter of the body angles, stepped on
    the raw pose or the limb member nearer the decided heading (None: the chosen state's)."""

    filter_factory: Callable[[float], object]
    fps: float
    switch: tuple[float, float] = SWITCH_PROBABILITY
    evidence_weight: float = EVIDENCE_WEIGHT
    reference_fps: float = DEFAULT_TRAINING_FPS
    keep_history: bool = True
    limb_filter_factory: Callable[[float], object] | None = None
    filters: list = field(default_factory=list)
    limb_filter: object | None = None
    log_alpha: np.ndarray | None = None
    history: list[_Frame] = field(default_factory=list)

    def step(self, hypotheses: Hypotheses) -> Decision:
        """Take one frame's hypotheses; returns the decision."""
        poses = hypotheses.poses
        K = len(poses)
        rate = self.frame_rate_ratio
        evidence = rate * self.evidence_weight * hypotheses.log_evidence
        log_A = _log_transitions(K, self.frame_switch)
        if self.log_alpha is None or len(self.filters) != K:
            self.filters = self._new_filters(K)
            self.log_alpha, link = _log_stationary(log_A) + evidence, None
        else:
            ll = np.array([f.log_likelihoods(poses) for f in self.filters])
            link = log_A + rate * ll
            scores = self.log_alpha[:, None] + link
            self.filters = self._continue(scores.argmax(axis=0))
            self.log_alpha = _logsumexp(scores, axis=0) + evidence
        self.log_alpha -= _logsumexp(self.log_alpha)
        if self.keep_history:
            limbs = None if hypotheses.limbs is None else np.array(hypotheses.limbs, float)
            self.history.append(_Frame(np.array(poses, float), evidence, link,
                                       np.array(hypotheses.raw, float), limbs))
        outputs = [f.step(pose) for f, pose in zip(self.filters, poses)]
        prob = np.exp(self.log_alpha)
        order = np.argsort(-prob)
        best = int(order[0])
        filtered = outputs[best][0]
        if self.limb_filter_factory is not None:
            if self.limb_filter is None:
                self.limb_filter = self.limb_filter_factory(self.fps)
            source = (hypotheses.raw if hypotheses.limbs is None
                      else pick_member(hypotheses.limbs, heading_deg(filtered[None])[0]))
            # The limb filter measures the decided heading, not the source's: its R couples
            # heading and joints, and a heading innovation would pull the limbs.
            source = with_body_angles(filtered, source)
            filtered = with_body_angles(filtered, self.limb_filter.step(source)[0])
        decision = Decision(filtered, bool(outputs[best][1]), best, float(prob[best]))
        if K > 1 and prob[order[1]] >= CLOSE_PROBABILITY:
            decision.runner_up = outputs[order[1]][0]
            decision.runner_up_probability = float(prob[order[1]])
        return decision

    @property
    def frame_rate_ratio(self) -> float:
        """reference_fps / fps: the exponent on evidence, likelihoods and switches."""
        return self.reference_fps / self.fps

    @property
    def frame_switch(self) -> tuple[float, float]:
        """Switch probabilities per frame at fps: 1 - (1 - p)^ratio (the same per second)."""
        rate = self.frame_rate_ratio
        if rate == 1.0:
            return tuple(self.switch)
        return tuple(float(-np.expm1(rate * np.log1p(-p))) for p in self.switch)

    def _new_filters(self, K: int) -> list:
        """K new filters, copies of one: they share what does not depend on the measurements."""
        first = self.filter_factory(self.fps)
        return [first] + [first.copy() for _ in range(K - 1)]

    def _continue(self, predecessor: np.ndarray) -> list:
        """Filters for the new states: state j continues predecessor[j]'s (a copy if taken)."""
        out = []
        for k, i in enumerate(predecessor):
            f = self.filters[int(i)]
            if i in predecessor[:k]:
                f = f.copy()
            out.append(f)
        return out

    def viterbi_path(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """The most probable state sequence (n,) int over history[start:stop] alone."""
        frames = self.history[start:stop]
        if not frames:
            return np.zeros(0, dtype=np.int64)
        log_A = _log_transitions(len(frames[0].poses), self.frame_switch)
        delta = _log_stationary(log_A) + frames[0].evidence
        back = []
        for frame in frames[1:]:
            scores = delta[:, None] + frame.link
            back.append(scores.argmax(axis=0))
            delta = scores.max(axis=0) + frame.evidence
        path = [int(delta.argmax())]
        for pointers in reversed(back):
            path.append(int(pointers[path[-1]]))
        return np.array(path[::-1], dtype=np.int64)

    def smoothed(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """RTS-smoothed poses (n, 55) of the Viterbi path's hypotheses of history[start:stop];
        with a limb_filter_factory the body angles are its smoothing of the raw poses or the
        limb members' most probable chain (members_over_time), under the smoothed heading."""
        frames = self.history[start:stop]
        chosen = [frame.poses[s] for frame, s in zip(frames, self.viterbi_path(start, stop))]
        out = self.filter_factory(self.fps).rts_smooth(np.array(chosen))
        if self.limb_filter_factory is not None and len(out):
            raws = np.array([frame.raw for frame in frames])
            if all(frame.limbs is not None for frame in frames):
                raws = members_over_time(np.array([frame.limbs for frame in frames]),
                                         heading_deg(out), self.frame_rate_ratio)
            raws = with_body_angles(out, raws)          # the decided heading, as online
            out = with_body_angles(out, self.limb_filter_factory(self.fps).rts_smooth(raws))
        return out


def members_over_time(limbs, headings_deg, frame_rate_ratio: float = 1.0,
                      step_variance: float = MEMBER_STEP_VARIANCE) -> np.ndarray:
    """Of each frame's canonical pose and its flip (limbs (T, 55), in time order), the ones on
    the most probable chain (T, 55), for the smoothed outputs (in profile the headings nearly
    meet, so pick_member may not say): a member's log evidence is a Gaussian's (sd
    MEMBER_HEADING_SD_DEG) of its heading's distance to headings_deg (T,) times frame_rate_ratio;
    each step costs the squared change of the 53 body angles (degrees) over 2 step_variance."""
    limbs = np.asarray(limbs, dtype=np.float64)
    headings = np.asarray(headings_deg, dtype=np.float64)
    if limbs.ndim != 2 or limbs.shape[1] != 55 or headings.shape != (len(limbs),):
        raise ValueError(f"limbs must be (T, 55) and headings (T,), got {limbs.shape} and "
                         f"{headings.shape}")
    if len(limbs) == 0:
        return limbs.copy()
    pair = np.stack([limbs, front_back_flip(limbs)], axis=1)                 # (T, 2, 55)
    off = wrap_deg(heading_deg(pair.reshape(-1, 55)).reshape(-1, 2) - headings[:, None])
    log_weight = -frame_rate_ratio * off ** 2 / (2.0 * MEMBER_HEADING_SD_DEG ** 2)
    path = most_probable_path(pair[:, :, 2:], log_weight, step_variance, angles_deg=True)
    return pair[np.arange(len(pair)), path]


def with_body_angles(pose: np.ndarray, limbs: np.ndarray) -> np.ndarray:
    """pose (..., 55) with its 53 body angles (entries 2..54) taken from limbs (..., 55)."""
    out = np.array(pose, dtype=np.float64, copy=True)
    out[..., 2:] = np.asarray(limbs)[..., 2:]
    return out


def _log_stationary(log_A: np.ndarray) -> np.ndarray:
    """log of the stationary distribution (K,) of the transition matrix exp(log_A) (K, K)."""
    return np.log(np.linalg.matrix_power(np.exp(log_A), 256)[0])


def _logsumexp(x: np.ndarray, axis=None) -> np.ndarray:
    top = np.max(x, axis=axis, keepdims=True)
    out = top + np.log(np.exp(x - top).sum(axis=axis, keepdims=True))
    return out.squeeze(axis) if axis is not None else out.reshape(())
