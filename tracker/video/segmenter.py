"""People's silhouettes from a learned person segmenter, where background subtraction cannot work.

MediaPipe's selfie segmentation (weights inside the ``mediapipe`` wheel) tells person from
background in one image but finds nobody under about a third of its height, so it runs on crops
around people: HOG's boxes and the whole frame's segmentation (every SEARCH_EVERY frames), a
background model's moving blobs (still camera only) and the previous frame's people. Each crop's
person is split by :func:`tracker.video.silhouettes.person_masks` into :class:`PersonMask`.
An optional extra (:data:`tracker.video.sources.INSTALL_HINT`). MediaPipe's graph is made on
first use, in the process that segments: one made before a fork breaks the forked process's.
"""
from __future__ import annotations

import contextlib
import os
import sys
from collections import deque

import cv2
import numpy as np

from tracker.video.area_shrink import shrink
from tracker.video.camera_motion import MIN_SHIFT, camera_moves, flat, frame_shift, small_grey
from tracker.video.noise_floor import FOREGROUND_LEVEL
from tracker.video.silhouettes import (DEFAULT_MIN_AREA_FRACTION, BackgroundSubtractor,
                                       PersonMask, clean_mask, median_background, person_masks)
from tracker.video.decode import colourless

#: Frames between searches for new people (HOG and the whole frame segmented); in between,
#: people are followed from their previous boxes and from the moving blobs.
SEARCH_EVERY = 15
#: A crop reaches this share of its person's box height beyond the box on every side.
CROP_MARGIN = 0.25
#: Crops are shrunk to at most this side before segmentation (the model works at 256x256).
MAX_CROP_SIDE = 256
#: Person probability at which a pixel is person (chosen on Pose2Sim: docs/code_notes/video.md).
PERSON_PROBABILITY = 0.3
#: HOG detections below this SVM score are dropped (OpenCV's default people detector).
MIN_HOG_SCORE = 0.5
#: The per-frame camera-motion meter compares a frame with the one this many frames earlier.
STEP_FRAMES = 5
#: Consecutive comparisons that must show motion before the meter says the camera moves.
MOVING_RUN = 3


#: The process ids in which a MediaPipe graph was made (forking them breaks: made_a_graph).
_GRAPH_PROCESSES: set[int] = set()


def made_a_graph() -> bool:
    """Whether this process has made a MediaPipe graph: a process forked from it then crashes
    making its own (a segfault), so tracker.run keeps such a run in one process."""
    return os.getpid() in _GRAPH_PROCESSES


class CameraMotionMeter:
    """Per-frame camera motion: called with each frame (BGR uint8 (H, W, 3)) in order, whether
    the last ``run`` comparisons of a frame with the one ``step`` frames earlier all moved
    (flat frames skipped). :attr:`moving_since`: the frame count at the first yes (or None)."""

    def __init__(self, step: int = STEP_FRAMES, run: int = MOVING_RUN):
        if step < 1 or run < 1:
            raise ValueError(f"step={step} and run={run} must be at least 1")
        self.step, self.run = step, run
        self._recent: deque = deque(maxlen=step + 1)
        self._streak = 0
        self.frames = 0
        self.moving_since: int | None = None

    def __call__(self, frame: np.ndarray) -> bool:
        grey = small_grey(frame)
        self.frames += 1
        if flat(grey):                      # nothing to compare: the answer stays as it was
            return self._streak >= self.run
        if self._recent and self._recent[0].shape != grey.shape:
            self._recent.clear()
        self._recent.append(grey)
        if len(self._recent) <= self.step:
            return False
        shift, _ = frame_shift(self._recent[0], grey)
        self._streak = self._streak + 1 if shift >= MIN_SHIFT else 0
        moving = self._streak >= self.run
        if moving and self.moving_since is None:
            self.moving_since = self.frames
        return moving


class SelfieModel:
    """MediaPipe's selfie segmentation (general model), made on first call: ``model(image)``
    with a BGR uint8 (h, w, 3) image gives float32 (h, w) person probabilities 0..1."""

    def __init__(self):
        self._graph = None

    def __call__(self, image: np.ndarray) -> np.ndarray:
        rgb = cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
        if self._graph is None:
            with _native_stderr_silenced():     # its start-up notes, one per process
                import mediapipe as mp
                _GRAPH_PROCESSES.add(os.getpid())
                self._graph = mp.solutions.selfie_segmentation.SelfieSegmentation(
                    model_selection=0)
                return self._graph.process(rgb).segmentation_mask
        return self._graph.process(rgb).segmentation_mask


@contextlib.contextmanager
def _native_stderr_silenced():
    """File descriptor 2 pointed at os.devnull inside the block: MediaPipe's native start-up
    notes bypass sys.stderr, and ``track``'s errors and warnings are one line each."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def hog_detector() -> cv2.HOGDescriptor | None:
    """OpenCV's HOG people detector with its built-in weights; None where this OpenCV has none
    (OpenCV 5 moved it out of the main modules)."""
    if not hasattr(cv2, "HOGDescriptor"):
        return None
    hog = cv2.HOGDescriptor()
    hog.setSVMDetector(cv2.HOGDescriptor_getDefaultPeopleDetector())
    return hog


def hog_boxes(hog: cv2.HOGDescriptor | None, image: np.ndarray,
              min_score: float = MIN_HOG_SCORE) -> np.ndarray:
    """Boxes (n, 4) x0, y0, x1, y1 px of the people HOG finds in ``image`` (BGR uint8); none
    without a detector or under its 64x128 px window."""
    if hog is None or image.shape[0] < 128 or image.shape[1] < 64:
        return np.zeros((0, 4), int)
    rects, scores = hog.detectMultiScale(image, winStride=(8, 8), padding=(8, 8), scale=1.05)
    if len(rects) == 0:
        return np.zeros((0, 4), int)
    rects = np.asarray(rects).reshape(-1, 4)[np.asarray(scores).ravel() >= min_score]
    return np.column_stack([rects[:, :2], rects[:, :2] + rects[:, 2:]]).astype(int)


def blob_boxes(mask: np.ndarray, min_area: float, max_area: float) -> np.ndarray:
    """Boxes (n, 4) x0, y0, x1, y1 px of ``mask``'s (uint8 (h, w), nonzero = set) external
    blobs whose area lies between ``min_area`` and ``max_area`` px."""
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    boxes = [cv2.boundingRect(c) for c in contours if min_area <= cv2.contourArea(c) <= max_area]
    boxes = np.array(boxes, int).reshape(-1, 4)
    return np.column_stack([boxes[:, :2], boxes[:, :2] + boxes[:, 2:]])


#: A box under max_part of another's height is a part of it (a moving limb's blob) when this
#: share of it lies inside the other; a person standing behind has less (Pose2Sim: 0.15).
PART_INSIDE = 0.3


def merge_boxes(boxes: np.ndarray, min_iou: float = 0.3, min_inside: float = 0.6,
                max_part: float = 0.5) -> np.ndarray:
    """Boxes (n, 4) x0, y0, x1, y1, those of one person replaced by their union until none are
    left: intersection over union at least ``min_iou``, or covering ``min_inside`` of the
    smaller, or the smaller under ``max_part`` of the other's height with PART_INSIDE of it
    inside. Others stay apart: a crop with two people segments only the more prominent."""
    boxes = [tuple(int(v) for v in b) for b in np.asarray(boxes).reshape(-1, 4)]
    merged = True
    while merged and len(boxes) > 1:
        merged = False
        for i in range(len(boxes)):
            for j in range(i + 1, len(boxes)):
                if _one_person(boxes[i], boxes[j], min_iou, min_inside, max_part):
                    a, b = boxes[i], boxes[j]
                    boxes[i] = (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]),
                                max(a[3], b[3]))
                    del boxes[j]
                    merged = True
                    break
            if merged:
                break
    return np.array(boxes, int).reshape(-1, 4)


def _one_person(a, b, min_iou: float, min_inside: float, max_part: float) -> bool:
    """Whether boxes a and b (x0, y0, x1, y1) show one person (:func:`merge_boxes`)."""
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    if w <= 0 or h <= 0:
        return False
    areas = [max(1, (a[2] - a[0]) * (a[3] - a[1])), max(1, (b[2] - b[0]) * (b[3] - b[1]))]
    heights = sorted([a[3] - a[1], b[3] - b[1]])
    inter = w * h
    return (inter >= min_iou * (sum(areas) - inter) or inter >= min_inside * min(areas)
            or (heights[0] < max_part * heights[1] and inter >= PART_INSIDE * min(areas)))


#: A person's next crop is at least this share of the box it was found in, on each axis, so a
#: mask that lost a limb or the head does not shrink the next crop.
BOX_HOLD = 0.9


def held_boxes(found: np.ndarray, proposed: np.ndarray, hold: float = BOX_HOLD) -> np.ndarray:
    """The boxes (n, 4) x0, y0, x1, y1 to look in next frame: each found box (n, 4), grown
    about its centre to at least ``hold`` x the width and height of the proposed box (m, 4)
    holding that centre, if any."""
    out = []
    for box in np.asarray(found).reshape(-1, 4):
        cx, cy = (box[0] + box[2]) / 2, (box[1] + box[3]) / 2
        width, height = box[2] - box[0], box[3] - box[1]
        for p in np.asarray(proposed).reshape(-1, 4):
            if p[0] <= cx <= p[2] and p[1] <= cy <= p[3]:
                width = max(width, hold * (p[2] - p[0]))
                height = max(height, hold * (p[3] - p[1]))
                break
        out.append((cx - width / 2, cy - height / 2, cx + width / 2, cy + height / 2))
    return np.round(np.array(out, float).reshape(-1, 4)).astype(int)


def overlapping(boxes: np.ndarray, others: np.ndarray) -> np.ndarray:
    """bool (n,): whether each box (n, 4) x0, y0, x1, y1 overlaps one of ``others`` (m, 4)."""
    boxes, others = np.asarray(boxes).reshape(-1, 4), np.asarray(others).reshape(-1, 4)
    if not len(boxes) or not len(others):
        return np.zeros(len(boxes), bool)
    overlap_x = np.minimum(boxes[:, None, 2], others[None, :, 2]) > np.maximum(
        boxes[:, None, 0], others[None, :, 0])
    overlap_y = np.minimum(boxes[:, None, 3], others[None, :, 3]) > np.maximum(
        boxes[:, None, 1], others[None, :, 1])
    return (overlap_x & overlap_y).any(axis=1)


def confirmed(boxes: np.ndarray, found: np.ndarray) -> np.ndarray:
    """The boxes (n, 4) x0, y0, x1, y1 that overlap one of ``found`` (m, 4), so that a false
    find (a heap of clothes) does not feed itself for ever."""
    boxes = np.asarray(boxes).reshape(-1, 4)
    return boxes[overlapping(boxes, found)]


#: A followed person's crop is scaled to this height (px) for HOG to confirm them: their box
#: is then about 100 px high, inside the detector's 64x128 window.
CONFIRM_HEIGHT = 160


def hog_confirms(hog: cv2.HOGDescriptor | None, frame: np.ndarray, box,
                 height: int = CONFIRM_HEIGHT) -> bool:
    """Whether HOG finds a person in the window around ``box`` (x0, y0, x1, y1 px of
    ``frame``, BGR uint8; :func:`crop_window`) scaled to ``height`` px high, where the search
    at working size misses people under 128 px (figures: docs/code_notes). False without HOG."""
    x0, y0, x1, y1 = crop_window(box, (frame.shape[1], frame.shape[0]))
    if hog is None or x1 - x0 < 2 or y1 - y0 < 2:
        return False
    scale = height / (y1 - y0)
    crop = cv2.resize(frame[y0:y1, x0:x1], (max(64, round((x1 - x0) * scale)), height),
                      interpolation=cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR)
    return len(hog_boxes(hog, crop)) > 0


def crop_window(box, size: tuple[int, int], margin: float = CROP_MARGIN,
                min_aspect: float = 0.5) -> tuple[int, int, int, int]:
    """The window (x0, y0, x1, y1) px around a box (x0, y0, x1, y1), ``margin`` x its size
    beyond it on every side and at least ``min_aspect`` x its height wide (not square, which
    takes in the people beside), clipped to an image of ``size`` (width, height)."""
    x0, y0, x1, y1 = box
    height = (y1 - y0) * (1 + 2 * margin)
    width = max((x1 - x0) * (1 + 2 * margin), min_aspect * height)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    frame_width, frame_height = size
    return (max(0, int(cx - width / 2)), max(0, int(cy - height / 2)),
            min(frame_width, int(np.ceil(cx + width / 2))),
            min(frame_height, int(np.ceil(cy + height / 2))))


class PersonSegmenter:
    """Frame -> list of :class:`PersonMask` by segmenting crops around people; a drop-in for
    :class:`tracker.video.silhouettes.SilhouetteExtractor`.

    ``min_area_fraction`` / ``max_area_fraction``: as :func:`person_masks`. ``working_width``:
    px width of the image masks are pasted into (and of the motion model). ``search_every``:
    frames between searches, the first included. ``use_motion``: propose a background model's
    moving blobs while the camera stays still (:meth:`learn_zone`, CameraMotionMeter).
    ``model``: image -> person probabilities (default :class:`SelfieModel`). :attr:`crops`:
    crops segmented.
    """

    def __init__(self, min_area_fraction: float = DEFAULT_MIN_AREA_FRACTION,
                 max_area_fraction: float = 0.5, working_width: int = 320,
                 search_every: int = SEARCH_EVERY, margin: float = CROP_MARGIN,
                 probability: float = PERSON_PROBABILITY, use_motion: bool = True, model=None):
        if search_every < 1 or not 0.0 < probability < 1.0:
            raise ValueError(f"search_every={search_every} must be >= 1 and probability="
                             f"{probability} in (0, 1)")
        self.subtractor = BackgroundSubtractor(working_width=working_width)
        self.min_area_fraction, self.max_area_fraction = min_area_fraction, max_area_fraction
        self.search_every, self.margin, self.probability = search_every, margin, probability
        self.use_motion = use_motion
        self.model = model if model is not None else SelfieModel()
        self.hog = hog_detector()
        self.meter = CameraMotionMeter()
        self.frames = 0
        self.crops = 0
        self._previous = np.zeros((0, 4), int)       # last frame's people, working px
        self._unconfirmed = np.zeros((0, 4), int)    # of those, the last search's unfound
        self._confirm_left = 0                       # frames left to confirm them

    def prime(self, background, frame_size: tuple[int, int] | None = None) -> None:
        """Teach the motion model the scene, as :meth:`SilhouetteExtractor.prime` takes it
        (frames: their median); a colourless scene turns shadows off."""
        if not (isinstance(background, np.ndarray) and background.ndim == 3):
            frames = list(background)
            height, width = frames[0].shape[:2]
            size = self.subtractor.working_size(width, height)
            background = median_background([shrink(f, size) for f in frames])
            frame_size = (width, height)
        if colourless(background):
            self.subtractor = BackgroundSubtractor(working_width=self.subtractor.working_width,
                                                   detect_shadows=False)
        self.subtractor.prime(background, frame_size)

    def learn_zone(self, frames, median: np.ndarray | None = None, threads: int = 1) -> None:
        """Judge frames spread over the clip (``median``, ``threads``: unused): when the
        camera moves (:func:`tracker.video.camera_motion.camera_moves`) no moving blob is
        proposed from the first frame on (the per-frame meter would see a pan only after about
        ten frames)."""
        if self.use_motion and camera_moves(list(frames)):
            self.use_motion = False

    def __call__(self, frame: np.ndarray) -> list[PersonMask]:
        """The people in ``frame`` (BGR uint8 (H, W, 3)); frames go in order."""
        size = (frame.shape[1], frame.shape[0])
        work = self.subtractor.working_size(*size)
        area = work[0] * work[1]
        limits = (self.min_area_fraction * area, self.max_area_fraction * area)
        # A moving camera makes everything a moving blob: none is proposed then.
        if self.use_motion and self.subtractor.reference is not None and not self.meter(frame):
            small, raw = self.subtractor.subtract(frame)
            moving = clean_mask(np.where(raw > FOREGROUND_LEVEL, 255, 0).astype(np.uint8))
            proposals = [self._previous, blob_boxes(moving, *limits)]
        else:
            small = shrink(frame, work)
            proposals = [self._previous]
        if self.frames % self.search_every == 0:
            found = np.vstack([self.search(small)] + proposals[1:])
            if self.hog is None:
                proposals[0] = confirmed(self._previous, found)
            else:               # the unfound are kept while HOG is asked in their crops
                self._unconfirmed = self._previous[~overlapping(self._previous, found)]
                self._confirm_left = self.search_every
            proposals.append(found)
        self.frames += 1
        crops = merge_boxes(np.vstack(proposals))
        people = self.people_in_crops(frame, small, crops)
        scale = np.array([work[0] / size[0], work[1] / size[1]] * 2)
        boxes = np.array([(x, y, x + w, y + h) for x, y, w, h in (p.bbox for p in people)])
        followed = held_boxes(np.round(boxes.reshape(-1, 4) * scale).astype(int), crops)
        self._previous = self._confirm(frame, followed, scale)
        return people

    def _confirm(self, frame: np.ndarray, boxes: np.ndarray, scale: np.ndarray) -> np.ndarray:
        """The boxes (n, 4) working px to follow next frame: ``boxes`` without those the last
        search missed (:attr:`_unconfirmed`) that HOG has not confirmed in their crop
        (:func:`hog_confirms`; ``scale``: working px per frame px, x and y twice) within
        ``search_every`` frames (dropping them at once split a panning walker's track)."""
        if not len(self._unconfirmed):
            return boxes
        waiting = overlapping(boxes, self._unconfirmed)
        for i in np.flatnonzero(waiting):
            waiting[i] = not hog_confirms(self.hog, frame, boxes[i] / scale)
        self._confirm_left -= 1
        if self._confirm_left <= 0:
            self._unconfirmed = boxes[:0]
            return boxes[~waiting]
        self._unconfirmed = boxes[waiting]
        return boxes

    def search(self, small: np.ndarray) -> np.ndarray:
        """Boxes (n, 4) x0, y0, x1, y1 px of the people in ``small`` (a frame at working size):
        HOG's and the whole image's segmented blobs."""
        area = small.shape[0] * small.shape[1]
        found = (self.model(small) >= self.probability).astype(np.uint8) * 255
        return np.vstack([hog_boxes(self.hog, small),
                          blob_boxes(found, self.min_area_fraction * area,
                                     self.max_area_fraction * area)])

    def crop_probability(self, frame: np.ndarray, small: np.ndarray, box
                         ) -> tuple[tuple[int, int, int, int], np.ndarray] | None:
        """(the window (x0, y0, x1, y1) working px around ``box`` (working px), its person
        probabilities float32 at that size), cut from the full ``frame``, shrunk to
        MAX_CROP_SIDE; None for a degenerate window."""
        height, width = small.shape[:2]
        sx, sy = frame.shape[1] / width, frame.shape[0] / height
        x0, y0, x1, y1 = crop_window(box, (width, height), self.margin)
        if x1 - x0 < 2 or y1 - y0 < 2:
            return None
        crop = frame[int(y0 * sy):int(np.ceil(y1 * sy)), int(x0 * sx):int(np.ceil(x1 * sx))]
        scale = min(1.0, MAX_CROP_SIDE / max(crop.shape[:2]))
        if scale < 1.0:
            crop = shrink(crop, (max(1, int(crop.shape[1] * scale)),
                                 max(1, int(crop.shape[0] * scale))))
        self.crops += 1
        return (x0, y0, x1, y1), cv2.resize(self.model(crop), (x1 - x0, y1 - y0),
                                            interpolation=cv2.INTER_LINEAR)

    def people_in_crops(self, frame: np.ndarray, small: np.ndarray, boxes: np.ndarray
                        ) -> list[PersonMask]:
        """One person per box (working px) at most, largest first: the person of its crop
        (thresholded, within half the crop's margin of the box) whose box overlaps it most.
        Each crop gives its own mask, so two people whose masks touch stay two; a person found
        by two crops is kept once (:func:`_distinct`)."""
        size = (frame.shape[1], frame.shape[0])
        height, width = small.shape[:2]
        scale = np.array([size[0] / width, size[1] / height] * 2)
        people: list[PersonMask] = []
        for box in boxes:
            cut = self.crop_probability(frame, small, box)
            if cut is None:
                continue
            (x0, y0, x1, y1), probability = cut
            canvas = np.zeros((height, width), np.uint8)
            canvas[y0:y1, x0:x1] = np.where(probability >= self.probability, 255, 0)
            # Only near the box: a neighbour in the crop must not draw the mask to them.
            a0, b0, a1, b1 = crop_window(box, (width, height), self.margin / 2, 0.0)
            canvas[:b0], canvas[b1:], canvas[:, :a0], canvas[:, a1:] = 0, 0, 0, 0
            found = person_masks(canvas, size, self.min_area_fraction, image=small,
                                 max_area_fraction=self.max_area_fraction)
            overlaps = [_iou(_corners(p.bbox), np.asarray(box) * scale) for p in found]
            if found and max(overlaps) > 0:
                people.append(found[int(np.argmax(overlaps))])
        return _distinct(people)


#: Two crops' people are one when this share of the smaller one's box lies in the other's.
DUPLICATE_SHARE = 0.5


def _corners(bbox) -> np.ndarray:
    """(x, y, w, h) -> (x0, y0, x1, y1)."""
    x, y, w, h = bbox
    return np.array([x, y, x + w, y + h], float)


def _intersection(a: np.ndarray, b: np.ndarray) -> float:
    """Area of the intersection of two boxes (x0, y0, x1, y1)."""
    w = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    h = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    return float(w * h)


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two boxes (x0, y0, x1, y1)."""
    inter = _intersection(a, b)
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return float(inter / union) if union > 0 else 0.0


def _distinct(people: list[PersonMask]) -> list[PersonMask]:
    """People (largest first) without those whose box lies by DUPLICATE_SHARE or more inside
    a larger one's (a second crop's piece of one person had split their track)."""
    kept: list[PersonMask] = []
    for person in sorted(people, key=lambda p: -p.area):
        box = _corners(person.bbox)
        own = max(1.0, (box[2] - box[0]) * (box[3] - box[1]))
        if all(_intersection(box, _corners(k.bbox)) < DUPLICATE_SHARE * own for k in kept):
            kept.append(person)
    return kept
