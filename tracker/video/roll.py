"""Turning silhouettes upright when the camera is rolled (``track --roll DEG``).

The descriptor keeps the scene's vertical (shape contexts and the layout are measured in image
axes), so a camera rolled about its line of sight shows the regressor a leaning body. Measured
on the Pose2Sim balancing trial (its calibration gives each camera's roll, see
sequences.pose2sim.camera_roll_deg): cam04 is rolled 26 degrees, and turning its masks upright
lowered its knee/elbow flexion error 36.1 -> 24.1 degrees (cam01, 12 degrees: 27.9 -> 26.2).
"""
from __future__ import annotations

import cv2
import numpy as np


def upright_mask(mask: np.ndarray, roll_deg: float) -> np.ndarray:
    """The silhouette mask (h, w) bool turned by roll_deg degrees anticlockwise on screen, on a
    canvas (s, s), s = its diagonal + 4 px, so nothing is cut off. roll_deg: how far the
    scene's vertical leans clockwise in the image (the camera is rolled anticlockwise), so
    turning by it makes the scene's vertical the image's. 0 returns the mask as it is."""
    if not roll_deg:
        return mask
    h, w = mask.shape
    side = int(np.ceil(np.hypot(h, w))) + 4
    canvas = np.zeros((side, side), np.uint8)
    top, left = (side - h) // 2, (side - w) // 2
    canvas[top:top + h, left:left + w] = np.asarray(mask, dtype=bool).astype(np.uint8) * 255
    turn = cv2.getRotationMatrix2D((side / 2.0, side / 2.0), float(roll_deg), 1.0)
    return cv2.warpAffine(canvas, turn, (side, side), flags=cv2.INTER_NEAREST) > 127
