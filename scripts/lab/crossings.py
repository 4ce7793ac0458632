"""Crossing people with known identities: a video beside its own mirror image, and how well
the tracker keeps who is who (identity switches, tracks per person).

A one-walker render (the sample spiral walk) becomes a two-person video by pasting, into each
frame, the walker of a frame ``offset`` later mirrored left to right: the two walk towards
each other, become one blob where they meet, and part again. The mirror copy can be tinted
(other clothes) or not (twins: only their motion tells them apart). Both people's centroids
and boxes are known from the render's ground truth, mirrored for the copy.
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment

from sequences.video import load_truth
from tracker.tracks.association import Associator
from tracker.pipeline import TrackerSettings, default_extractor
from tracker.video.silhouettes import median_background

#: Grey levels by which the mirrored frame must differ from the mirrored background to be the
#: walker (the render's sensor noise is 2 grey levels).
PASTE_THRESHOLD = 30
#: BGR gains of a tinted copy: reddish clothes against the original's skin tone.
TINT = (0.55, 0.7, 1.15)


def read_frames(path: str | Path) -> np.ndarray:
    """Every frame of a video, (T, H, W, 3) BGR uint8."""
    capture = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        frames.append(frame)
    capture.release()
    if not frames:
        raise ValueError(f"no frame could be read from {path}")
    return np.stack(frames)


def mirror_crossing(frames: np.ndarray, truth: dict, offset: int = 0, tint: bool = False
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Two people from one walker: frame t shows the walker of frame t and, pasted over it,
    the walker of frame t + offset mirrored (tinted by TINT when ``tint``).

    frames: (T, H, W, 3) BGR uint8 of a one-person static-camera video; truth: its ground
    truth (sequences.video.load_truth). Returns (frames (T - offset, H, W, 3), the empty
    scene (H, W, 3) (median of 25 frames), centroids (T - offset, 2, 2) px and boxes
    (T - offset, 2, 4) px (x, y, w, h) of person 0 (the original) and 1 (the copy))."""
    if not 0 <= offset < len(frames) - 1:
        raise ValueError(f"offset={offset} must be in 0..{len(frames) - 2}")
    background = median_background(list(frames[np.linspace(0, len(frames) - 1, 25).astype(int)]))
    width = frames.shape[2]
    count = len(frames) - offset
    behind = np.ascontiguousarray(background[:, ::-1])
    out = frames[:count].copy()
    for composite, frame in zip(out, frames[offset:]):
        mirrored = np.ascontiguousarray(frame[:, ::-1])
        still = cv2.inRange(cv2.absdiff(mirrored, behind), (0, 0, 0), (PASTE_THRESHOLD,) * 3)
        if tint:
            mirrored = cv2.multiply(mirrored, TINT + (0.0,), dtype=cv2.CV_8U)
        cv2.copyTo(mirrored, cv2.bitwise_not(still), composite)
    centroid = truth["centroid_px"][:, 0]
    box = truth["bbox_px"][:, 0].astype(float)
    centroids = np.stack([centroid[:count], centroid[offset:] * [-1, 1] + [width, 0]], axis=1)
    mirror_box = box[offset:].copy()
    mirror_box[:, 0] = width - box[offset:, 0] - box[offset:, 2]
    return out, background, centroids, np.stack([box[:count], mirror_box], axis=1)


def track_identities(frames: Sequence[np.ndarray], background: np.ndarray,
                     associator: Associator | None = None,
                     settings: TrackerSettings = TrackerSettings()) -> list[list[tuple]]:
    """Who the tracker says is where: per frame, (track_id, centroid (x, y) px) of each person
    reported, from the ``track`` command's own extractor and associator (identities are
    decided there; the poses do not change them), the extractor primed with ``background``
    as a clean plate (``track --background``)."""
    extractor = default_extractor(settings)
    extractor.prime(background)
    associator = associator or Associator()
    return [[(track_id, person.centroid) for track_id, person in
             associator.update(extractor(frame)[: settings.max_people])] for frame in frames]


def identity_measures(reported: list[list[tuple]], centroids: np.ndarray,
                      boxes: np.ndarray) -> dict:
    """Crossings, identity switches and tracks per person of ``reported`` (track_identities)
    against the truth's centroids (T, P, 2) px and boxes (T, P, 4) px.

    Only frames where the true people's boxes do not overlap are scored (in between, one blob
    is nobody in particular); a report belongs to the true person nearest it, within half
    that person's height. switches: the times a person's track id differs from the one it
    had at its last scored frame; tracks_per_person: distinct ids per person (1 is perfect);
    found: the share of scored person-frames with a track; crossings: the times the people's
    left-to-right order changes; found_touching: the share of person-frames where the true
    boxes overlap whose report (paired as above) bears the id the person has at the nearest
    frame apart, i.e. a silhouette of their own (tracker.video.blob_split) rather than none or the
    other's."""
    x0, x1 = boxes[..., 0], boxes[..., 0] + boxes[..., 2]
    apart = (np.maximum(x0[:, 0], x0[:, 1]) >= np.minimum(x1[:, 0], x1[:, 1]))
    order = np.sign(centroids[:, 0, 0] - centroids[:, 1, 0])
    crossings = int(np.count_nonzero(np.diff(order[order != 0])))
    people = centroids.shape[1]
    ids: list[list[int]] = [[] for _ in range(people)]
    scored = found = 0
    for t in np.flatnonzero(apart):
        scored += people
        if not reported[t]:
            continue
        points = np.array([c for _, c in reported[t]], float)
        distance = np.linalg.norm(points[:, None] - centroids[t][None], axis=2)
        rows, cols = linear_sum_assignment(distance)
        for r, p in zip(rows, cols):
            if distance[r, p] <= 0.5 * boxes[t, p, 3]:
                ids[p].append(reported[t][r][0])
                found += 1
    switches = sum(int(np.count_nonzero(np.diff(seq))) for seq in ids)
    tracks = [len(set(seq)) for seq in ids]
    return {"crossings": crossings, "switches": switches, "tracks_per_person": tracks,
            "found": found / scored if scored else 0.0,
            "found_touching": _found_touching(reported, centroids, boxes, apart)}


def _found_touching(reported: list[list[tuple]], centroids: np.ndarray, boxes: np.ndarray,
                    apart: np.ndarray) -> float:
    """identity_measures' found_touching: over the frames where the true boxes overlap
    (``apart`` (T,) False), the share of person-frames whose report (reports and people
    paired by distance, within half the person's height) bears the id the person had at the
    nearest frame apart."""
    people = centroids.shape[1]
    known = {}                       # (frame apart, person) -> id reported there
    for t in np.flatnonzero(apart):
        for track_id, c in reported[t]:
            p = int(np.argmin(np.linalg.norm(centroids[t] - np.asarray(c), axis=1)))
            if np.linalg.norm(centroids[t, p] - c) <= 0.5 * boxes[t, p, 3]:
                known[t, p] = track_id
    touching = np.flatnonzero(~apart)
    if not len(touching) or not known:
        return 0.0
    seen = np.array(sorted(known))                    # (n, 2): frame apart, person
    found = 0
    for t in touching:
        if not reported[t]:
            continue
        points = np.array([c for _, c in reported[t]], float)
        distance = np.linalg.norm(points[:, None] - centroids[t][None], axis=2)
        for r, p in zip(*linear_sum_assignment(distance)):
            frames = seen[seen[:, 1] == p, 0]
            if len(frames) and distance[r, p] <= 0.5 * boxes[t, p, 3]:
                expected = known[int(frames[np.argmin(np.abs(frames - t))]), int(p)]
                found += reported[t][r][0] == expected
    return found / (len(touching) * people)


def evaluate_mirror_crossing(video: str | Path, offset: int = 0, tint: bool = False,
                             frames: np.ndarray | None = None) -> dict:
    """identity_measures of the tracker on mirror_crossing(video's frames, its truth, offset,
    tint); ``frames``: the video's frames when already read."""
    frames = read_frames(video) if frames is None else frames
    clip, background, centroids, boxes = mirror_crossing(frames, load_truth(video), offset,
                                                         tint)
    return identity_measures(track_identities(clip, background), centroids, boxes)
