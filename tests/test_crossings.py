"""People who cross: one blob while they overlap, and still the same two people after."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from conftest import load_script, refused_in_one_line
from tracker.tracks.association import AssociationError, Associator
from lab.crossings import (identity_measures, mirror_crossing, read_frames,
                                       track_identities)
from tracker.video.silhouettes import COLOUR_BINS, colour_histogram
from sequences.video import load_truth

SAMPLE = Path(__file__).resolve().parents[1] / "sequences" / "data" / "sample_spiral_walk.mp4"


@dataclass
class Blob:
    centroid: tuple[float, float]
    area: int
    bbox: tuple[float, float, float, float]
    colour: np.ndarray


def _colour(hue: int, rng) -> np.ndarray:
    """A colour histogram (COLOUR_BINS,) mostly in one bin, with some noise."""
    hist = rng.uniform(0, 0.02, COLOUR_BINS)
    hist[hue] += 1.0
    return hist / hist.sum()


def _person(x: float, colour: np.ndarray) -> Blob:
    return Blob((x, 200.0), 4000, (x - 20, 140.0, 40, 120), colour)


def _merged(a: float, b: float, rng) -> Blob:
    """Two people overlapping as one blob: one box around both, mixed colour."""
    x0, x1 = min(a, b) - 20, max(a, b) + 20
    colour = 0.5 * (_colour(3, rng) + _colour(40, rng))
    return Blob(((a + b) / 2, 200.0), int(4000 + 100 * (x1 - x0 - 40)),
                (x0, 140.0, x1 - x0, 120), colour)


def _run(paths, associator: Associator, seed: int = 0) -> tuple[dict, set]:
    """Feed two people at x = paths[t] = (a, b) px, one blob while within 40 px; returns
    each track id's (t, x) and the frames with one blob."""
    rng = np.random.default_rng(seed)
    history, merged = {}, set()
    for t, (a, b) in enumerate(paths):
        if abs(a - b) < 40:
            detections = [_merged(a, b, rng)]
            merged.add(t)
        else:
            detections = [_person(a, _colour(3, rng)), _person(b, _colour(40, rng))]
        for track_id, blob in associator.update(detections):
            history.setdefault(track_id, []).append((t, blob.centroid[0]))
    return history, merged


def test_boxes_that_cross_merged_for_39_frames_keep_their_two_ids():
    # 1 px a frame each: 39 frames as one blob (1.3 s at 30 fps), longer than max_missed.
    paths = [(100.0 + t, 260.0 - t) for t in range(190)]
    history, merged = _run(paths, Associator())
    assert len(merged) > Associator().max_missed
    assert set(history) == {0, 1}               # no id for the blob, none lost at the split
    assert history[0][0][1] < 110 and history[0][-1][1] > 280
    assert history[1][0][1] > 250 and history[1][-1][1] < 80
    # While merged the blob is neither person: no pose comes from a two-person silhouette.
    assert not merged & {t for points in history.values() for t, _ in points}


def test_people_who_turn_back_inside_the_blob_are_told_apart_by_colour():
    # They meet, stand as one blob for 6 frames and walk back the way they came: constant
    # velocity says they crossed, their colours say they did not.
    approach = [(100.0 + 4 * t, 260.0 - 4 * t) for t in range(20)]
    meet = [(178.0, 182.0)] * 6
    back = [(178.0 - 4 * t, 182.0 + 4 * t) for t in range(1, 20)]
    history, _ = _run(approach + meet + back, Associator())
    assert set(history) == {0, 1}
    assert history[0][-1][1] < 110 and history[1][-1][1] > 250
    without_colour, _ = _run(approach + meet + back, Associator(appearance_weight=0.0))
    assert without_colour[0][-1][1] > 250       # the motion alone swaps them


def test_a_fragment_of_one_person_makes_no_group():
    # The extractor cut a walker's legs off for a few frames (a second, short track); when
    # the legs join again the whole walker is one person, not a group of two.
    associator = Associator(min_hits=1)
    colour = _colour(3, np.random.default_rng(0))
    reported = []
    for t in range(12):
        x = 100.0 + 3 * t
        if 3 <= t < 8:
            people = [Blob((x, 180.0), 2400, (x - 20, 140.0, 40, 80), colour),
                      Blob((x, 250.0), 1200, (x - 15, 225.0, 30, 40), colour)]
        else:
            people = [Blob((x, 200.0), 4000, (x - 20, 140.0, 40, 120), colour)]
        reported.append([track_id for track_id, _ in associator.update(people)])
    assert all(0 in ids for ids in reported)


def test_two_overlapping_blobs_that_both_hold_both_people_make_one_group_at_most():
    """Two wide blobs whose boxes overlap, each holding both tracks' predictions: the second
    found its members taken (an IndexError of an empty argmax, a traceback for track)."""
    rng = np.random.default_rng(0)
    associator = Associator()
    for _ in range(5):
        associator.update([_person(200, _colour(3, rng)), _person(260, _colour(40, rng))])
    wide = [Blob((20, 200.0), 9000, (0, 130.0, 400, 140), _colour(3, rng)),
            Blob((480, 200.0), 9000, (100, 130.0, 400, 140), _colour(40, rng))]
    assert len(associator.update(wide)) <= 2


def test_bad_group_settings_are_refused():
    for bad in (dict(max_occluded=-1), dict(appearance_weight=-0.5), dict(colour_rate=0.0),
                dict(min_height_ratio=1.5)):
        with pytest.raises(AssociationError, match=str(next(iter(bad.values())))):
            Associator(**bad)


def test_colour_histogram_sums_to_one_inside_the_mask():
    image = np.zeros((20, 20, 3), np.uint8)
    image[:, :10] = (0, 0, 255)                  # red left, blue right
    image[:, 10:] = (255, 0, 0)
    mask = np.zeros((20, 20), np.uint8)
    mask[:, :10] = 255
    red = colour_histogram(image, mask)
    assert red.shape == (COLOUR_BINS,) and red.sum() == pytest.approx(1.0)
    blue = colour_histogram(image, 255 - mask)
    assert np.sqrt(red * blue).sum() == pytest.approx(0.0)
    assert not colour_histogram(image, np.zeros_like(mask)).any()


@pytest.fixture(scope="module")
def sample_crossing():
    """The sample's first crossing with its mirror image: 48 frames around the merge."""
    frames = read_frames(SAMPLE)
    clip, background, centroids, boxes = mirror_crossing(frames, load_truth(SAMPLE), tint=True)
    window = slice(50, 98)
    return clip[window], background, centroids[window], boxes[window]


def test_mirrored_sample_crossing_keeps_two_tracks_without_a_switch(sample_crossing):
    clip, background, centroids, boxes = sample_crossing
    reported = track_identities(clip, background)
    measures = identity_measures(reported, centroids, boxes)
    assert measures["crossings"] == 1
    assert measures["switches"] == 0
    assert measures["tracks_per_person"] == [1, 1]
    assert measures["found"] > 0.9
    assert {track_id for frame in reported for track_id, _ in frame} == {0, 1}


def test_old_association_switches_on_the_mirrored_sample(sample_crossing):
    # The measure itself: without groups the blob goes to one track and the other is lost.
    clip, background, centroids, boxes = sample_crossing
    reported = track_identities(clip, background, Associator(max_occluded=0))
    measures = identity_measures(reported, centroids, boxes)
    assert measures["switches"] >= 1 and max(measures["tracks_per_person"]) == 2


def test_mirror_crossing_pastes_the_mirrored_walker():
    frames = read_frames(SAMPLE)[:3]
    truth = {k: v[:3] for k, v in load_truth(SAMPLE).items() if k in ("centroid_px", "bbox_px")}
    clip, background, centroids, boxes = mirror_crossing(frames, truth, offset=1)
    assert clip.shape == (2, *frames.shape[1:])
    assert centroids[0, 1, 0] == pytest.approx(320 - truth["centroid_px"][1, 0, 0])
    x, y, w, h = boxes[0, 1].astype(int)
    copy = clip[0, y:y + h, x:x + w].astype(int)
    original = frames[1, y:y + h, ::-1][:, x:x + w].astype(int)
    walker = np.abs(original - background[y:y + h, ::-1][:, x:x + w]).max(axis=2) > 30
    assert np.abs(copy - original)[walker].max() == 0
    with pytest.raises(ValueError, match="offset"):
        mirror_crossing(frames, truth, offset=5)


def test_evaluate_crossings_refuses_bad_options_in_one_line(capsys, tmp_path):
    script = load_script("evaluate_crossings")
    assert "--video" in refused_in_one_line(script, ["--video", str(tmp_path / "no.mp4")],
                                            capsys)
    assert "--offsets" in refused_in_one_line(script, ["--offsets", "400"], capsys)
