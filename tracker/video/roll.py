"""Turning silhouettes upright when the camera is rolled (``track --roll DEG``): the descriptor
keeps image axes, so a rolled camera shows the regressor a leaning body (figures: docs/code_notes).
"""
from __future__ import annotations

import cv2
import numpy as np


def upright_mask(mask: np.ndarray, roll_deg: float) -> np.ndarray:
    """The mask (h, w) bool turned roll_deg degrees anticlockwise (how far the scene's vertical
    leans clockwise in the image) on an (s, s) canvas, s = its diagonal + 4 px; 0: as it is."""
    if not roll_deg:
        return mask
    h, w = mask.shape
    side = int(np.ceil(np.hypot(h, w))) + 4
    canvas = np.zeros((side, side), np.uint8)
    top, left = (side - h) // 2, (side - w) // 2
    canvas[top:top + h, left:left + w] = np.asarray(mask, dtype=bool).astype(np.uint8) * 255
    turn = cv2.getRotationMatrix2D((side / 2.0, side / 2.0), float(roll_deg), 1.0)
    return cv2.warpAffine(canvas, turn, (side, side), flags=cv2.INTER_NEAREST) > 127
