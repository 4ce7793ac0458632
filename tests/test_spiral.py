"""Spiral walks: heading sweeps a full turn, the gait loops without a seam, the path spirals."""
from __future__ import annotations

import numpy as np
import pytest

from sequences.bvh import Motion, read_bvh
from sequences.pose_conversions import motion_to_pose_vectors
from sequences.pose_vector import heading_deg
from sequences.skeleton import CMU_JOINT_NAMES
from tests.synthetic import cmu_motion
from sequences.spiral import SpiralError, find_loop, line_of_sight_azimuth, spiral_walk

FPS = 30.0


def _synthetic_walk(T: int = 90, period: int = 30) -> Motion:
    """A straight walk along +Z: legs swing with a known period, root advances 2 units/frame."""
    J = len(CMU_JOINT_NAMES)
    euler = np.zeros((T, J, 3))
    phase = 2 * np.pi * np.arange(T) / period
    left, right = CMU_JOINT_NAMES.index("LeftUpLeg"), CMU_JOINT_NAMES.index("RightUpLeg")
    euler[:, left, 2] = 25 * np.sin(phase)          # X rotation (last channel): leg swing
    euler[:, right, 2] = -25 * np.sin(phase)
    root = np.column_stack([np.zeros(T), 17 + 0.3 * np.cos(2 * phase), 0.5 * np.arange(T)])
    return cmu_motion(euler, root, fps=FPS)


def _heading_sweep(motion: Motion) -> float:
    h = np.unwrap(np.radians(heading_deg(motion_to_pose_vectors(motion))))
    return float(np.degrees(h[-1] - h[0]))


def test_loop_found_at_a_whole_gait_period():
    i, j = find_loop(_synthetic_walk(period=30))
    assert (j - i) % 30 == 0


def test_spiral_sweeps_a_full_turn_at_the_requested_rate():
    walk = _synthetic_walk()
    spiral = spiral_walk(walk, deg_per_s=30.0)
    assert spiral.n_frames == int(np.ceil(360 / 30 * FPS)) + 1
    assert _heading_sweep(spiral) == pytest.approx(360.0, abs=3.0)
    assert _heading_sweep(spiral_walk(walk, deg_per_s=-45.0)) == pytest.approx(-360.0, abs=3.0)


def test_spiral_keeps_joint_angles_and_step_length():
    walk = _synthetic_walk()
    spiral = spiral_walk(walk, deg_per_s=30.0)
    # Every output frame's joint angles are one of the source's frames (looped).
    src = walk.euler_deg[:, 1:].reshape(walk.n_frames, -1)
    out = spiral.euler_deg[:, 1:].reshape(spiral.n_frames, -1)
    nearest = np.abs(out[:, None, :] - src[None, :, :]).max(axis=2).min(axis=1)
    assert nearest.max() < 1e-9
    step = np.linalg.norm(np.diff(spiral.root_position[:, [0, 2]], axis=0), axis=1)
    assert np.allclose(step, 0.5, atol=1e-9)
    assert np.allclose(np.sort(np.unique(np.round(spiral.root_position[:, 1], 9))),
                       np.sort(np.unique(np.round(walk.root_position[:, 1], 9))))


def test_spiral_radius_shrinks():
    spiral = spiral_walk(_synthetic_walk(), deg_per_s=30.0, turns=2.0)
    xz = spiral.root_position[:, [0, 2]]
    n = len(xz)
    centre_first = xz[: n // 2].mean(axis=0)
    centre_last = xz[n // 2:].mean(axis=0)
    r_first = np.linalg.norm(xz[: n // 2] - centre_first, axis=1).mean()
    r_last = np.linalg.norm(xz[n // 2:] - centre_last, axis=1).mean()
    assert r_last < 0.9 * r_first


def test_bad_options_are_refused():
    with pytest.raises(SpiralError, match="out of range"):
        spiral_walk(_synthetic_walk(), deg_per_s=float("nan"))
    with pytest.raises(SpiralError, match="too short"):
        find_loop(_synthetic_walk(T=10))


def test_line_of_sight_azimuth_matches_the_pose_vector_convention():
    subject = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [3.0, 0.0, 5.0]])
    camera = np.array([0.0, 1.0, 10.0])
    az = line_of_sight_azimuth(subject, camera)
    assert az[0] == pytest.approx(0.0)           # camera on +Z: azimuth 0
    assert az[2] == pytest.approx(np.degrees(np.arctan2(-3.0, 5.0)))
    # A subject at rest (facing +Z) seen from azimuth 0 has heading 0.
    walk = _synthetic_walk(T=3)
    az_origin = line_of_sight_azimuth(np.zeros((3, 3)), camera)
    assert np.allclose(heading_deg(motion_to_pose_vectors(walk, az_origin)), 0.0, atol=1e-9)
    # Seen from the side (camera on +X, azimuth 90), the same subject is turned by -90.
    side = line_of_sight_azimuth(np.zeros((3, 3)), np.array([10.0, 1.0, 0.0]))
    assert np.allclose(heading_deg(motion_to_pose_vectors(walk, side)), -90.0, atol=1e-9)


def test_real_curved_walk_becomes_a_full_spiral(cmu_bvh_dir):
    walk = read_bvh(cmu_bvh_dir / "16_11.bvh")
    spiral = spiral_walk(walk, deg_per_s=30.0)
    assert _heading_sweep(spiral) > 360.0
    i, j = find_loop(walk)
    assert 0.6 * FPS <= j - i <= 2.0 * FPS      # about one gait cycle
