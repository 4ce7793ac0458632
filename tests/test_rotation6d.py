"""The 6-D rotation representation of the 53 body angles (regressor.rotation6d)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from regressor.angles import wrap_deg
from regressor.rotation6d import ROT6D_LENGTH, angles_to_rot6d, rot6d_to_angles
from sequences.pose_vector import pose_vectors_to_local_rotations
from sequences.skeleton import CMU_JOINT_NAMES, FOLDED, POSE_JOINTS


def _angles(n=200, seed=0, y_limit=85.0):
    """Random 53 body angles: tilts, then (z, y, x) per joint with |y| < y_limit."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(-170, 170, (n, 53))
    a[:, 3::3] = rng.uniform(-y_limit, y_limit, (n, 17))    # each joint's middle (y) angle
    return a


def _rotations(angles):
    return Rotation.from_euler("ZYX", angles[:, 2:].reshape(-1, 3), degrees=True).as_matrix()


def test_angles_come_back_and_the_values_are_the_matrices_first_two_columns():
    a = _angles()
    six = angles_to_rot6d(a)
    assert six.shape == (200, ROT6D_LENGTH) == (200, 104)
    np.testing.assert_allclose(six[:, :2], a[:, :2])        # the root's tilts stay angles
    R = _rotations(a)
    np.testing.assert_allclose(six[:, 2:].reshape(-1, 2, 3), R[:, :, :2].transpose(0, 2, 1),
                               atol=1e-12)
    back = rot6d_to_angles(six)
    np.testing.assert_allclose(wrap_deg(back - a), 0.0, atol=1e-6)


def test_beyond_the_middle_angles_range_the_rotation_comes_back():
    a = _angles(seed=1, y_limit=179.0)                      # other Euler triples, same rotation
    back = rot6d_to_angles(angles_to_rot6d(a))
    np.testing.assert_allclose(_rotations(back), _rotations(a), atol=1e-9)
    assert np.abs(back[:, 3::3]).max() <= 90.0 + 1e-9       # scipy's triple: |y| <= 90


def test_any_six_numbers_give_a_rotation_near_the_one_they_perturb():
    a = _angles(seed=2)
    rng = np.random.default_rng(3)
    six = angles_to_rot6d(a)
    noisy = six.copy()
    noisy[:, 2:] = 1.7 * six[:, 2:] + rng.normal(0, 0.05, six[:, 2:].shape)  # scaled, off
    R = _rotations(rot6d_to_angles(noisy))
    np.testing.assert_allclose(R @ R.transpose(0, 2, 1), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-9)
    angle = Rotation.from_matrix(R.transpose(0, 2, 1) @ _rotations(a)).magnitude()
    assert np.degrees(angle).max() < 10.0 and np.degrees(angle).mean() < 3.0


def test_the_joint_order_is_the_pose_vectors():
    """The matrices here are the ones sequences.pose_vector builds from the same angles (a
    joint that is not folded), so the representation and the pose vector agree."""
    a = _angles(5, seed=4)
    pose = np.hstack([np.tile([1.0, 0.0], (5, 1)), a])
    local = pose_vectors_to_local_rotations(pose)
    R = _rotations(a).reshape(5, 17, 3, 3)
    checked = 0
    for k, joint in enumerate(POSE_JOINTS[1:]):
        if len(FOLDED.get(joint, (joint,))) == 1:
            np.testing.assert_allclose(local[:, CMU_JOINT_NAMES.index(joint)], R[:, k],
                                       atol=1e-12)
            checked += 1
    assert checked >= 10


def test_wrong_shapes_are_refused():
    with pytest.raises(ValueError, match=r"\(N, 53\)"):
        angles_to_rot6d(np.zeros((3, 55)))
    with pytest.raises(ValueError, match=r"\(N, 104\)"):
        rot6d_to_angles(np.zeros((3, 53)))


def test_at_the_middle_angles_plus_minus_90_the_rotation_comes_back_with_x_zero():
    a = np.zeros((2, 53))
    a[:, 2:5] = [[30.0, 90.0, 20.0], [-50.0, -90.0, 10.0]]  # gimbal lock: z and x share an axis
    back = rot6d_to_angles(angles_to_rot6d(a))
    np.testing.assert_allclose(_rotations(back), _rotations(a), atol=1e-12)
    np.testing.assert_allclose(back[:, 2:5], [[10.0, 90.0, 0.0], [-40.0, -90.0, 0.0]],
                               atol=1e-9)


def test_the_limb_networks_6d_output_width_is_the_heading_and_rot6d_length():
    """regressor.limb_net spells out its 6-D output width so that ``track`` need not load this
    module for the shipped model's Euler-angle networks."""
    from regressor.limb_net import OUTPUT_WIDTHS, ROT6D_OUTPUTS
    assert ROT6D_OUTPUTS == 2 + ROT6D_LENGTH == OUTPUT_WIDTHS["rot6d"]
