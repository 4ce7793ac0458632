"""Each track's root (hip) path smoothed over time, for the smoothed outputs: the root, placed
per frame from the silhouette's box, jitters with it as the limbs move; the outputs take a line
fitted with Gaussian weights about each pose's time (no lag, no pull at a track's ends or gaps)."""
from __future__ import annotations

from array import array
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from tracker.outputs.geometry import pose_joints_m

if TYPE_CHECKING:
    from tracker.pipeline import TrackedPose

#: Standard deviation of the Gaussian over time, seconds (chosen: docs/tuning.md).
ROOT_SMOOTHING_S = 0.2
_REACH_SIGMAS = 4.0        # the Gaussian is cut beyond this many standard deviations


def smoothed_roots(roots_m: np.ndarray, fps: float, sigma_s: float = ROOT_SMOOTHING_S,
                   frames: np.ndarray | None = None) -> np.ndarray:
    """roots_m (T, 3) metres, one track's roots in time order at fps, smoothed (T, 3): each is
    the value at its time of the line fitted to the roots within 4 sigma by Gaussian weights of
    sigma_s seconds (0: unchanged) over their frame indices frames (T,) (None: 0, 1, ...)."""
    roots = np.asarray(roots_m, dtype=np.float64)
    if roots.ndim != 2 or roots.shape[1] != 3:
        raise ValueError(f"roots must be (T, 3), got {roots.shape}")
    if not (np.isfinite(fps) and fps > 0 and np.isfinite(sigma_s) and sigma_s >= 0):
        raise ValueError(f"fps={fps} must be > 0 and sigma_s={sigma_s} >= 0")
    count = len(roots)
    times = np.arange(count, dtype=np.float64) if frames is None else np.asarray(frames, float)
    if times.shape != (count,) or np.any(np.diff(times) <= 0):
        raise ValueError(f"frames must be ({count},) and increasing")
    if sigma_s == 0 or count < 2:
        return roots.copy()
    sigma = sigma_s * fps                               # frames
    reach = _REACH_SIGMAS * sigma
    # Weighted sums for each pose's fit: of w, w d, w d^2, w y, w d y (d: time from it).
    s0, s1, s2 = np.zeros(count), np.zeros(count), np.zeros(count)
    t0, t1 = np.zeros_like(roots), np.zeros_like(roots)
    # Neighbours within reach in time are within reach in pose order: a pass per offset.
    farthest = min(int(reach), count - 1)
    for offset in range(-farthest, farthest + 1):
        lo, hi = max(0, -offset), min(count, count - offset)
        d = times[lo + offset:hi + offset] - times[lo:hi]
        w = np.exp(-0.5 * (d / sigma) ** 2) * (np.abs(d) <= reach)
        y = roots[lo + offset:hi + offset]
        s0[lo:hi] += w
        s1[lo:hi] += w * d
        s2[lo:hi] += w * d * d
        t0[lo:hi] += w[:, None] * y
        t1[lo:hi] += (w * d)[:, None] * y
    det = s0 * s2 - s1 * s1
    # A lone pose (no neighbour within reach) has no line: its weighted mean, which is itself.
    line = det > 1e-9 * s0 * s0
    out = t0 / s0[:, None]
    out[line] = (s2[line, None] * t0[line] - s1[line, None] * t1[line]) / det[line, None]
    return out


class RootHistory:
    """Each track's raw roots (metres) and frame indices as they come, 32 bytes a pose."""

    def __init__(self):
        self._tracks: dict[int, tuple[array, array]] = {}

    def add(self, track_id: int, frame_index: int, root_m) -> None:
        """Keep a track's next pose's root (3,) metres and frame index."""
        roots, frames = self._tracks.setdefault(int(track_id), (array("d"), array("q")))
        roots.extend(float(c) for c in np.asarray(root_m, dtype=np.float64)[:3])
        frames.append(int(frame_index))

    def get(self, track_id: int, start: int = 0, stop: int | None = None
            ) -> tuple[np.ndarray, np.ndarray]:
        """Poses start:stop of a track: roots (n, 3) metres and frame indices (n,), copies."""
        roots, frames = self._tracks[int(track_id)]
        start, stop, _ = slice(start, stop).indices(len(frames))
        # Only the slice is copied: a long track's history is read a block at a time.
        return np.array(roots[3 * start:3 * stop]).reshape(-1, 3), np.array(frames[start:stop])


def drawn_at(poses: list[tuple[TrackedPose, np.ndarray, np.ndarray]]) -> list[TrackedPose]:
    """Each (pose, smoothed (55,), smoothed root (3,) metres) as the pose with filtered =
    smoothed and its joints drawn from it at that root, in one forward-kinematics call."""
    if not poses:
        return []
    vectors = np.array([vector for _, vector, _ in poses])
    roots = np.array([root for _, _, root in poses])
    joints = pose_joints_m(vectors, root_position_m=roots)
    return [replace(pose, filtered=vector, joints_m=j)
            for (pose, _, _), vector, j in zip(poses, vectors, joints)]
