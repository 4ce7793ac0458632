"""Spiral walks: turn a (walking) motion so its heading sweeps all 360 degrees past a fixed camera.

The paper evaluates on a spiral walk because it shows the body from every side, so the
regressor's front/back ambiguities appear as they would in real use. This module makes such a
sequence from any CMU motion:

1. The motion is split into per-frame pieces that do not depend on where the body is or which
   way it faces: joint angles, root height, root tilt, the root's step on the ground expressed
   in the body's own heading frame, and the change of heading from one frame to the next.
2. If the motion is too short for a full turn, a seamless loop [i, j) is found (the pose at j
   nearly equals the pose at i) and repeated.
3. Heading and ground path are re-integrated with an extra turning rate that ramps from
   0.75x to 1.25x the requested rate, so the path is a spiral (radius shrinking), not a circle.

Ground truth for a camera is then ``pose_conversions.motion_to_pose_vectors(motion, azimuths)`` with
``line_of_sight_azimuth`` giving the per-frame azimuth of the camera seen from the subject.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from regressor.angles import wrap_deg
from regressor.errors import SilhouettePoseError

from .bvh import Motion
from .pose_conversions import motion_to_pose_vectors

_ROOT_ORDER = "YXZ"          # R_root = Ry(yaw) Rx(tilt_x) Rz(tilt_z), as pose_vector
_MIN_LOOP_SECONDS = 0.6      # shorter loops repeat a single step and look mechanical
_RAMP = (0.75, 1.25)         # turning-rate ramp (fraction of the mean rate) that makes a spiral


class SpiralError(SilhouettePoseError, ValueError):
    """A motion that cannot be turned into a spiral walk (too short, bad options)."""


def _root_index(motion: Motion) -> int:
    return int(np.flatnonzero(np.asarray(motion.parents) < 0)[0])


def _pieces(motion: Motion):
    """Per-frame heading-free pieces of the motion.

    Returns yaw (T,) deg, tilt (T, 2) deg (x, z), local_step (T, 2) CMU units (x, z step to the
    next frame in the body's heading frame; last row repeats the previous), yaw_rate (T,) deg per
    frame (last row repeats), height (T,) CMU units.
    """
    root = _root_index(motion)
    local = motion.local_rotations()[:, root]
    yaw, tilt_x, tilt_z = Rotation.from_matrix(local).as_euler(_ROOT_ORDER, degrees=True).T
    pos = np.asarray(motion.root_position, dtype=np.float64)
    step_world = np.diff(pos[:, [0, 2]], axis=0)                       # (T-1, 2) x, z
    c, s = np.cos(np.radians(yaw[:-1])), np.sin(np.radians(yaw[:-1]))
    # Ry(-yaw) applied to (x, z): x' = c x - s z, z' = s x + c z
    local_step = np.stack([c * step_world[:, 0] - s * step_world[:, 1],
                           s * step_world[:, 0] + c * step_world[:, 1]], axis=1)
    yaw_rate = wrap_deg(np.diff(yaw))
    local_step = np.vstack([local_step, local_step[-1:]])
    yaw_rate = np.append(yaw_rate, yaw_rate[-1])
    return yaw, np.stack([tilt_x, tilt_z], axis=1), local_step, yaw_rate, pos[:, 1].copy()


def find_loop(motion: Motion, min_seconds: float = _MIN_LOOP_SECONDS) -> tuple[int, int]:
    """The frame pair (i, j), i < j, whose poses match best, with j - i >= min_seconds * fps.

    Compares heading-free pose vectors (joint angles and root tilt, degrees, wrapped) of frames
    i and j and of their successors (so velocities match too). Playing frames i..j-1 repeatedly
    then has no visible seam. Raises SpiralError if the motion is shorter than two loops' worth.
    """
    vectors = motion_to_pose_vectors(motion)[:, 2:]
    T = len(vectors)
    gap = int(np.ceil(min_seconds * motion.fps))
    if T < gap + 2:
        raise SpiralError(f"{motion.source or 'motion'}: too short to loop into a spiral "
                          f"walk: {T} frame(s) at {motion.fps:g} fps, needs at least {gap + 2}")
    pose = vectors[:-1]
    nxt = vectors[1:]
    # Pairwise wrapped distance over all (i, j) pairs: (T-1, T-1), small enough for mocap clips.
    d = np.abs(wrap_deg(pose[:, None, :] - pose[None, :, :])).mean(axis=2)
    d += np.abs(wrap_deg(nxt[:, None, :] - nxt[None, :, :])).mean(axis=2)
    i_idx, j_idx = np.indices(d.shape)
    d[j_idx - i_idx < gap] = np.inf
    i, j = np.unravel_index(np.argmin(d), d.shape)
    return int(i), int(j)


def spiral_walk(motion: Motion, deg_per_s: float = 30.0, turns: float = 1.0,
                n_frames: int | None = None) -> Motion:
    """A spiral walk made from ``motion`` (any fps, CMU skeleton; a walk looks best).

    deg_per_s: mean extra turning rate in degrees per second (0 keeps the original path but
        still loops the motion to n_frames); turns: how many full 360-degree sweeps of heading
        the extra turning adds (ignored if n_frames is given); n_frames: output length.
    The ground path is centred on the origin (x, z), root height kept. Joint angles are the
    source's, frame by frame. Returns a new Motion on the same skeleton and fps.
    """
    if not np.isfinite(deg_per_s) or abs(deg_per_s) > 720:
        raise SpiralError(f"spiral rate {deg_per_s} deg/s is out of range (-720..720)")
    if n_frames is None:
        if deg_per_s == 0:
            n_frames = motion.n_frames
        else:
            n_frames = int(np.ceil(360.0 * turns / abs(deg_per_s) * motion.fps)) + 1
    if n_frames < 2:
        raise SpiralError(f"{motion.source or 'motion'}: a spiral walk needs at least 2 "
                          f"frames, got {n_frames}")
    # The frames to play first: a motion too short to loop (a 2-frame file at 120 fps is one
    # frame at 30) is refused by find_loop, naming it, before _pieces needs two frames.
    if n_frames <= motion.n_frames:
        source_frames = np.arange(n_frames)
    else:
        i, j = find_loop(motion)
        loop = np.arange(i, j)
        reps = int(np.ceil((n_frames - i) / len(loop)))
        source_frames = np.concatenate([np.arange(i), np.tile(loop, reps)])[:n_frames]
    yaw, tilt, local_step, yaw_rate, height = _pieces(motion)

    fps = motion.fps
    ramp = np.linspace(*_RAMP, n_frames)
    extra = deg_per_s / fps * ramp                                  # deg per frame
    turn = yaw_rate[source_frames] + extra
    new_yaw = yaw[source_frames[0]] + np.concatenate([[0.0], np.cumsum(turn[:-1])])
    c, s = np.cos(np.radians(new_yaw)), np.sin(np.radians(new_yaw))
    step = local_step[source_frames]
    # Ry(yaw) applied to the body-frame step (x, z): x' = c x + s z, z' = -s x + c z
    world = np.stack([c * step[:, 0] + s * step[:, 1], -s * step[:, 0] + c * step[:, 1]], axis=1)
    ground = np.vstack([[0.0, 0.0], np.cumsum(world[:-1], axis=0)])
    ground -= 0.5 * (ground.min(axis=0) + ground.max(axis=0))
    root_position = np.stack([ground[:, 0], height[source_frames], ground[:, 1]], axis=1)

    root = _root_index(motion)
    euler = np.asarray(motion.euler_deg, dtype=np.float64)[source_frames].copy()
    root_rot = Rotation.from_euler(
        _ROOT_ORDER, np.column_stack([new_yaw, tilt[source_frames]]), degrees=True)
    euler[:, root] = root_rot.as_euler(motion.rotation_orders()[root], degrees=True)
    return Motion(names=list(motion.names), parents=np.asarray(motion.parents).copy(),
                  offsets=np.asarray(motion.offsets).copy(),
                  end_sites=np.asarray(motion.end_sites).copy(),
                  channels=[list(ch) for ch in motion.channels], euler_deg=euler,
                  root_position=root_position, fps=fps,
                  source=f"{motion.source} spiral {deg_per_s:g} deg/s")


def line_of_sight_azimuth(root_position: np.ndarray, camera_position: np.ndarray) -> np.ndarray:
    """Per-frame azimuth (T,) in degrees of a fixed camera seen from the subject.

    root_position: (T, 3) and camera_position: (3,), same length unit, Y up. The azimuth az
    satisfies: the camera lies in direction Ry(az) @ (0, 0, 1) = (sin az, 0, cos az) from the
    subject, the convention of pose_vector, so heading = yaw - az is relative to the line of sight.
    """
    d = np.asarray(camera_position, dtype=np.float64)[None, :] - np.asarray(root_position)
    return np.degrees(np.arctan2(d[:, 0], d[:, 2]))
