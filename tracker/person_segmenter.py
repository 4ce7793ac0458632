"""A learned person segmenter that refines each person's mask inside its box.

Background subtraction cannot see behind a person who never leaves the spot: the clip's
background estimate shows them, so their mask carries ghosts (where a limb was earlier) and a
band of background round the outline (Pose2Sim's balancing trial: 20-32 % of each mask lies off
the body, tracker.offline.silhouette_evaluation). A segmenter looks at the image itself. Here
MediaPipe's selfie segmentation model (Apache 2.0, `tracker/models/`, taken from the PyPI wheel
of mediapipe 0.10.14; README there) runs through OpenCV's dnn module on a square crop round
each person the subtractor found, and its mask replaces the subtractor's: only the parts that
overlap the subtractor's mask are kept (a bystander in the crop stays out), and where the model
finds no person there the subtractor's mask is kept (it never loses a person).

Cost: one 256 x 256 pass per person and frame, about 4.3 ms on one core of this machine.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import cv2
import numpy as np

from regressor.errors import SilhouettePoseError

from .silhouettes import PersonMask

MODEL_PATH = Path(__file__).resolve().parent / "models" / "selfie_segmentation.tflite"
#: The shipped model's SHA-256: a damaged or replaced file is refused before OpenCV reads it.
MODEL_SHA256 = "9ee168ec7c8f2a16c56fe8e1cfbc514974cbbb7e434051b455635f1bd1462f5c"
INPUT_SIDE = 256          # px, the model's square input
MARGIN = 0.15             # the crop's margin round the person's box, a share of its longer side
THRESHOLD = 0.5           # the model's person probability above which a pixel is the person
MIN_KEPT = 0.05           # below this share of the subtractor's area, keep the subtractor's mask
NEAR = 0.04               # parts this close to the kept ones (a share of the crop's side) join
HOLE = 0.01               # holes below this share of the person's area are filled
GROW = 0.0                # the subtractor's pixels this close to the kept ones (x side) join
RECROP = 0.7              # a first answer's box under this share of the subtractor's: look again


class SegmenterError(SilhouettePoseError, ValueError):
    """The segmenter model is missing, damaged or unreadable; one line naming the file."""


class PersonSegmenter:
    """Refines PersonMasks (tracker.silhouettes) with the selfie segmentation model.

    ``model_path``: the .tflite file (default: the shipped one, checked against MODEL_SHA256;
    another file is taken as it is). Call with the frame (BGR uint8 (H, W, 3)) and its people
    (list of PersonMask, frame pixels); returns the refined list, same order and length."""

    def __init__(self, model_path: str | Path | None = None):
        path = MODEL_PATH if model_path is None else Path(model_path)
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise SegmenterError(f"segmenter model {path}: cannot read it ({exc.strerror})") from None
        if model_path is None and hashlib.sha256(data).hexdigest() != MODEL_SHA256:
            raise SegmenterError(f"segmenter model {path}: checksum mismatch (damaged or replaced)")
        try:
            self.net = cv2.dnn.readNetFromTFLite(str(path))
        except cv2.error:
            raise SegmenterError(f"segmenter model {path}: not a model OpenCV can read") from None
        self.path = path

    def probabilities(self, crops: np.ndarray) -> np.ndarray:
        """Person probability (N, 256, 256) in [0, 1] of square crops (N, 256, 256, 3) BGR uint8."""
        blob = cv2.dnn.blobFromImages(list(crops), 1.0 / 255.0, (INPUT_SIDE, INPUT_SIDE),
                                      swapRB=True)
        self.net.setInput(blob)
        return self.net.forward()[:, 0]

    def __call__(self, frame: np.ndarray, people: list[PersonMask]) -> list[PersonMask]:
        if not people:
            return people
        out = self._pass(frame, people, people)
        # The subtractor's box may hold ghosts far from the body; where the first answer is
        # much smaller than it, the person is small in the crop: look again, closer.
        again = [k for k, (a, b) in enumerate(zip(people, out))
                 if b is not a and max(b.bbox[2:]) < RECROP * max(a.bbox[2:])]
        if again:
            closer = self._pass(frame, [out[k] for k in again], [out[k] for k in again])
            for k, person in zip(again, closer):
                out[k] = person
        return out

    def _pass(self, frame: np.ndarray, boxes_of: list[PersonMask], anchors: list[PersonMask]
              ) -> list[PersonMask]:
        """One segmentation of a square crop round each of boxes_of's boxes, the parts kept
        being those near the matching anchor's mask (:func:`refined`)."""
        boxes = [square_box(p.bbox, frame.shape) for p in boxes_of]
        crops = np.stack([crop_square(frame, box, INPUT_SIDE) for box in boxes])
        prob = self.probabilities(crops)
        return [refined(anchor, box, p, frame.shape)
                for anchor, box, p in zip(anchors, boxes, prob)]


def square_box(bbox: tuple[int, int, int, int], frame_shape) -> tuple[int, int, int]:
    """(x0, y0, side) px: a square centred on bbox (x, y, w, h) px, its side the longer one plus
    MARGIN on each side; it may reach beyond the frame (crop_square pads)."""
    x, y, w, h = bbox
    side = max(int(round(max(w, h) * (1.0 + 2.0 * MARGIN))), 8)
    return int(round(x + w / 2.0 - side / 2.0)), int(round(y + h / 2.0 - side / 2.0)), side


def crop_square(frame: np.ndarray, box: tuple[int, int, int], out_side: int) -> np.ndarray:
    """The square box (x0, y0, side) of frame (H, W, 3), black beyond the frame, resized to
    (out_side, out_side, 3)."""
    x0, y0, side = box
    H, W = frame.shape[:2]
    crop = np.zeros((side, side, 3), frame.dtype)
    fx0, fy0, fx1, fy1 = max(x0, 0), max(y0, 0), min(x0 + side, W), min(y0 + side, H)
    if fx1 > fx0 and fy1 > fy0:
        crop[fy0 - y0:fy1 - y0, fx0 - x0:fx1 - x0] = frame[fy0:fy1, fx0:fx1]
    interp = cv2.INTER_AREA if side > out_side else cv2.INTER_LINEAR
    return cv2.resize(crop, (out_side, out_side), interpolation=interp)


def refined(person: PersonMask, box: tuple[int, int, int], prob: np.ndarray,
            frame_shape) -> PersonMask:
    """The person's mask from the model's probabilities prob (s, s) over the square box (x0,
    y0, side) px: the connected parts above THRESHOLD that touch person's mask, then those
    within NEAR x side of them (a head the model parts from the neck, a hand from the arm),
    small holes filled, clipped to the frame; person itself if they cover less than MIN_KEPT
    of its area."""
    x0, y0, side = box
    H, W = frame_shape[:2]
    fx0, fy0, fx1, fy1 = max(x0, 0), max(y0, 0), min(x0 + side, W), min(y0 + side, H)
    if fx1 <= fx0 or fy1 <= fy0:
        return person
    full = cv2.resize(prob.astype(np.float32), (side, side), interpolation=cv2.INTER_LINEAR)
    seg = (full[fy0 - y0:fy1 - y0, fx0 - x0:fx1 - x0] > THRESHOLD).astype(np.uint8)
    old = np.zeros_like(seg)                  # person's mask in the same window
    px, py, pw, ph = person.bbox
    ox0, oy0, ox1, oy1 = max(px, fx0), max(py, fy0), min(px + pw, fx1), min(py + ph, fy1)
    if ox1 > ox0 and oy1 > oy0:
        old[oy0 - fy0:oy1 - fy0, ox0 - fx0:ox1 - fx0] = \
            person.mask[oy0 - py:oy1 - py, ox0 - px:ox1 - px]
    _, labels = cv2.connectedComponents(seg, connectivity=8)
    keep = _parts(labels, (old > 0) & (seg > 0))
    if keep.sum() < MIN_KEPT * max(person.area, 1):
        return person
    reach = max(3, int(round(NEAR * side)))
    near = cv2.dilate(keep.astype(np.uint8), cv2.getStructuringElement(
        cv2.MORPH_ELLIPSE, (2 * reach + 1, 2 * reach + 1))) > 0
    keep |= _parts(labels, near & (seg > 0))
    if GROW > 0:
        # The model leaves out what it does not take for a person (a swimming cap seen from
        # behind); the subtractor's own pixels right beside its mask come back.
        grow = max(1, int(round(GROW * side)))
        beside = cv2.dilate(keep.astype(np.uint8), cv2.getStructuringElement(
            cv2.MORPH_ELLIPSE, (2 * grow + 1, 2 * grow + 1))) > 0
        keep |= beside & (old > 0)
    keep = _fill_small_holes(keep, HOLE * keep.sum())
    ys, xs = np.nonzero(keep)
    bx0, by0, bx1, by1 = xs.min(), ys.min(), xs.max() + 1, ys.max() + 1
    return PersonMask(mask=keep[by0:by1, bx0:bx1],
                      bbox=(int(fx0 + bx0), int(fy0 + by0), int(bx1 - bx0), int(by1 - by0)),
                      centroid=(float(fx0 + xs.mean()), float(fy0 + ys.mean())),
                      area=int(keep.sum()))


def _parts(labels: np.ndarray, touched: np.ndarray) -> np.ndarray:
    """bool mask of the labelled parts (labels from cv2.connectedComponents, 0 = none) that
    have a pixel in touched (bool, same shape)."""
    hit = np.unique(labels[touched])
    return np.isin(labels, hit[hit > 0])


def _fill_small_holes(mask: np.ndarray, max_area: float) -> np.ndarray:
    """bool mask with its enclosed holes of at most max_area pixels filled (larger ones, such
    as the gap between a hand on the hip and the trunk, stay)."""
    n, labels, stats, _ = cv2.connectedComponentsWithStats((~mask).astype(np.uint8), connectivity=4)
    h, w = mask.shape
    x, y, bw, bh, area = (stats[:, k] for k in range(5))
    inner = (x > 0) & (y > 0) & (x + bw < w) & (y + bh < h) & (area <= max_area)
    inner[0] = False                                # label 0: the mask itself
    return mask | inner[labels] & ~mask
