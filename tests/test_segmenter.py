"""The learned person segmenter (track --silhouettes segment/auto, issue 54): real frames of a
person who never leaves the spot, a short clip through ``track``, camera motion on a synthetic
pan, and what happens without the segment extra."""
from __future__ import annotations

import json
import warnings

import cv2
import numpy as np
import pytest

from sequences.video import textured_background
from tests.test_track_cli import _assert_one_line_error, _noise_video, _track
from tracker import cli
from tracker.video import segmenter, sources
from tracker.video.camera_motion import camera_moves
from lab.silhouette_evaluation import silhouette_measures, track_masks
from tracker.pipeline import TrackerSettings, default_extractor
from tracker.video.sources import (INSTALL_HINT, AutoExtractor, segmenter_available,
                                   silhouette_extractor)
from tracker.video.segmenter import CameraMotionMeter, PersonSegmenter, merge_boxes

SAMPLE = "sequences/data/sample_spiral_walk.mp4"
needs_segmenter = pytest.mark.skipif(
    not segmenter_available(),
    reason=f"the person segmenter is not installed ({INSTALL_HINT}; scripts/test.sh installs it)")


def panning_frames(count: int, step_px: int, size=(240, 320), seed: int = 5) -> list:
    """``count`` frames (BGR uint8) of a window of ``size`` (height, width) moving ``step_px``
    px right per frame over a wide textured scene, with sensor noise."""
    height, width = size
    scene = cv2.cvtColor(textured_background((height, width + count * step_px + 1), seed),
                         cv2.COLOR_RGB2BGR)
    rng = np.random.default_rng(seed)
    return [cv2.add(scene[:, t * step_px:t * step_px + width],
                    rng.integers(0, 4, (height, width, 3), dtype=np.uint8))
            for t in range(count)]


def still_frames(count: int, size=(240, 320), seed: int = 5, speed: int = 6) -> list:
    """``count`` frames of a still camera on the same kind of scene, a dark figure walking
    across it (``speed`` px a frame), with sensor noise."""
    height, width = size
    scene = cv2.cvtColor(textured_background(size, seed), cv2.COLOR_RGB2BGR)
    rng = np.random.default_rng(seed)
    frames = []
    for t in range(count):
        frame = scene.copy()
        cv2.ellipse(frame, (40 + speed * t, 140), (18, 60), 0, 0, 360, (40, 60, 160), -1)
        frames.append(cv2.add(frame, rng.integers(0, 4, frame.shape, dtype=np.uint8)))
    return frames


def test_camera_motion_is_seen_in_a_pan_and_not_with_a_still_camera():
    """A pan of 2 px a frame (0.6 % of the width) is motion within a few frames; a still
    camera with a person walking across is not, frame by frame or over samples."""
    pan, still = panning_frames(40, 2), still_frames(40)
    meter = CameraMotionMeter()
    answers = [meter(f) for f in pan]
    assert answers[-1] and meter.moving_since is not None and meter.moving_since <= 10
    meter = CameraMotionMeter()
    assert not any(meter(f) for f in still) and meter.moving_since is None
    assert camera_moves(pan[::4]) and not camera_moves(still[::4])


def test_black_frames_before_a_still_scene_are_not_camera_motion():
    """A clip that starts black (a fade-in) and has a black glitch inside: comparing the first
    scene frames with the black ones made a run of "moved" answers (track's auto mode then
    switched to the segmenter); frames with nothing to align are skipped."""
    still = still_frames(30)
    black = np.zeros_like(still[0])
    frames = [black] * 12 + still[:10] + [black] + still[10:]
    meter = CameraMotionMeter()
    assert not any(meter(f) for f in frames) and meter.moving_since is None
    assert not camera_moves(frames[::3])
    pan = panning_frames(40, 2)
    meter = CameraMotionMeter()                             # a pan after black still counts
    assert [meter(f) for f in [black] * 12 + pan][-1]


def test_auto_without_the_segmenter_stays_with_background_and_says_how_to_get_it():
    """A panning clip's samples: the camera moves; without the extra the background path is
    kept and one warning names the install command."""
    settings = TrackerSettings()
    auto = AutoExtractor(lambda **o: default_extractor(settings, **o), None)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        auto.prime(panning_frames(25, 8))
    assert auto.source == "background" and auto.reason == "the camera moves"
    assert len(caught) == 1 and INSTALL_HINT in str(caught[0].message)


def test_segment_without_the_extra_is_one_line_naming_the_install(tmp_path, monkeypatch):
    monkeypatch.setattr(sources, "segmenter_available", lambda: False)
    video = _noise_video(tmp_path / "v.mp4", frames=5)
    result = _track(video, "--silhouettes", "segment", "--json", tmp_path / "o.json")
    _assert_one_line_error(result, "--silhouettes segment", INSTALL_HINT)
    assert not (tmp_path / "o.json").exists()


def test_silhouettes_option_refuses_other_sources(tmp_path):
    video = _noise_video(tmp_path / "v.mp4", frames=5)
    result = _track(video, "--silhouettes", "grabcut")
    assert result.returncode == 2 and "--silhouettes" in result.stderr
    assert "Traceback" not in result.stderr
    # The command's copies (kept import-free) are the module's.
    assert cli.SILHOUETTE_SOURCES == sources.SOURCES
    assert cli.SEGMENT_INSTALL == sources.INSTALL_HINT
    with pytest.raises(ValueError, match="grabcut"):
        silhouette_extractor("grabcut", TrackerSettings())


def test_boxes_of_one_person_merge_and_people_side_by_side_stay_apart():
    """A detection and the last frame's box of one person (IoU 0.6), and a moving arm's blob
    inside it, become one crop; a person standing behind whose box overlaps a little (Pose2Sim
    cam02's still woman, 15 % of her box) keeps a crop of her own."""
    person, again = [80, 110, 230, 350], [90, 120, 240, 360]
    arm, behind = [200, 150, 236, 190], [203, 131, 275, 274]
    merged = merge_boxes(np.array([person, again, arm, behind]))
    assert sorted(merged.tolist()) == [[80, 110, 240, 360], [203, 131, 275, 274]]


@needs_segmenter
def test_segmenter_follows_the_still_person_on_a_real_view(pose2sim_trial):
    """Pose2Sim's balancing, cam01's first 30 frames at full size: the median of the clip
    holds the person, the segmenter needs no empty scene. One track in every frame holding
    most keypoints (the whole view: 88.8 %, docs/segmenter.md), little spill. track's auto
    keeps background subtraction there (a still camera)."""
    from sequences.pose2sim import load_trial, project_reference
    from tracker.video.decode import open_video
    trial = load_trial(pose2sim_trial)
    source = open_video(trial.video("cam01"))
    samples = source.sample_frames(25)
    frames = [(i, f) for i, _, f in source if i < 30]
    extractor = PersonSegmenter()
    extractor.prime(samples)
    measures = silhouette_measures(track_masks(frames, extractor),
                                   project_reference("cam01", np.arange(30), trial))
    assert measures["coverage"] >= 0.75 and measures["spill"] <= 0.15, measures
    assert measures["main_track_fraction"] == 1.0, measures
    settings = TrackerSettings()
    default = silhouette_extractor("auto", settings)
    default.prime(samples)
    default(frames[0][1])
    assert default.source == "background" and default.reason is None


@needs_segmenter
def test_track_with_the_segmenter_follows_the_sample_walker(tmp_path):
    """The shipped sample's first two seconds through ``track --silhouettes segment``: one
    track holding (nearly) every frame, as background subtraction gives."""
    out = tmp_path / "s.json"
    result = _track(SAMPLE, "--silhouettes", "segment", "--end", "2", "--json", out,
                    "--quiet", "--workers", "2")
    assert result.returncode == 0, result.stderr
    tracks = json.loads(out.read_text())["tracks"]
    frames = sorted((len(t["frames"]) for t in tracks), reverse=True)
    assert frames[0] >= 55, frames


def dark_person_model(image: np.ndarray) -> np.ndarray:
    """A stand-in for the selfie model: person probability 1 where the image (BGR uint8) is
    dark red-brown (the figure of :func:`panning_figure_frames`), else 0."""
    near = np.abs(image.astype(np.int16) - (42, 62, 162)).max(axis=-1) <= 6
    return near.astype(np.float32)


def panning_figure_frames(count: int, step_px: int) -> list:
    """:func:`panning_frames` with a figure standing in the middle of the view (a camera
    turning to follow its subject: the scene moves behind it)."""
    frames = panning_frames(count, step_px)
    for frame in frames:
        cv2.ellipse(frame, (160, 130), (12, 45), 0, 0, 360, (40, 60, 160), -1)
    return frames


def test_segment_sees_a_pan_in_the_samples_and_proposes_no_moving_blobs_as_auto():
    """A panning clip: the samples run._prime gives (learn_zone) show the pan, so the
    segmenter proposes no moving blobs of its background model from the first frame on,
    and ``--silhouettes segment`` gives the same masks as ``auto``. Its own per-frame meter
    sees the pan only after about ten frames: those frames' blobs (the whole moving scene)
    had changed its first crops, and the filter's first headings with them (16_11's
    panning render, docs/segmenter.md). A still camera's samples keep the blobs."""
    frames = panning_figure_frames(40, 4)
    samples, median = frames[::4], np.median(np.stack(frames[::4]), axis=0).astype(np.uint8)
    settings = TrackerSettings()
    segment = PersonSegmenter(model=dark_person_model)
    auto = AutoExtractor(lambda **o: default_extractor(settings, **o),
                         PersonSegmenter(model=dark_person_model))
    subtracted, subtract = [], segment.subtractor.subtract
    segment.subtractor.subtract = lambda frame: subtracted.append(1) or subtract(frame)
    for extractor in (segment, auto):
        extractor.prime(median)
        extractor.learn_zone(samples)
    assert auto.source == "segment"
    for frame in frames:
        ours, theirs = segment(frame), auto(frame)
        assert len(ours) == len(theirs) == 1
        assert np.array_equal(ours[0].mask, theirs[0].mask)
    assert not subtracted and segment.crops == auto.segmenter.crops
    still = PersonSegmenter(model=dark_person_model)
    still.learn_zone(still_frames(40)[::4])
    assert still.use_motion


class FirstSearchModel:
    """A stand-in for the selfie model (:func:`dark_person_model`) whose search of the whole
    frame (an image of ``frame_shape``) finds the figure the first time only, as a search at
    working size misses a smaller person (CMU 02_02's panning walker)."""

    def __init__(self, frame_shape):
        self.frame_shape, self.searched = frame_shape, False

    def __call__(self, image):
        if image.shape[:2] == self.frame_shape:
            if self.searched:
                return np.zeros(image.shape[:2], np.float32)
            self.searched = True
        return dark_person_model(image)


class CropHog:
    """A stand-in for OpenCV's HOG detector: a person in every image CONFIRM_HEIGHT px high
    (a followed person's crop, :func:`segmenter.hog_confirms`) when ``sees``, none elsewhere."""

    def __init__(self, sees: bool):
        self.sees = sees

    def detectMultiScale(self, image, **options):
        if self.sees and image.shape[0] == segmenter.CONFIRM_HEIGHT:
            return np.array([[0, 0, 64, 128]]), np.array([[1.0]])
        return (), ()


@pytest.mark.parametrize("sees", [True, False])
def test_a_followed_person_the_search_misses_stays_while_hog_confirms_them_in_their_crop(sees):
    """A person found once and then followed from crop to crop, whom later searches (at
    working size) miss: HOG in their own crop keeps them (every frame); without it they are
    dropped search_every frames after the search that missed them, not at once."""
    frames = still_frames(50, speed=2)
    extractor = PersonSegmenter(model=FirstSearchModel(frames[0].shape[:2]), use_motion=False)
    extractor.hog = CropHog(sees)
    found = [len(extractor(frame)) for frame in frames]
    expected = [1] * 50 if sees else [1] * 30 + [0] * 20
    assert found == expected


@pytest.mark.skipif(segmenter.hog_detector() is None, reason="this OpenCV has no HOG detector")
def test_hog_finds_a_person_in_their_crop_whom_it_misses_at_working_size():
    """The sample's walker in a frame twice the size (the person about 140 px of 480): HOG on
    the frame at working size (320 px wide) misses them, in their own crop it finds them."""
    from tracker.video.decode import open_video
    source = open_video(SAMPLE)
    plate = np.median(np.stack(source.sample_frames(15)), axis=0).astype(np.int16)
    frame = next(f for i, _, f in source if i == 30)
    body = np.argwhere(np.abs(frame.astype(np.int16) - plate).max(axis=2) > 30)
    (y0, x0), (y1, x1) = body.min(axis=0), body.max(axis=0)
    big = np.zeros((480, 640, 3), np.uint8)
    big[120:360, 160:480] = frame
    hog = segmenter.hog_detector()
    assert len(segmenter.hog_boxes(hog, cv2.resize(big, (320, 240)))) == 0
    assert segmenter.hog_confirms(hog, big, (x0 + 160, y0 + 120, x1 + 161, y1 + 121))


@pytest.mark.parametrize("axes", [(16, 55), (40, 110)])
def test_a_pan_is_seen_behind_a_subject_the_camera_follows(axes):
    """A camera turning to follow its subject: the figure stays in the middle of the view (3.6
    and 18 % of it) while the scene pans 4 px a frame behind. The figure held the phase
    correlation's highest peak at no shift, and the pan went unseen (samples and per frame);
    the runner-up peak, kept where it aligns the scene, is the pan. A still camera with a
    figure walking across still never moves."""
    frames = panning_frames(40, 4)
    for frame in frames:
        cv2.ellipse(frame, (160, 130), axes, 0, 0, 360, (40, 60, 160), -1)
    meter = CameraMotionMeter()
    answers = [meter(f) for f in frames]
    assert camera_moves(frames[::4]) and answers[-1] and meter.moving_since <= 10
    for speed in (2, 6):
        meter = CameraMotionMeter()
        still = still_frames(40, speed=speed)
        assert not any(meter(f) for f in still) and not camera_moves(still[::4])
