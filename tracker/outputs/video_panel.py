"""The video beside the skeletons: a small copy of the frame with each person's silhouette
outline and track id drawn in the track's colour, JPEG-encoded for the browser.

Costs about a millisecond per panel at 256 px wide (resize, one contour per person, encode),
so the live view makes a few a second, never one per frame.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import cv2
import numpy as np

from tracker.outputs.geometry import track_colour

if TYPE_CHECKING:
    from tracker.video.silhouettes import PersonMask


def _bgr(track_id: int) -> tuple[int, int, int]:
    r, g, b = (int(round(255 * c)) for c in track_colour(track_id))
    return b, g, r


def panel_image(frame: np.ndarray, people: Mapping[int, PersonMask], width_px: int = 256
                ) -> np.ndarray:
    """The frame (BGR uint8 (H, W, 3)) shrunk to ``width_px`` wide (never enlarged), with the
    outline of each person's mask (track id -> PersonMask, frame pixels) and its track id.
    Returns BGR uint8 (h, width_px, 3)."""
    height, width = frame.shape[:2]
    scale = min(1.0, width_px / width)
    size = (max(1, round(width * scale)), max(1, round(height * scale)))
    small = cv2.resize(frame, size, interpolation=cv2.INTER_AREA)
    for track_id, person in people.items():
        x, y = person.bbox[:2]
        contours, _ = cv2.findContours(person.mask.astype(np.uint8), cv2.RETR_EXTERNAL,
                                       cv2.CHAIN_APPROX_SIMPLE)
        colour = _bgr(track_id)
        outlines = [np.round((c.reshape(-1, 2) + (x, y)) * scale).astype(np.int32)
                    for c in contours]
        cv2.polylines(small, outlines, True, colour, 2, cv2.LINE_AA)
        corner = (int(x * scale), max(12, int(y * scale) - 3))
        cv2.putText(small, str(track_id), corner, cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 3,
                    cv2.LINE_AA)
        cv2.putText(small, str(track_id), corner, cv2.FONT_HERSHEY_SIMPLEX, 0.45, colour, 1,
                    cv2.LINE_AA)
    return small


def encode_jpeg(image: np.ndarray, quality: int = 80) -> bytes:
    """JPEG bytes of a BGR uint8 image."""
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise ValueError(f"could not encode a {image.shape} image as JPEG")
    return data.tobytes()


def label_image(text: str, rgb: tuple[float, float, float], size=(256, 64)) -> np.ndarray:
    """A transparent label: ``text`` in colour ``rgb`` ([0, 1]) with a dark outline, centred.
    Returns BGRA uint8 (size[1], size[0], 4), for a PNG (JPEG has no transparency)."""
    width, height = size
    image = np.zeros((height, width, 4), np.uint8)
    font, scale = cv2.FONT_HERSHEY_DUPLEX, 1.1
    (tw, th), _ = cv2.getTextSize(text, font, scale, 2)
    scale *= min(1.0, 0.95 * width / tw)
    (tw, th), _ = cv2.getTextSize(text, font, scale, 2)
    origin = ((width - tw) // 2, (height + th) // 2)
    b, g, r = (int(round(255 * c)) for c in rgb[::-1])
    cv2.putText(image, text, origin, font, scale, (30, 30, 30, 255), 7, cv2.LINE_AA)
    cv2.putText(image, text, origin, font, scale, (b, g, r, 255), 2, cv2.LINE_AA)
    return image


def encode_png(image: np.ndarray) -> bytes:
    """PNG bytes of a BGR or BGRA uint8 image."""
    ok, data = cv2.imencode(".png", image)
    if not ok:
        raise ValueError(f"could not encode a {image.shape} image as PNG")
    return data.tobytes()
