"""A skeleton and its motion (what a BVH file holds): sequences.bvh reads it (and turns Euler
angles to rotation matrices and back), sequences.bvh_write writes it."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

ROTATION_CHANNELS = ("Xrotation", "Yrotation", "Zrotation")


@dataclass
class Motion:
    """A skeleton and its motion, one row per frame. names (J,); parents (J,) int, -1 for the
    root (parents precede children); offsets (J, 3) from the parent and end_sites (J, 3) in the
    joint's frame (NaN rows: none), CMU units; channels: per joint, its channel names as in the
    file (root: 3 positions + 3 rotations); euler_deg (T, J, 3) local rotation angles in each
    joint's rotation-channel order (CMU: Z, Y, X, R = Rz @ Ry @ Rx, intrinsic); root_position
    (T, 3) CMU units; fps; source: the file it came from ("" if none)."""

    names: list[str]
    parents: np.ndarray
    offsets: np.ndarray
    end_sites: np.ndarray
    channels: list[list[str]]
    euler_deg: np.ndarray
    root_position: np.ndarray
    fps: float
    source: str = field(default="")

    @property
    def n_frames(self) -> int:
        """Number of frames T."""
        return int(self.euler_deg.shape[0])

    def rotation_orders(self) -> list[str]:
        """Per joint, the intrinsic Euler sequence of its rotation channels, e.g. "ZYX"."""
        return ["".join(c[0] for c in ch if c in ROTATION_CHANNELS) for ch in self.channels]

    def local_rotations(self) -> np.ndarray:
        """Local joint rotation matrices (T, J, 3, 3): child vector in parent frame = R @ v."""
        from .bvh import euler_to_matrices
        return euler_to_matrices(self.euler_deg, self.rotation_orders())
