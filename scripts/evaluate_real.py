"""Evaluate the tracker on real videos with a 3-D reference: Pose2Sim's balancing and swings.

    python scripts/evaluate_real.py [--trial all|balancing|swings|FOLDER] [--model FILE]
        [--peer mediapipe [--peer-results DIR]] [--max-people N] [--roll calibration]
        [--zone-foreground sure] [--silhouettes background|segment|auto] [--json OUT]
        [--masks PNG] [--reference-masks cut|drawn|rendered]

For each trial (default both), a table of the 8 limb angles (knee and elbow flexion, hip and
shoulder as thigh and upper arm against the trunk; sequences.measures.limb_angles_from_points)
per view, averaged over the views and pooled: correlation with the reference and mean error,
beside the reference's own mean angle and the training-mean pose held still, and the heading;
with ``--peer mediapipe`` the same for MediaPipe Pose's 3-D world landmarks on the same frames
(run in-process, or read from ``scripts/run_mediapipe.py --out DIR`` with --peer-results DIR);
then a summary line per trial. Details (docs/real_video.md): runs ``track``'s pipeline on each
of the four views and prints, per view, knee and elbow flexion
error and correlation against the reference (beside two constants: the reference's own mean
flexion, which knows the answer's average, and the model's training-mean pose, what a regressor
that ignores its input would score), heading error against the reference, the number of
tracks, the 53 body angles against the project's body fitted to the reference keypoints
(sequences.keypoint_fit; error beside the training-mean pose's, correlation of the 8
most-moving angles), and across views the heading consistency (heading differences against
camera azimuth differences) and disagreement of the 53 body angles, and the novelty of the
subject's silhouettes (how unlike the training silhouettes they are: PoseEstimates.novelty;
--masks draws them); the flexion and heading figures also for the smoothed poses (track's
JSON and BVH) and the lagged ones (``track --lag 0.5``, the live view's). In each view the
subject is, per
frame, the tracked person whose box holds the reference's projected mid-hip (another person
walks behind in cam02; background subtraction splits the subject into several tracks in some
views).

``--reference-masks`` is a diagnostic, not a result: it reads the reference to correct the
silhouettes (lab.reference_masks: ``cut`` removes whatever lies off the body drawn
from the reference keypoints, ``drawn`` uses that drawing as the silhouette, ``rendered`` the
training renderer's body fitted to the reference and rendered through each calibrated camera),
to tell how much of the error the silhouettes cause and how much the regressor.

Options that cannot work (a --trial folder or --model file that does not exist, --max-people 0,
a --json or --masks that could not be written or that is one of the files read) are refused
before any work (exit 2); bad data (a trial file that is not text, a NaN in the calibration, a
view's video missing or undecodable) ends the run in one line naming the file (exit 1), also
before any work; Ctrl-C in one line (exit 130). --json and --masks are written whole or not at
all.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import NamedTuple

import numpy as np
from threadpoolctl import threadpool_limits

from regressor.errors import SilhouettePoseError
from regressor.pose_model import DEFAULT_MODEL_PATH, PoseModelError, load_pose_model
from sequences.keypoint_fit import KeypointFitError
from sequences.measures import (FLEXION_NAMES, MeasureError, flexion_deg, limb_angles_deg,
                                novelty_summary)
from sequences.mediapipe_peer import PeerError, keypoint_boxes, read_results, run_view
from sequences.pose2sim import (VIEWS, Pose2SimError, Trial, camera_roll_deg, mid_hip_px,
                                project_reference, reference_flexion, reference_heading_deg,
                                trial_roots, video_frames)
from sequences.pose2sim_measures import (cross_view_heading_rms, cross_view_measures,
                                         peer_view_measures, pooled_limb_measures,
                                         reference_body, reference_cross_view_check,
                                         subject_rows, view_measures)
from tracker.cli import VIEW_LAG_S, ZONE_FOREGROUND
from tracker.tracks.fixed_lag import replay
from sequences.pose_vector import heading_deg
from lab.evaluation import constant_pose
from lab.pose2sim_trial import checked_trial, missing_trial, trial_files
from lab.report import ReportError, check_plotting, plot_real_video
from tracker.one_line_parser import OneLineParser, quiet_decoder_logs, stops_in_one_line
from tracker.video.sources import INSTALL_HINT, SOURCES, segmenter_available
from tracker.outputs import PoseRecorder
from tracker.outputs.files import OutputWriteError
from tracker.outputs.whole_files import write_whole
from tracker.video.decode import VideoError



class ViewTrack(NamedTuple):
    """Every pose the tracker output on one video, one row per (frame, person): frames (n,)
    int video frame indices, filtered, raw and smoothed (each whole track RTS-smoothed, as
    track's JSON and BVH get them) (n, 55) pose vectors, track_ids (n,) int, bbox_px (n, 4)
    (x, y, w, h) pixels, novelty (n,) (PoseEstimates.novelty; NaN if unknown), lagged (n, 55): as
    ``track --lag LAG_S`` streams them (the live view's default; tracker.tracks.fixed_lag)."""

    frames: np.ndarray
    filtered: np.ndarray
    raw: np.ndarray
    smoothed: np.ndarray
    track_ids: np.ndarray
    bbox_px: np.ndarray
    novelty: np.ndarray
    lagged: np.ndarray
    tiles: dict | None = None


#: The lag of the "lagged" poses, seconds: track --view's default.
LAG_S = VIEW_LAG_S


_TILE_PX = 160                  # height of a mask in the --masks contact sheet


class _MaskRecorder(PoseRecorder):
    """PoseRecorder that also keeps each person's silhouette as the regressor saw it
    (upright), scaled to _TILE_PX rows: tiles[(frame index, track id)] uint8, from
    tracker.run.track_video's write_frame hook."""

    def __init__(self, roll_deg: float):
        super().__init__()
        self.roll_deg, self.tiles = roll_deg, {}

    def write_frame(self, frame_index: int, time_s: float, frame, people: dict) -> None:
        import cv2

        from tracker.video.roll import upright_mask
        for track_id, person in people.items():
            mask = upright_mask(person.mask, self.roll_deg).astype(np.uint8) * 255
            width = max(1, round(mask.shape[1] * _TILE_PX / mask.shape[0]))
            self.tiles[(frame_index, track_id)] = cv2.resize(mask, (width, _TILE_PX),
                                                             interpolation=cv2.INTER_NEAREST)


def _track_view(video: Path, model, max_people: int | None, roll_deg: float = 0.0,
                keep_masks: bool = False, trust_zone_foreground: bool = False,
                reference_extractor=None, silhouettes: str = "background") -> ViewTrack:
    """Run the tracker on one video as the ``track`` command does (tracker.run.track_video),
    with ``--roll roll_deg``; keep_masks: also keep the silhouettes (ViewTrack.tiles);
    trust_zone_foreground: the extractor's (tracker.video.zone.refine_in_zone);
    reference_extractor: a function of the extractor giving the extractor to use
    (``--reference-masks``), or None; silhouettes: ``track --silhouettes`` (when no
    reference_extractor)."""
    from tracker import PoseTracker, track_video
    from tracker.video.sources import silhouette_extractor
    from tracker.pipeline import TrackerSettings, default_extractor
    from tracker.video.decode import open_video

    source = open_video(video)
    settings = TrackerSettings(max_people=max_people, roll_deg=roll_deg, novelty=True,
                               trust_zone_foreground=trust_zone_foreground)
    extractor = (silhouette_extractor(silhouettes, settings) if reference_extractor is None
                 else reference_extractor(default_extractor(settings)))
    tracker = PoseTracker(model, source.fps, settings, extractor=extractor)
    recorder = _MaskRecorder(roll_deg) if keep_masks else PoseRecorder()
    # The same poses on two cores; a run cut short by Ctrl-C is not measured.
    track_video(source, tracker, sinks=[recorder], workers=2).stop_if_interrupted()
    poses = recorder.poses
    if not poses:
        raise Pose2SimError(f"{video}: nobody was tracked")
    # Each track's smoothed poses, in the order of its rows in poses.
    smoothed = {t: iter(tracker.smoothed_track(t)) for t in {p.track_id for p in poses}}
    lagged = replay(tracker, recorder.frames(), LAG_S)     # the same rows, in the same order
    return ViewTrack(np.array([p.frame_index for p in poses]),
                     np.array([p.filtered for p in poses]), np.array([p.raw for p in poses]),
                     np.array([next(smoothed[p.track_id]) for p in poses]),
                     np.array([p.track_id for p in poses]),
                     np.array([p.bbox_px for p in poses], dtype=float),
                     np.array([np.nan if p.novelty is None else p.novelty for p in poses]),
                     np.array([p.filtered for p in lagged]),
                     recorder.tiles if keep_masks else None)


def evaluate_view(trial: Trial, view: str, track: ViewTrack, constant=None, fit=None
                  ) -> tuple[dict, np.ndarray]:
    """Measures of one view's subject (filtered and raw poses) and the subject's rows;
    constant (55,), a pose: also its flexion error; fit (reference_body): also the body
    angles' measures (view_measures)."""
    rows = subject_rows(track.frames, track.bbox_px, mid_hip_px(trial, view, track.frames))
    frames = track.frames[rows]
    out = {"tracks": int(len(np.unique(track.track_ids))),
           "subject_tracks": int(len(np.unique(track.track_ids[rows]))),
           "filtered": view_measures(trial, view, frames, track.filtered[rows], constant, fit),
           "raw": view_measures(trial, view, frames, track.raw[rows], constant, fit),
           "smoothed": view_measures(trial, view, frames, track.smoothed[rows], constant, fit),
           "lagged": view_measures(trial, view, frames, track.lagged[rows], constant, fit),
           "novelty": novelty_summary(track.novelty[rows])}
    return out, rows


def _fitted_body(fit) -> tuple:
    """(the body model, the fitted body's vertices (T, V, 3) metres) for ``rendered``: posed
    once for the four views."""
    from sequences.body import load_body
    from sequences.keypoint_fit import posed_vertices

    body = load_body()
    return body, posed_vertices(fit, body)


def _reference_extractor(trial: Trial, view: str, mode: str, fitted=None):
    """A function wrapping an extractor in a ReferenceMaskExtractor of ``mode`` ("cut",
    "drawn") fed with the reference keypoints projected into ``view``, or for "rendered" in a
    RenderedMaskExtractor fed with the fitted body (fitted: _fitted_body) rendered through the
    view's camera at the video's size."""
    from lab.reference_masks import ReferenceMaskExtractor, RenderedMaskExtractor
    from lab.silhouette_evaluation import pose2sim_body

    frames = video_frames(trial)
    if mode == "rendered":
        from sequences.pose2sim import render_view_masks
        from tracker.video.decode import open_video

        source = open_video(trial.video(view))
        body, vertices = fitted
        masks = render_view_masks(vertices, body.faces, body.patch_start, trial.camera(view),
                                  (source.height, source.width))
        return lambda extractor: RenderedMaskExtractor(extractor, masks, frames)
    keypoints = project_reference(view, frames, trial)
    body = pose2sim_body(trial)
    return lambda extractor: ReferenceMaskExtractor(extractor, keypoints, frames, body, mode)


def _fit_progress(done: int, total: int) -> None:
    if done == 1 or done % 25 == 0 or done == total:
        print(f"fitting the body to the reference: {done}/{total} frames", file=sys.stderr,
              flush=True)


def evaluate(trial: Trial, model, max_people: int | None, roll: bool = False,
             sheet: list | None = None, trust_zone_foreground: bool = False,
             reference_masks: str = "none", series: list | None = None,
             peer=None, silhouettes: str = "background") -> dict:
    """The whole evaluation as a JSON-ready dict: per view, their means, and cross-view.
    roll: track each view with its camera's roll from the calibration (``track --roll``).
    trust_zone_foreground: True takes the subtractor's foreground inside the unreliable zone
    as sure person (tracker.video.zone.refine_in_zone; ``--zone-foreground sure``), False
    (the default, as track's) lets colour decide on it too.
    sheet: a list that gets, per view, the subject's silhouettes as the regressor saw them
    at 8 frames spread over the clip (uint8 masks, write_mask_sheet draws them).
    reference_masks: "none", or "cut" / "drawn" / "rendered" to correct the silhouettes by the
    reference (a diagnostic: lab.reference_masks).
    series: a list that gets, per view, the subject's flexions and headings over time beside
    the reference's (lab.report.plot_real_video draws them).
    peer: a function of a view giving MediaPipe's results there (mediapipe_peer.read_results),
    to score on the same frames as ours, or None. silhouettes: ``track --silhouettes``."""
    per_view, subject = {}, {}
    constant = constant_pose(model)
    fit = reference_body(trial, progress=_fit_progress)
    fitted = _fitted_body(fit) if reference_masks == "rendered" else None
    for view in VIEWS:
        roll_deg = camera_roll_deg(trial, view) if roll else 0.0
        track = _track_view(trial.video(view), model, max_people, roll_deg,
                            keep_masks=sheet is not None,
                            trust_zone_foreground=trust_zone_foreground,
                            reference_extractor=None if reference_masks == "none" else
                            _reference_extractor(trial, view, reference_masks, fitted),
                            silhouettes=silhouettes)
        per_view[view], rows = evaluate_view(trial, view, track, constant, fit)
        if sheet is not None:
            picked = rows[np.linspace(0, len(rows) - 1, 8).astype(int)]
            sheet.append([track.tiles[(int(track.frames[i]), int(track.track_ids[i]))]
                          for i in picked])
        per_view[view]["roll_deg"] = round(roll_deg, 1)
        per_view[view]["zone_foreground"] = next(
            name for name, trusted in ZONE_FOREGROUND.items() if trusted == trust_zone_foreground)
        per_view[view]["reference_masks"] = reference_masks
        subject[view] = (track.frames[rows], track.filtered[rows], track.raw[rows],
                         track.smoothed[rows])
        if series is not None:
            series.append(_view_series(trial, view, *subject[view], constant))
    common = subject[VIEWS[0]][0]
    for view in VIEWS[1:]:
        common = np.intersect1d(common, subject[view][0])
    cross = {}
    for kind, col in (("filtered", 1), ("raw", 2), ("smoothed", 3)):
        poses = {v: subject[v][col][np.isin(subject[v][0], common)] for v in VIEWS}
        cross[kind] = cross_view_measures(trial, common, poses)
    still = limb_angles_deg(np.asarray(constant)[None])[0]
    limbs = {kind: pooled_limb_measures(trial, {v: subject[v][0] for v in VIEWS},
                                        {v: limb_angles_deg(subject[v][col]) for v in VIEWS},
                                        still)
             for kind, col in (("filtered", 1), ("smoothed", 3))}
    return {"trial": str(trial.root), "views": per_view, "mean": _means(per_view),
            "limbs": limbs["filtered"], "limbs_smoothed": limbs["smoothed"],
            **({} if peer is None else
               {"peer": _peer(trial, {v: subject[v][0] for v in VIEWS}, peer)}),
            "reference_fit_direction_error_deg": {
                "median": float(np.median(fit.direction_error_deg)),
                "max": float(fit.direction_error_deg.max())},
            "cross_view": cross, "common_frames": int(len(common)),
            "reference_cross_view_heading_rms_deg": reference_cross_view_check(trial, common,
                                                                                VIEWS)}


def _peer(trial: Trial, frames_by_view: dict, peer) -> dict:
    """MediaPipe scored on each view's frames where ours has the subject (and MediaPipe
    follows it): {"views": per view peer_view_measures, "limbs": pooled_limb_measures,
    "cross_view_heading_rms_deg" over the frames every view has}."""
    views = {v: peer_view_measures(trial, v, peer(v), frames_by_view[v]) for v in VIEWS}
    series = {v: views[v].pop("series") for v in VIEWS}
    common = series[VIEWS[0]][0]
    for v in VIEWS[1:]:
        common = np.intersect1d(common, series[v][0])
    heading = {v: series[v][2][np.isin(series[v][0], common)] for v in VIEWS}
    return {"views": views,
            "limbs": pooled_limb_measures(trial, {v: series[v][0] for v in VIEWS},
                                          {v: series[v][1] for v in VIEWS}),
            "cross_view_heading_rms_deg": cross_view_heading_rms(trial, common, heading),
            "common_frames": int(len(common))}


def _view_series(trial: Trial, view: str, frames, filtered, raw, smoothed, constant) -> dict:
    """One view's flexions (T, 4) and headings (T,) over its frames, estimated and the
    reference's, and the constant pose's flexions (4,): a row of the --plot figure."""
    return {"view": view, "frames": frames, "reference": reference_flexion(trial, frames),
            "filtered": flexion_deg(filtered), "smoothed": flexion_deg(smoothed),
            "constant": flexion_deg(np.asarray(constant, dtype=np.float64)[None])[0],
            "reference_heading": reference_heading_deg(trial, view, frames),
            "filtered_heading": heading_deg(filtered), "smoothed_heading": heading_deg(smoothed)}


def write_mask_sheet(path: Path, rows: list[list[np.ndarray]]) -> None:
    """rows of uint8 masks (each _TILE_PX tall) -> one PNG, a grey border round each mask;
    Pose2SimError if it cannot be written."""
    import cv2

    lines = [np.hstack([np.pad(t, 3, constant_values=128) for t in row]) for row in rows]
    width = max(line.shape[1] for line in lines)
    image = np.vstack([np.pad(line, ((0, 0), (0, width - line.shape[1])), constant_values=60)
                       for line in lines])
    try:
        written = cv2.imwrite(str(path), image)
    except cv2.error:
        written = False
    if not written:
        raise Pose2SimError(f"{path}: cannot write the mask sheet")


def _means(per_view: dict) -> dict:
    """Means over views of the filtered poses' per-angle flexion and heading figures (and
    the body angles' where every view has them)."""
    def mean(get):
        return np.mean([get(r["filtered"]) for r in per_view.values()], axis=0).tolist()

    return {"flexion_error_per_angle": mean(lambda m: m["flexion"]["error_per_angle"]),
            "flexion_error": mean(lambda m: m["flexion"]["error"]),
            "flexion_corr_per_angle": mean(lambda m: m["flexion"]["corr_per_angle"]),
            "constant_flexion_error": mean(lambda m: m["flexion"]["truth_mean_error_mean"]),
            "training_mean_flexion_error": mean(lambda m: m["flexion"]["constant_error_mean"]),
            "heading_within_45": mean(lambda m: m["heading"]["within_45"]),
            "heading_rms_deg": mean(lambda m: m["heading"]["rms_deg"]),
            **({"body_error_deg": mean(lambda m: m["body"]["error_deg"]),
                "body_constant_error_deg": mean(lambda m: m["body"]["constant_error_deg"]),
                "body_top_angle_corr": mean(lambda m: m["body"]["top_angles"]["mean"])}
               if all("body" in r["filtered"] for r in per_view.values()) else {})}


def _row(label: str, tracks: str, frames: str, err, err_mean, const, train, corr, within,
         rms) -> str:
    return (f"{label:6} {tracks:>3} {frames:>3} | " + " ".join(f"{e:5.1f}" for e in err)
            + f" {err_mean:5.1f} {const:5.1f} {train:5.1f} | "
            + " ".join(f"{c:5.2f}" for c in corr)
            + f" | {within:5.2f} {rms:4.0f}")


def format_table(result: dict) -> str:
    """The evaluation as a plain-text table (filtered poses)."""
    short = " ".join(f"{s:>5}" for s in ("Lkn", "Rkn", "Lel", "Rel"))
    head = (f"{'':14} | {'flexion error (deg)':^41} | {'flexion corr.':^23} | heading\n"
            f"{'view':6} {'trk':>3} {'frm':>3} | {short} {'mean':>5} {'const':>5} {'train':>5} "
            f"| {short} "
            f"| {'<=45':>5} {'RMS':>4}")
    lines = [head, "-" * len(head.splitlines()[1])]
    for view, r in result["views"].items():
        f, h = r["filtered"]["flexion"], r["filtered"]["heading"]
        lines.append(_row(view, str(r["tracks"]), str(r["filtered"]["frames"]),
                          f["error_per_angle"], f["error"], f["truth_mean_error_mean"],
                          f["constant_error_mean"], f["corr_per_angle"], h["within_45"],
                          h["rms_deg"]))
    m = result["mean"]
    lines.append(_row("mean", "", "", m["flexion_error_per_angle"], m["flexion_error"],
                      m["constant_flexion_error"], m["training_mean_flexion_error"],
                      m["flexion_corr_per_angle"],
                      m["heading_within_45"], m["heading_rms_deg"]))
    for kind in ("filtered", "raw", "smoothed"):
        c = result["cross_view"][kind]
        lines.append(f"cross-view ({kind}, {c['frames']} common frames): heading RMS "
                     f"{c['heading_rms_deg']:.0f} deg (random headings "
                     f"{c['random_heading_rms_deg']:.0f}); 53 body angles disagree by "
                     f"{c['body_angle_disagreement_deg']:.1f} deg")
    body = {v: r["filtered"].get("body") for v, r in result["views"].items()}
    if all(b is not None for b in body.values()):
        lines.append("53 body angles against the body fitted to the reference (filtered; error "
                     "/ training-mean pose's / offset-free error / a still pose's / corr. of "
                     "the 8 most-moving): "
                     + ", ".join(f"{v} {b['error_deg']:.1f} / {b['constant_error_deg']:.1f} / "
                                 f"{b['offset_free_error_deg']:.1f} / "
                                 f"{b['constant_offset_free_error_deg']:.1f} / "
                                 f"{b['top_angles']['mean']:.2f}" for v, b in body.items()))
    for kind, what in (("smoothed", "smoothed poses (track's JSON and BVH)"),
                       ("lagged", f"lagged poses (track --lag {LAG_S:g}, the live view's)")):
        if kind not in next(iter(result["views"].values())):
            continue                  # a result written before the lagged poses were measured
        rows = [r[kind] for r in result["views"].values()]
        lines.append(f"{what}: flexion error "
                     f"{np.mean([s['flexion']['error'] for s in rows]):.1f} deg (mean over "
                     "views), corr. " + " / ".join(
                         f"{c:.2f}" for c in np.mean([s["flexion"]["corr_per_angle"]
                                                      for s in rows], axis=0))
                     + ", heading within 45 deg " + " / ".join(
                         f"{100 * s['heading']['within_45']:.0f}" for s in rows) + " %")
    raw = [r["raw"]["flexion"]["error"] for r in result["views"].values()]
    lines.append(f"raw poses: flexion error {np.mean(raw):.1f} deg (mean over views). "
                 f"const: a constant at the reference's own mean flexion; train: the model's "
                 f"training-mean pose held still; trk: tracks in the view; frm: frames with "
                 f"the subject tracked")
    novel = {v: r.get("novelty", {}) for v, r in result["views"].items()}
    if all(n.get("median") is not None for n in novel.values()):
        lines.append("novelty (distance to the training silhouettes over their own 99th "
                     "percentile; 1 % of training rows are above 1): median "
                     + ", ".join(f"{v} {n['median']:.2f}" for v, n in novel.items())
                     + "; frames above 1: "
                     + ", ".join(f"{v} {100 * n['share_above_1']:.0f} %"
                                 for v, n in novel.items()))
    rolls = [result["views"][v].get("roll_deg", 0.0) for v in result["views"]]
    if any(rolls):
        lines.append("tracked with the cameras' roll (track --roll, degrees): "
                     + ", ".join(f"{v} {r:g}" for v, r in zip(result["views"], rolls)))
    zone = {r.get("zone_foreground", "colour") for r in result["views"].values()}
    if zone != {"colour"}:
        lines.append("silhouettes: --zone-foreground sure (the subtractor's foreground inside "
                     "the unreliable zone taken as sure person)")
    reference = {r.get("reference_masks", "none") for r in result["views"].values()}
    if reference != {"none"}:
        lines.append(f"silhouettes corrected by the reference ({', '.join(sorted(reference))}; "
                     "a diagnostic, not a result: lab.reference_masks)")
    return "\n".join(lines)


_SHORT8 = ("Lkn", "Rkn", "Lel", "Rel", "Lhp", "Rhp", "Lsh", "Rsh")


def _limb_row(label: str, frames, m: dict, heading) -> str:
    const = m.get("constant_error_mean")
    return (f"{label:16} {frames:>3} | " + " ".join(f"{c:5.2f}" for c in m["corr_per_angle"])
            + f" {np.mean(m['corr_per_angle']):5.2f} | "
            + " ".join(f"{e:4.0f}" for e in m["error_per_angle"])
            + f" {np.mean(m['error_per_angle']):5.1f} {np.mean(m['truth_mean_error']):5.1f} "
            + ("    -" if const is None else f"{const:5.1f}")
            + ("" if heading is None else f" | {heading:4.0f}"))


def format_limb_table(name: str, result: dict) -> str:
    """One trial's 8 limb angles, ours and the peer's: per view, the views' mean, and all views
    pooled; then the trial's summary line."""
    head = (f"{name}: 8 limb angles, ours (filtered poses) and the peer's\n{'':20} | "
            f"{'correlation with the reference':^53} | {'mean error (deg)':^57} | heading\n"
            f"{'':16} frm | " + " ".join(f"{s:>5}" for s in _SHORT8) + "  mean | "
            + " ".join(f"{s:>4}" for s in _SHORT8) + "  mean const train |  RMS")
    lines = [head, "-" * len(head.splitlines()[2])]
    sources = [("ours", result["views"], result["limbs"], "filtered")]
    if "peer" in result:
        sources.append(("MediaPipe", result["peer"]["views"], result["peer"]["limbs"], None))
    for label, views, limbs, kind in sources:
        for view, r in views.items():
            m = r[kind] if kind else r
            lines.append(_limb_row(f"{label} {view}", m["frames"], m["limbs"],
                                   m["heading"]["rms_deg"]))
        lines.append(_limb_row(f"{label} mean", "", limbs["mean"], None))
        lines.append(_limb_row(f"{label} pooled", limbs["pooled"]["frames"], limbs["pooled"],
                               None))
    if "limbs_smoothed" in result:
        smoothed = result["limbs_smoothed"]["mean"]
        lines.append(f"ours, smoothed poses (track's JSON and BVH): mean corr "
                     f"{np.mean(smoothed['corr_per_angle']):.2f}, mean error "
                     f"{np.mean(smoothed['error_per_angle']):.1f} deg (mean over the views)")
    lines.append("const: a constant at the reference's own mean angle; train: the model's "
                 "training-mean pose held still; mean: over the views' figures; pooled: all "
                 "views' frames together")
    lines.append(summary_line(name, result))
    return "\n".join(lines)


def summary_line(name: str, result: dict) -> str:
    """The trial's figures in one line: mean correlation and error over the 8 angles (over
    the views' figures), cross-view heading RMS, and balancing's flexion error: ours (filtered
    poses, and smoothed as track's JSON has them) and the peer's."""
    def part(label, limbs, cross, flexion):
        return (f"{label} mean corr {np.mean(limbs['corr_per_angle']):.2f}, mean error "
                f"{np.mean(limbs['error_per_angle']):.1f} deg, cross-view heading RMS "
                f"{cross:.0f}" + ("" if flexion is None else f", flexion error {flexion:.1f}"))

    limbs, flex = result["limbs"]["mean"], name == "balancing"
    parts = [part("ours", limbs, result["cross_view"]["filtered"]["heading_rms_deg"],
                  np.mean(limbs["error_per_angle"][:4]) if flex else None)
             + f" (constant {np.mean(limbs['truth_mean_error']):.1f}, training-mean "
               f"{limbs['constant_error_mean']:.1f})"]
    if "limbs_smoothed" in result:
        smoothed = result["limbs_smoothed"]["mean"]
        parts.append(part("ours smoothed (track's JSON)", smoothed,
                          result["cross_view"]["smoothed"]["heading_rms_deg"],
                          np.mean(smoothed["error_per_angle"][:4]) if flex else None))
    if "peer" in result:
        peer = result["peer"]
        parts.append(part("MediaPipe", peer["limbs"]["mean"], peer["cross_view_heading_rms_deg"],
                          np.mean(peer["limbs"]["mean"]["error_per_angle"][:4])
                          if flex else None))
    return f"{name} summary: " + "; ".join(parts)


def build_parser() -> argparse.ArgumentParser:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trial", default="all", help="all (the default: balancing and swings, "
                    "in ../shared/data/pose2sim beside the repo), balancing, swings, or a "
                    "trial folder")
    ap.add_argument("--peer", choices=("none", "mediapipe"), default="none",
                    help="also score MediaPipe Pose's 3-D world landmarks on the same frames "
                         "(needs mediapipe==0.10.14: pip install -e '.[peers]', or "
                         "--peer-results)")
    ap.add_argument("--peer-results", type=Path, metavar="DIR", help="read MediaPipe's "
                    "results from DIR/TRIAL/camNN.npz (scripts/run_mediapipe.py --out DIR) "
                    "instead of running it")
    ap.add_argument("--model", type=Path, default=DEFAULT_MODEL_PATH, help="model file")
    ap.add_argument("--max-people", type=int, default=None, metavar="N",
                    help="track at most N people per frame (default: all, as track)")
    ap.add_argument("--roll", choices=("none", "calibration"), default="none",
                    help="track each view with its camera's roll from the calibration "
                         "(track --roll), or without (the default, as track)")
    ap.add_argument("--silhouettes", choices=SOURCES, default="background",
                    help="as track --silhouettes (default background, the figures of "
                         f"docs/real_video.md; segment and auto need {INSTALL_HINT})")
    ap.add_argument("--zone-foreground", choices=tuple(ZONE_FOREGROUND), default="colour",
                    help="as track --zone-foreground: inside the background's unreliable zone, "
                         "let colour decide on the subtractor's foreground too (the default) "
                         "or take it as sure person (tracker.video.zone.refine_in_zone)")
    ap.add_argument("--reference-masks", choices=("none", "cut", "drawn", "rendered"),
                    default="none",
                    help="a diagnostic that reads the reference: cut each silhouette to the "
                         "body drawn from the reference keypoints, use that drawing as the "
                         "silhouette, or the training renderer's body fitted to the reference "
                         "and rendered through each camera (lab.reference_masks); "
                         "default none")
    ap.add_argument("--json", type=Path, metavar="OUT", help="write the measures as JSON")
    ap.add_argument("--masks", type=Path, metavar="PNG", help="write the subject's "
                    "silhouettes as the regressor saw them, 8 frames per view, as a PNG")
    ap.add_argument("--plot", type=Path, metavar="PNG", help="plot each view's knee and "
                    "elbow flexions and heading over time against the reference's, as a PNG "
                    "(needs matplotlib: pip install -e '.[report]')")
    return ap


def _main(argv) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    if args.silhouettes == "segment" and not segmenter_available():
        ap.error(f"--silhouettes segment needs the person segmenter: {INSTALL_HINT}")
    if args.max_people is not None and args.max_people < 1:
        ap.error(f"--max-people must be at least 1, got {args.max_people} (leave it out to "
                 f"track everyone)")
    problem = (_png_path_problem("--masks", args.masks)
               or _png_path_problem("--plot", args.plot))
    if problem:
        ap.error(problem)
    roots = trial_roots(args.trial)
    if len(roots) > 1 and (args.masks or args.plot):
        ap.error("--masks and --plot draw one trial: give --trial balancing or swings")
    peer = args.peer == "mediapipe" or args.peer_results is not None
    _check_peer(ap, peer, args.peer_results, roots)
    # Before about a minute of tracking, not after it: the outputs must be writable and may
    # overwrite none of the files read (the model, the trial's reference, calibration, videos).
    ap.check_outputs([("--json", args.json), ("--masks", args.masks), ("--plot", args.plot)],
                     [("--model", args.model),
                      *(f for root in roots.values() for f in trial_files(root))])
    for root in roots.values():
        if missing_trial(root):
            ap.error(missing_trial(root))
    if not args.model.is_file():
        ap.error(f"--model {args.model}: no such file")
    quiet_decoder_logs()          # as track: one line, not FFmpeg's too
    sheet = [] if args.masks else None
    series = [] if args.plot else None
    if args.plot:
        try:
            check_plotting()            # before the minute of work: matplotlib is there
        except ReportError as exc:
            print(f"evaluate_real: error: --plot {args.plot}: {exc}", file=sys.stderr)
            return 1
    results = {"model": str(args.model), "trials": {}}
    try:
        trials, model = {n: checked_trial(r) for n, r in roots.items()}, load_pose_model(args.model)
        for name, trial in trials.items():
            with threadpool_limits(1):  # small matrices: BLAS threads cost more than they save
                result = evaluate(trial, model, args.max_people,
                                  roll=args.roll == "calibration", sheet=sheet,
                                  trust_zone_foreground=ZONE_FOREGROUND[args.zone_foreground],
                                  reference_masks=args.reference_masks, series=series,
                                  peer=_peer_source(trial, name, args.peer_results)
                                  if peer else None, silhouettes=args.silhouettes)
            print(format_table(result), format_limb_table(name, result), sep="\n\n",
                  end="\n\n", flush=True)
            results["trials"][name] = result
    except (Pose2SimError, PoseModelError, MeasureError, KeypointFitError, VideoError,
            SilhouettePoseError, PeerError) as exc:
        print(f"evaluate_real: error: {exc}", file=sys.stderr)
        return 1
    if not peer:
        print("MediaPipe not scored: give --peer mediapipe (needs mediapipe==0.10.14, "
              "pip install -e '.[peers]') or --peer-results DIR (scripts/run_mediapipe.py)")
    for name, result in results["trials"].items():
        print(summary_line(name, result))
    try:
        if args.json:
            write_whole(args.json, lambda path: path.write_text(json.dumps(results, indent=1)))
        if args.masks:      # whole or not at all; the temporary name keeps .png for OpenCV
            write_whole(args.masks, lambda path: write_mask_sheet(path, sheet), keep_suffix=True)
        if args.plot:
            write_whole(args.plot, lambda path: plot_real_video(path, series,
                                                                list(FLEXION_NAMES)),
                        keep_suffix=True)
    except (Pose2SimError, OutputWriteError, ReportError) as exc:
        print(f"evaluate_real: error: {exc}", file=sys.stderr)
        return 1
    return 0


def _check_peer(ap, peer: bool, results_dir: Path | None, roots: dict) -> None:
    """Refuse (usage error) a MediaPipe peer that cannot be scored: mediapipe not installed
    and no --peer-results, or a --peer-results folder lacking a view's file."""
    if not peer:
        return
    if results_dir is None:
        import importlib.util
        if importlib.util.find_spec("mediapipe") is None:
            ap.error("--peer mediapipe: mediapipe is not installed (pip install "
                     "mediapipe==0.10.14, or run scripts/run_mediapipe.py elsewhere and give "
                     "--peer-results DIR)")
        return
    for name in roots:
        for view in VIEWS:
            if not (results_dir / name / f"{view}.npz").is_file():
                ap.error(f"--peer-results {results_dir}: no {name}/{view}.npz (write it with "
                         f"scripts/run_mediapipe.py --out {results_dir})")


def _peer_source(trial: Trial, name: str, results_dir: Path | None):
    """A function of a view giving MediaPipe's results there: read from results_dir/name/, or
    run now (mediapipe_peer.run_view, the subject picked by the reference's keypoint box)."""
    if results_dir is not None:
        return lambda view: read_results(results_dir / name / f"{view}.npz")
    frames = video_frames(trial)
    return lambda view: run_view(trial.video(view),
                                 keypoint_boxes(project_reference(view, frames, trial)))


def _png_path_problem(option: str, path: Path | None) -> str | None:
    """Why --masks or --plot cannot be written as a PNG (checked before a minute of
    tracking; the outputs' other checks are check_outputs'), or None."""
    if path is None:
        return None
    if path.suffix.lower() != ".png":
        return f"{option} {path}: it is written as a PNG, give a .png path"
    return None


main = stops_in_one_line("evaluate_real", _main)       # Ctrl-C: one line, no traceback


if __name__ == "__main__":
    sys.exit(main())
