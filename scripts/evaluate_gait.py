"""Are left and right legs kept apart? Gait figures of held-out walks seen from fixed cameras.

    python scripts/evaluate_gait.py [--model regressor/models/default_model.npz] \
        [--trials 02_02 08_03] [--azimuths 0 45 90 135] [--variants shipped no_mirror] \
        [--cache-dir cache/gait] [--json out.json]

Each held-out CMU walk (lab.training.VALIDATION_TRIALS) is rendered as a 320x240
video from a fixed camera at each azimuth relative to its walking direction (0: walking
towards the camera, 90 and 270: in profile from either side), cached in --cache-dir,
and run through the ``track`` loop (lab.evaluation.track_longest's, the tracker
kept to read its hypotheses). Knee flexion of each output against the truth
(sequences.gait_measures: timing, alternation, range, our L-R correlation), for:

  raw       the main head's pose (the regressor's average of a silhouette's bodies)
  member    the limb networks' canonical member (after the mirror image's average)
  best2     per frame the nearer of the member and its front/back flip (an oracle: does
            either hypothesis carry the right leg configuration?)
  truehead  the member or flip whose heading is nearer the TRUE heading (an oracle: how far
            a perfect heading would get, the way the tracker picks)
  picked    the member or flip the online tracker takes (nearer the filtered heading),
            before the limb filter (NaN when the video held more than one track)
  filtered  what ``track`` streams
  chain     the members chosen offline over the smoothed heading (hypotheses.members_over_time),
            before the limb smoother
  smoothed  what ``track --smooth`` writes

Variants patch the tracker for one run (as scripts/ablation.py does; VARIANTS): shipped;
no_mirror (no mirror-image average of the limbs); headqF (heading process noise x F);
predictW (online member by the limb filter's prediction, weight W); chain2_V (offline
members by a second-order chain); unfoldP (offline members by unfolding the legs within P
degrees of profile); unfold20_limbrF (that, limb filter R x F); signchainC (offline members
by heading evidence plus a C-nat cost for a leg-sign change off a leg crossing). The figures
and what they showed: docs/left_right.md.

A missing trial, a model or video that cannot be read: one line on stderr, exit 2 or 1.
"""
from __future__ import annotations

import json
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.signal import argrelmin
from threadpoolctl import threadpool_limits

from regressor.angles import wrap_deg
from regressor.errors import SilhouettePoseError
from regressor.pose_model import load_pose_model
from sequences.bvh import read_bvh
from sequences.gait_measures import best_of, gait_measures, knee_flexion, swapped
from sequences.pose_vector import front_back_flip, heading_deg, pose_vector_names
from sequences.video import load_truth, replace_video
from tracker.tracks import hypotheses
from tracker.tracks.hypotheses import MEMBER_HEADING_SD_DEG
from tracker.one_line_parser import OneLineParser, stops_in_one_line
from lab.evaluation import CameraOptions, run_longest_track, write_camera_video
from tracker.pipeline import HEADING_Q_SCALE, LIMB_R_SCALE, TrackerSettings

REPO = Path(__file__).resolve().parents[1]

NAMES = pose_vector_names()
OUTPUTS = ("raw", "member", "best2", "truehead", "picked", "filtered", "chain", "smoothed")
FIGURES = ("timing", "alternation", "range", "lr_corr")


def walking_azimuth(bvh: Path, fps: float = 30.0) -> float:
    """The world azimuth (degrees, the renderer's: atan2(x, z)) of the walk's overall
    displacement from its first to its last frame."""
    root = read_bvh(bvh, fps=fps).root_position
    d = root[-1] - root[0]
    return float(np.degrees(np.arctan2(d[0], d[2])))


def gait_video(trial: str, relative_deg: float, bvh_dir: Path, cache: Path) -> Path:
    """The trial's video from a fixed camera relative_deg from its walking direction, rendered
    once into cache (with its ground-truth sidecar)."""
    path = cache / f"{trial}_az{relative_deg:g}.mp4"
    if not path.is_file():
        bvh = bvh_dir / f"{trial}.bvh"
        motion = read_bvh(bvh, fps=30.0)
        cam = CameraOptions(azimuth_deg=walking_azimuth(bvh) + relative_deg)
        cache.mkdir(parents=True, exist_ok=True)
        replace_video(path, lambda partial: write_camera_video(partial, motion, cam))
    return path


def track(video: Path, model, settings: TrackerSettings) -> dict:
    """The track loop on a one-person video; its longest track's frame indices (n,) and each
    OUTPUTS' poses (n, 55), plus the member pairs (n, 2, 55) the hypotheses held."""
    tracker, recorder, tid = run_longest_track(video, model, settings)
    poses = recorder.by_track()[tid]
    chain = tracker.tracks[tid].hypotheses
    frames = chain.history
    if len(frames) != len(poses):
        raise RuntimeError(f"{video}: {len(frames)} chain frames for {len(poses)} poses")
    filtered = np.array([p.filtered for p in poses])
    smoothed = tracker.smoothed_track(tid)
    limbs = np.array([f.limbs for f in frames])
    pairs = np.stack([limbs, front_back_flip(limbs)], axis=1)
    picked, chosen = np.array(RECORD["picked"]), RECORD["chain"]
    if len(chosen) != 1:
        raise RuntimeError(f"{video}: {len(chosen)} chains recorded")
    if len(picked) != len(poses):     # picks of other (shorter) tracks too: not this one's
        picked = np.full((len(poses), 55), np.nan)
    return {"index": np.array([p.frame_index for p in poses]),
            "raw": np.array([p.raw for p in poses]), "member": limbs, "pairs": pairs,
            "picked": picked, "filtered": filtered, "chain": chosen[0], "smoothed": smoothed,
            "evidence": np.array([f.evidence for f in frames]),
            "viterbi": chain.viterbi_path()}


def figures(out: dict, truth: np.ndarray) -> dict:
    """Gait figures of each output (OUTPUTS) against the truth poses (n, 55)."""
    tk = knee_flexion(truth)
    res = {}
    for name in OUTPUTS:
        if name == "best2":
            pk = knee_flexion(out["pairs"][:, 0])
            est = best_of(np.stack([pk, swapped(pk)], axis=1), tk)
        elif name == "truehead":
            est = knee_flexion(_ORIGINAL["pick_member"](out["member"], heading_deg(truth)))
        elif not np.isfinite(out[name]).all():              # picked of a multi-track video
            res[name] = dict.fromkeys(FIGURES, np.nan)
            continue
        else:
            est = knee_flexion(out[name])
        res[name] = gait_measures(est, tk)
    return res


# ------------------------------------------------------------------ variants
#
# Each variant is (context manager patching the tracker for one run, TrackerSettings
# overrides). The patches replace tracker.tracks.hypotheses' module-level pick_member (online choice
# of the limbs' member) and members_over_time (offline chain of members); RECORD keeps what
# the tracker took, so the "picked" and "chain" rows are the run's own.

RECORD: dict[str, list] = {"picked": [], "chain": []}
_CURRENT: list = []              # the FrontBackTracker stepping now (its limb filter)
_ORIGINAL = {"pick_member": hypotheses.pick_member,
             "members_over_time": hypotheses.members_over_time,
             "step": hypotheses.FrontBackTracker.step}


def _heading_log_weight(pair: np.ndarray, heading: np.ndarray, sd_deg: float) -> np.ndarray:
    """log weight (..., 2) of each member of pair (..., 2, 55) by how near its heading is to
    heading (...,) degrees: a Gaussian of sd_deg, as hypotheses.members_over_time's evidence."""
    off = wrap_deg(heading_deg(pair.reshape(-1, 55)).reshape(pair.shape[:-1])
                   - np.asarray(heading)[..., None])
    return -off ** 2 / (2.0 * sd_deg ** 2)


def predicted_pick(weight: float, sd_deg: float = MEMBER_HEADING_SD_DEG):
    """pick_member by the limb filter's prediction: of the member and its flip, the one with
    the larger weight * innovation log-likelihood under the body angles' Kalman filter
    (constant velocity: a leg swap breaks the motion's continuation) + the heading's log
    weight (as the offline chain). Before the filter's first step: the heading alone."""
    def pick(limbs, heading):
        limbs = np.asarray(limbs, dtype=np.float64)
        pair = np.stack([limbs, front_back_flip(limbs)])
        score = _heading_log_weight(pair, np.asarray(heading), sd_deg)
        chain = _CURRENT[-1] if _CURRENT else None
        lf = getattr(chain, "limb_filter", None)
        if lf is not None and weight > 0:
            h = np.radians(float(heading))
            head = np.array([np.cos(h), np.sin(h)])
            cands = hypotheses.with_body_angles(np.concatenate([head, limbs[2:]])[None]
                                                .repeat(2, 0), pair)
            score = score + weight * lf.log_likelihoods(cands)
        return pair[int(np.argmax(score))]
    return pick


def second_order_chain(acc_var: float, sd_deg: float = MEMBER_HEADING_SD_DEG):
    """members_over_time by a second-order chain: each member's evidence is its heading's
    (as hypotheses.members_over_time), each step costs the squared change of the 53 angles' velocity
    (second difference, wrapped; deg^2 per frame^2 summed) over 2 acc_var, so a swap that
    reverses the legs' motion costs more than one that continues it. Viterbi over the pairs
    (member at t-1, member at t)."""
    def chain(limbs, headings, frame_rate_ratio=1.0, **_):
        limbs = np.asarray(limbs, dtype=np.float64)
        T = len(limbs)
        pair = np.stack([limbs, front_back_flip(limbs)], axis=1)          # (T, 2, 55)
        lw = frame_rate_ratio * _heading_log_weight(pair, headings, sd_deg)  # (T, 2)
        if T < 3:
            return pair[np.arange(T), lw.argmax(axis=1)]
        X = pair[:, :, 2:]
        d = wrap_deg(X[1:, None, :, :] - X[:-1, :, None, :])     # (T-1, a, b, 53): b at t+1
        # delta[a, b]: best log score of a path ending with a at t-1, b at t
        delta = lw[0][:, None] + lw[1][None, :]
        back = []
        for t in range(1, T - 1):
            acc = d[t][None, :, :, :] - d[t - 1][:, :, None, :]     # (a, b, c, 53)
            cost = (acc ** 2).sum(-1) / (2.0 * acc_var)
            scores = delta[:, :, None] - cost                       # (a, b, c)
            arg = scores.argmax(axis=0)                             # (b, c): best a
            delta = scores.max(axis=0) + lw[t + 1][None, :]
            back.append(arg)
        b, c = np.unravel_index(int(delta.argmax()), delta.shape)
        path = [c, b]
        for arg in reversed(back):
            a = int(arg[path[-1], path[-2]])
            path.append(a)
        path = np.array(path[::-1])
        return pair[np.arange(T), path]
    return chain


def unfolded_chain(profile_deg: float = 20.0, order: int = 3, depth: float = 0.5):
    """members_over_time for gait in profile, by unfolding the legs: the members' thigh
    difference g = LeftUpLeg_x - RightUpLeg_x (degrees; the flip's is -g) has |g| with a
    minimum at each leg crossing (local minima of |g| smoothed over 3 frames, within order
    frames, below depth x its median); between crossings the true g keeps one sign, and it
    changes sign at each. So the members are taken with alternating signs of g segment by
    segment, and of the two such sequences the one whose headings are nearer the smoothed
    heading over the whole track (summed squared error). Frames whose smoothed heading is
    more than profile_deg from profile keep the shipped chain's choice (the heading decides
    there)."""
    left, right = (NAMES.index(n) for n in ("LeftUpLeg_x", "RightUpLeg_x"))

    def chain(limbs, headings, frame_rate_ratio=1.0, **kw):
        limbs = np.asarray(limbs, dtype=np.float64)
        headings = np.asarray(headings, dtype=np.float64)
        shipped = _ORIGINAL["members_over_time"](limbs, headings, frame_rate_ratio, **kw)
        T = len(limbs)
        if T < 2 * order + 1:
            return shipped
        pair = np.stack([limbs, front_back_flip(limbs)], axis=1)
        g = limbs[:, left] - limbs[:, right]
        a = uniform_filter1d(np.abs(g), 3)
        crossings = [i for i in argrelmin(a, order=order)[0] if a[i] < depth * np.median(a)]
        segment = np.zeros(T, dtype=np.int64)
        for i in crossings:
            segment[i:] += 1
        sel = (np.sign(g) != np.where(segment % 2 == 0, 1.0, -1.0)).astype(np.int64)
        cands = [pair[np.arange(T), sel], pair[np.arange(T), 1 - sel]]
        errs = [(wrap_deg(heading_deg(c) - headings) ** 2).sum() for c in cands]
        unfolded = cands[int(np.argmin(errs))]
        near = np.abs(wrap_deg(np.abs(headings) - 90.0)) <= profile_deg
        return np.where(near[:, None], unfolded, shipped)
    return chain


def gait_sign_chain(cost: float, sd_deg: float = MEMBER_HEADING_SD_DEG, order: int = 3,
                    depth: float = 0.5):
    """members_over_time as a two-state chain over (member, flip): each frame's evidence is
    its heading's (as members_over_time, a Gaussian of sd_deg about the smoothed heading);
    a step costs `cost` nats when the chosen body's thigh difference g (unfolded_chain's)
    changes sign between frames with no leg crossing between them, or keeps its sign across
    a crossing (a crossing: a minimum of |g| smoothed over 3 frames, within order frames,
    below depth x its median, placed between the minimum's frame and its neighbour of smaller
    |g|). Away from profile the heading outweighs it; in profile it unfolds the legs."""
    left, right = (NAMES.index(n) for n in ("LeftUpLeg_x", "RightUpLeg_x"))

    def chain(limbs, headings, frame_rate_ratio=1.0, **_):
        limbs = np.asarray(limbs, dtype=np.float64)
        T = len(limbs)
        pair = np.stack([limbs, front_back_flip(limbs)], axis=1)
        lw = frame_rate_ratio * _heading_log_weight(pair, np.asarray(headings), sd_deg)
        g = limbs[:, left] - limbs[:, right]
        a = uniform_filter1d(np.abs(g), 3)
        crossing = np.zeros(T, dtype=bool)           # crossing[t]: between frames t-1 and t
        for i in argrelmin(a, order=order)[0]:
            if a[i] < depth * np.median(a):
                # the zero lies between the minimum and its neighbour of smaller |g|
                after = i + 1 < T and (i == 0 or abs(g[i + 1]) < abs(g[i - 1]))
                crossing[i + 1 if after else i] = True
        sign = np.stack([np.sign(g), -np.sign(g)], axis=1)             # (T, 2) chosen g sign
        delta, back = lw[0].copy(), []
        for t in range(1, T):
            flips = sign[t - 1][:, None] != sign[t][None, :]          # (i, j)
            bad = flips != crossing[t]
            scores = delta[:, None] - cost * bad
            back.append(scores.argmax(axis=0))
            delta = scores.max(axis=0) + lw[t]
        path = [int(delta.argmax())]
        for arg in reversed(back):
            path.append(int(arg[path[-1]]))
        return pair[np.arange(T), np.array(path[::-1])]
    return chain


@contextmanager
def patched(pick=None, chain=None):
    """The tracker with pick_member / members_over_time replaced (None: the shipped ones),
    every choice recorded in RECORD."""
    pick = pick or _ORIGINAL["pick_member"]
    chain = chain or _ORIGINAL["members_over_time"]
    RECORD["picked"].clear()
    RECORD["chain"].clear()

    def record_pick(limbs, heading):
        out = pick(limbs, heading)
        RECORD["picked"].append(np.array(out))
        return out

    def record_chain(*a, **k):
        out = chain(*a, **k)
        RECORD["chain"].append(np.array(out))
        return out

    def step(self, *a, **k):
        _CURRENT.append(self)
        try:
            return _ORIGINAL["step"](self, *a, **k)
        finally:
            _CURRENT.pop()

    hypotheses.pick_member = record_pick
    hypotheses.members_over_time = record_chain
    hypotheses.FrontBackTracker.step = step
    try:
        yield
    finally:
        hypotheses.pick_member = _ORIGINAL["pick_member"]
        hypotheses.members_over_time = _ORIGINAL["members_over_time"]
        hypotheses.FrontBackTracker.step = _ORIGINAL["step"]


VARIANTS = {
    "shipped": (lambda: patched(), {}),
    "no_mirror": (lambda: patched(), {"mirror_limbs": False}),
}
for _f in (4.0, 16.0):
    VARIANTS[f"headq{_f:g}"] = (lambda: patched(), {"heading_q_scale": HEADING_Q_SCALE * _f})
for _w in (0.1, 0.3, 1.0):
    VARIANTS[f"predict{_w:g}"] = (lambda w=_w: patched(pick=predicted_pick(w)), {})
for _p in (20.0, 45.0, 90.0):
    VARIANTS[f"unfold{_p:g}"] = (lambda p=_p: patched(chain=unfolded_chain(p)), {})
for _f in (0.25, 0.5):
    VARIANTS[f"unfold20_limbr{_f:g}"] = (lambda: patched(chain=unfolded_chain(20.0)),
                                         {"limb_r_scale": LIMB_R_SCALE * _f})
for _c in (1.0, 3.0, 10.0):
    VARIANTS[f"signchain{_c:g}"] = (lambda c=_c: patched(chain=gait_sign_chain(c)), {})
VARIANTS["signchain1_limbr0.5"] = (lambda: patched(chain=gait_sign_chain(1.0)),
                                  {"limb_r_scale": LIMB_R_SCALE * 0.5})
for _v in (50.0, 200.0, 800.0):
    VARIANTS[f"chain2_{_v:g}"] = (lambda v=_v: patched(chain=second_order_chain(v)), {})


def _main(argv=None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", type=Path, default=REPO / "regressor/models/default_model.npz")
    ap.add_argument("--trials", nargs="+", default=["02_02", "08_03"])
    ap.add_argument("--azimuths", nargs="+", type=float, default=[0, 45, 90, 135])
    ap.add_argument("--variants", nargs="+", default=["shipped"], choices=sorted(VARIANTS))
    ap.add_argument("--bvh-dir", type=Path, default=REPO.parent / "shared/data/cmu/bvh")
    ap.add_argument("--cache-dir", type=Path, default=REPO / "cache/gait")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    for trial in args.trials:
        if not (args.bvh_dir / f"{trial}.bvh").is_file():
            ap.error(f"trial {trial}: no {args.bvh_dir / f'{trial}.bvh'}")
    try:
        model = load_pose_model(args.model)
    except (OSError, SilhouettePoseError) as exc:
        ap.error(f"--model {args.model}: {exc}")
    try:
        return _evaluate(args, model)
    except (OSError, ValueError, RuntimeError, SilhouettePoseError) as exc:
        print(f"evaluate_gait: error: {' '.join(str(exc).split()) or type(exc).__name__}",
              file=sys.stderr)
        return 1


def _evaluate(args, model) -> int:
    """The table (and --json) of the parsed options."""
    rows = []
    print(f"{'trial':6s} {'az':>4s} {'variant':10s} {'output':9s} "
          + " ".join(f"{c:>11s}" for c in FIGURES))
    with threadpool_limits(1):
        for trial in args.trials:
            for az in args.azimuths:
                video = gait_video(trial, az, args.bvh_dir, args.cache_dir)
                truth_all = load_truth(video)["pose"][:, 0]
                for variant in args.variants:
                    patch, overrides = VARIANTS[variant]
                    with patch():
                        out = track(video, model, TrackerSettings(**overrides))
                    res = figures(out, truth_all[out["index"]])
                    for name, m in res.items():
                        rows.append({"trial": trial, "azimuth": az, "variant": variant,
                                     "output": name, "frames": int(len(out["index"])), **m})
                        print(f"{trial:6s} {az:4g} {variant:10s} {name:9s} "
                              + " ".join(f"{m[c]:11.3f}" for c in FIGURES), flush=True)
                    head = heading_deg(truth_all[out["index"]])
                    print(f"{trial:6s} {az:4g} truth: L-R corr {res['raw']['truth_lr_corr']:.3f},"
                          f" heading {np.median(head):.0f} deg (median), {len(out['index'])} "
                          f"frames", flush=True)
    _summary(rows)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


def _summary(rows: list[dict]) -> None:
    """Mean figures per (azimuth, variant, output) over the trials."""
    keys = sorted({(r["azimuth"], r["variant"], r["output"]) for r in rows},
                  key=lambda k: (k[0], k[1], OUTPUTS.index(k[2])))
    print("\nmean over trials")
    for az, variant, output in keys:
        sel = [r for r in rows if (r["azimuth"], r["variant"], r["output"]) == (az, variant,
                                                                              output)]
        print(f"{'mean':6s} {az:4g} {variant:10s} {output:9s} "
              + " ".join(f"{np.mean([r[c] for r in sel]):11.3f}" for c in FIGURES))


main = stops_in_one_line("evaluate_gait", _main)       # Ctrl-C: one line, no traceback


if __name__ == "__main__":
    sys.exit(main())
