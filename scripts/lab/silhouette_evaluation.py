"""How good are the silhouettes of a real video? Coverage, spill and off-body share against
projected keypoints.

On a video whose subject has 2-D reference keypoints per frame (e.g. Pose2Sim's balancing trial,
``sequences.pose2sim.project_reference``), the extractor and the associator run exactly as in
``tracker.pipeline.PoseTracker`` (people -> track ids); the pose regression is skipped,
since it does not change the masks or the track ids. Measures per view:

- ``coverage``: fraction of keypoints (over all frames) inside the subject's mask dilated by
  ``dilate_px`` px; a frame where the subject's track has no mask covers none.
- ``spill``: mean over the frames with a mask of (mask area outside the keypoints' bounding box
  padded by ``pad`` x its height on every side) / (padded box area).
- ``off_body``: mean over the frames with a mask of the share of the mask's area off the body
  drawn from the keypoints (:func:`body_region`: torso filled, bones as lines ``body_width`` x
  the keypoints' height thick, the head a disc of that radius; a generous body): background
  taken for the person inside the box, which ``spill`` does not see. Only with a
  :class:`BodyDrawing`. Like spill, it counts the subject's main track only: a ghost that
  becomes a track of its own leaves this measure (see ``tracks``).
- ``tracks``: track ids in the view; ``subject_tracks``: those whose masks hold a keypoint;
  ``main_track_fraction``: fraction of frames in which the subject's main track (the one whose
  masks hold the most keypoints) has a mask.
- ``own_track_fraction``: fraction of frames in which the subject has a track of their own
  (:func:`own_track_frames`): some track's mask holds at least ``OWN_MIN_COVERED`` of the
  keypoints (dilated as for coverage) and spills at most ``OWN_MAX_SPILL`` (``spill`` above)
  and ``OWN_MAX_OFF_BODY`` of its area off the body drawn from the keypoints (with a
  :class:`BodyDrawing`). A mask that also holds a second person, or a wide piece of floor,
  fails the spill or off-body bound; a subject cut into pieces fails the coverage bound.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import cv2
import numpy as np

from tracker.tracks.association import Associator
from tracker.video.silhouettes import PersonMask, SilhouetteExtractor


@dataclass(frozen=True)
class BodyDrawing:
    """Which keypoints make a body (indices into the K keypoints): ``torso`` the corners of
    the torso, ``head`` the head's, ``bones`` (B, 2) pairs drawn as lines."""

    torso: tuple[int, ...]
    head: int
    bones: tuple[tuple[int, int], ...]

    @classmethod
    def from_names(cls, names, torso, head, bones) -> "BodyDrawing":
        """From keypoint names (K,) and the torso, head and bones given by name; ValueError
        naming a keypoint that ``names`` lacks."""
        index = {n: i for i, n in enumerate(names)}
        wanted = list(torso) + [head] + [n for bone in bones for n in bone]
        missing = [n for n in wanted if n not in index]
        if missing:
            raise ValueError(f"the keypoints have no {missing[0]!r} to draw the body with")
        return cls(tuple(index[n] for n in torso), index[head],
                   tuple((index[a], index[b]) for a, b in bones))


@dataclass(frozen=True)
class FramePeople:
    """One frame's tracked people: (track_id, PersonMask) pairs."""

    index: int
    people: list[tuple[int, PersonMask]]


def track_masks(frames: Iterable[tuple[int, np.ndarray]], extractor: Callable,
                associator: Associator | None = None) -> list[FramePeople]:
    """Run ``extractor`` (frame BGR uint8 -> list of PersonMask) and the associator (default:
    PoseTracker's) on (index, frame) pairs in order, as PoseTracker does; every frame's
    tracked people."""
    associator = associator or default_associator()
    return [FramePeople(index, associator.update(extractor(image))) for index, image in frames]


def keypoints_inside(person: PersonMask, points_px: np.ndarray, dilate_px: int = 3) -> np.ndarray:
    """(K,) bool: which points (K, 2) px (x, y) fall on the person's mask dilated by dilate_px."""
    x, y, w, h = person.bbox
    mask = person.mask.astype(np.uint8)
    if dilate_px > 0:
        mask = cv2.copyMakeBorder(mask, dilate_px, dilate_px, dilate_px, dilate_px,
                                  cv2.BORDER_CONSTANT, value=0)
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * dilate_px + 1,) * 2)
        mask = cv2.dilate(mask, kernel)
        x, y = x - dilate_px, y - dilate_px
    col = np.floor(points_px[:, 0]).astype(int) - x
    row = np.floor(points_px[:, 1]).astype(int) - y
    ok = (col >= 0) & (row >= 0) & (col < mask.shape[1]) & (row < mask.shape[0])
    inside = np.zeros(len(points_px), bool)
    inside[ok] = mask[row[ok], col[ok]] > 0
    return inside


def spill(person: PersonMask, points_px: np.ndarray, pad: float = 0.1) -> float:
    """Mask area outside the points' (K, 2) px bounding box, padded by pad x the box height on
    every side, divided by the padded box's area."""
    lo, hi = points_px.min(axis=0), points_px.max(axis=0)
    margin = pad * (hi[1] - lo[1])
    bx0, by0 = np.floor(lo - margin).astype(int)
    bx1, by1 = np.ceil(hi + margin).astype(int)
    x, y, w, h = person.bbox
    inner = person.mask[max(by0 - y, 0):max(by1 - y, 0), max(bx0 - x, 0):max(bx1 - x, 0)]
    outside = person.area - int(np.count_nonzero(inner))
    return outside / float((bx1 - bx0) * (by1 - by0))


def body_region(points_px: np.ndarray, body: BodyDrawing, box: tuple[int, int, int, int],
                width: float = 0.14) -> np.ndarray:
    """bool (h, w) over ``box`` (x, y, w, h) px: the body drawn from keypoints (K, 2) px (x, y):
    the torso's convex hull filled, each bone a line ``width`` x the keypoints' height thick,
    a disc of that radius round the head. Drawn whole, then cut to the box, so that the
    drawing does not depend on where the box cuts it (OpenCV clips shapes at the canvas)."""
    p = np.asarray(points_px, np.float64)
    thick = max(2, int(round(width * float(np.ptp(p[:, 1])))))
    x, y, w, h = box
    x0 = int(min(x, np.floor(p[:, 0].min()) - thick))
    y0 = int(min(y, np.floor(p[:, 1].min()) - thick))
    x1 = int(max(x + w, np.ceil(p[:, 0].max()) + thick + 1))
    y1 = int(max(y + h, np.ceil(p[:, 1].max()) + thick + 1))
    canvas = np.zeros((y1 - y0, x1 - x0), np.uint8)
    q = np.round(p - (x0, y0)).astype(np.int32)
    cv2.fillConvexPoly(canvas, cv2.convexHull(q[list(body.torso)]), 1)
    for a, b in body.bones:
        cv2.line(canvas, (int(q[a, 0]), int(q[a, 1])), (int(q[b, 0]), int(q[b, 1])), 1, thick)
    cv2.circle(canvas, (int(q[body.head, 0]), int(q[body.head, 1])), thick, 1, -1)
    return canvas[y - y0:y - y0 + h, x - x0:x - x0 + w] > 0


def off_body(person: PersonMask, points_px: np.ndarray, body: BodyDrawing,
             width: float = 0.14) -> float:
    """Share of the person's mask area off the body drawn from points (K, 2) px
    (:func:`body_region`); 0 for an empty mask."""
    if person.area == 0:
        return 0.0
    region = body_region(points_px, body, person.bbox, width)
    return float(np.count_nonzero(person.mask & ~region)) / float(person.area)


#: Bounds of "the subject has a track of their own" (own_track_frames): share of the keypoints
#: on the mask, spill (mask area outside the keypoints' padded box over that box's area) and
#: share of the mask off the generous body drawing. The subject alone (balancing's four views,
#: swings' cam02 and cam04: spill up to 0.26, off-body up to 0.58 with the floor the
#: extractor takes for him) is within them in every frame; joined with the second person
#: (swings' cam01: off-body 0.63-0.76) in none (docs/crossings.md).
OWN_MIN_COVERED = 0.5
OWN_MAX_SPILL = 0.3
OWN_MAX_OFF_BODY = 0.6


def own_track_frames(tracked: list[FramePeople], keypoints_px: np.ndarray, dilate_px: int = 3,
                     pad: float = 0.1, body: BodyDrawing | None = None,
                     body_width: float = 0.14) -> np.ndarray:
    """(T,) bool: in which of the frames ``tracked`` (keypoints (T, K, 2) px, one row per
    frame) the subject has a track of their own: a tracked mask holding at least
    OWN_MIN_COVERED of the keypoints (dilated by dilate_px) whose spill (pad) is at most
    OWN_MAX_SPILL and, with ``body``, whose share off the body is at most OWN_MAX_OFF_BODY."""
    own = np.zeros(len(tracked), bool)
    for t, (frame, points) in enumerate(zip(tracked, keypoints_px)):
        for _, person in frame.people:
            if (keypoints_inside(person, points, dilate_px).mean() >= OWN_MIN_COVERED
                    and spill(person, points, pad) <= OWN_MAX_SPILL
                    and (body is None or off_body(person, points, body, body_width)
                         <= OWN_MAX_OFF_BODY)):
                own[t] = True
                break
    return own


def silhouette_measures(tracked: list[FramePeople], keypoints_px: np.ndarray,
                        dilate_px: int = 3, pad: float = 0.1, body: BodyDrawing | None = None,
                        body_width: float = 0.14) -> dict:
    """Coverage, spill, off-body share (with ``body``) and track counts (module docstring) of
    tracked people against keypoints (T, K, 2) px, one row per entry of ``tracked``. Returns a
    JSON-ready dict."""
    if len(tracked) != len(keypoints_px):
        raise ValueError(f"{len(tracked)} tracked frames for {len(keypoints_px)} keypoint rows")
    held: dict[int, int] = {}
    inside: dict[tuple[int, int], np.ndarray] = {}
    for t, (frame, points) in enumerate(zip(tracked, keypoints_px)):
        for track_id, person in frame.people:
            inside[t, track_id] = keypoints_inside(person, points, dilate_px)
            held[track_id] = held.get(track_id, 0) + int(inside[t, track_id].sum())
    all_ids = {tid for frame in tracked for tid, _ in frame.people}
    own = float(own_track_frames(tracked, keypoints_px, dilate_px, pad, body, body_width).mean())
    if not held or max(held.values()) == 0:
        out = {"frames": len(tracked), "coverage": 0.0, "spill": float("nan"),
               "spill_p90": float("nan"), "tracks": len(all_ids), "subject_tracks": 0,
               "main_track_fraction": 0.0, "own_track_fraction": own}
        if body is not None:
            out["off_body"] = float("nan")
        return out
    main = max(held, key=held.get)
    covered, spills, offs, present = 0, [], [], 0
    for t, (frame, points) in enumerate(zip(tracked, keypoints_px)):
        for track_id, person in frame.people:
            if track_id == main:
                present += 1
                covered += int(inside[t, track_id].sum())
                spills.append(spill(person, points, pad))
                if body is not None:
                    offs.append(off_body(person, points, body, body_width))
    out = {"frames": len(tracked), "coverage": covered / keypoints_px[:, :, 0].size,
           "spill": float(np.mean(spills)), "spill_p90": float(np.percentile(spills, 90)),
           "tracks": len(all_ids), "subject_tracks": sum(1 for n in held.values() if n > 0),
           "main_track_fraction": present / len(tracked), "own_track_fraction": own}
    if body is not None:
        out["off_body"] = float(np.mean(offs))
    return out


def evaluate_pose2sim_view(trial, view: str, make_extractor: Callable, samples: int = 25,
                           dilate_px: int = 3, pad: float = 0.1,
                           make_associator: Callable[[], Associator] | None = None) -> dict:
    """Silhouette measures of one view of a Pose2Sim trial (sequences.pose2sim.Trial).

    ``make_extractor(sample_frames) -> extractor``: builds a primed extractor from ``samples``
    frames spread over the video (as the ``track`` command samples them);
    ``make_associator() -> Associator`` (default :func:`default_associator`)."""
    from sequences.pose2sim import project_reference, video_frames
    from tracker.video.decode import open_video

    source = open_video(trial.video(view))
    extractor = make_extractor(source.sample_frames(samples))
    wanted = set(int(i) for i in video_frames(trial))
    associator = (make_associator or default_associator)()
    tracked = [f for f in track_masks(((i, im) for i, _, im in source), extractor, associator)
               if f.index in wanted]
    keypoints = project_reference(view, [f.index for f in tracked], trial)
    return silhouette_measures(tracked, keypoints, dilate_px, pad, pose2sim_body(trial))


def pose2sim_body(trial) -> BodyDrawing:
    """The body drawn from a Pose2Sim trial's reference keypoints (sequences.pose2sim's
    BODY_TORSO, BODY_HEAD, BODY_BONES); Pose2SimError naming a keypoint the trial lacks."""
    from sequences.pose2sim import BODY_BONES, BODY_HEAD, BODY_TORSO, Pose2SimError
    try:
        return BodyDrawing.from_names(trial.reference.names, BODY_TORSO, BODY_HEAD, BODY_BONES)
    except ValueError as exc:
        raise Pose2SimError(f"{trial.root}: {exc}") from None


def legacy_extractor(frames) -> "SilhouetteExtractor":
    """The extractor as it was before the clip background (issue 11): MOG2 primed with the
    median of the sampled frames, shadows dropped, no brightness, lighting or zone handling,
    a plain opening, only pieces stacked one above the other joined into one person."""
    from tracker.video.silhouettes import SilhouetteExtractor, median_background
    extractor = SilhouetteExtractor(keep_enclosed_shadow=False, drop_lighting=False,
                                    refine=False, normalise_brightness=False,
                                    max_fragment_area=0.0, restore_px=0)
    extractor.prime(median_background(list(frames)))
    return extractor


def clip_extractor(frames) -> "SilhouetteExtractor":
    """The extractor with its own defaults (the subtractor's foreground inside the unreliable
    zone sure person: ``track --zone-foreground sure``, track's default until 2026-12-04)
    primed with the sampled frames (clip background)."""
    from tracker.video.silhouettes import SilhouetteExtractor
    extractor = SilhouetteExtractor()
    extractor.prime(frames)
    return extractor


def colour_zone_extractor(frames) -> "SilhouetteExtractor":
    """The extractor as ``track`` builds it by default since 2026-12-04: colour also decides
    on the foreground inside the unreliable zone (``trust_zone_foreground=False``:
    tracker.video.zone.refine_in_zone)."""
    from tracker.video.silhouettes import SilhouetteExtractor
    extractor = SilhouetteExtractor(trust_zone_foreground=False)
    extractor.prime(frames)
    return extractor


def default_associator() -> Associator:
    """The associator PoseTracker builds by default."""
    return Associator()


def legacy_associator() -> Associator:
    """The associator as it was before issue 11: no boxes (the area gate always applies),
    every detection a track at once."""
    return Associator(use_boxes=False, min_hits=1)


EXTRACTORS = {"before": legacy_extractor, "after": clip_extractor, "colour": colour_zone_extractor}
ASSOCIATORS = {"before": legacy_associator, "after": default_associator,
               "colour": default_associator}


def format_table(results: dict[str, dict[str, dict]]) -> str:
    """{label: {view: silhouette_measures dict}} as a plain-text table."""
    lines = [f"{'':7} {'view':6} {'coverage':>8} {'spill':>6} {'spill90':>7} {'off-body':>8} "
             f"{'tracks':>6} {'subj.trk':>8} {'main-track frames':>17} {'own-track frames':>16}"]
    for label, views in results.items():
        for view, r in views.items():
            off = f"{r['off_body']:8.1%}" if "off_body" in r else f"{'-':>8}"
            lines.append(f"{label:7} {view:6} {r['coverage']:8.1%} {r['spill']:6.1%} "
                         f"{r['spill_p90']:7.1%} {off} {r['tracks']:6d} "
                         f"{r['subject_tracks']:8d} {r['main_track_fraction']:17.0%} "
                         f"{r.get('own_track_fraction', float('nan')):16.0%}")
    return "\n".join(lines)
