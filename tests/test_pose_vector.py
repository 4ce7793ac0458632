"""Pose vector <-> rotations <-> positions <-> BVH channels."""
from __future__ import annotations

import numpy as np
import pytest

from sequences.bvh import Motion, matrices_to_euler, read_bvh, write_bvh
from regressor.angles import heading_norm
from sequences.pose_conversions import PART_OF_ENTRY, motion_to_pose_vectors
from sequences.pose_vector import (POSE_DIM, PoseVectorError, forward_kinematics,
                                   front_back_flip, heading_deg, image_mirror, joint_positions,
                                   pose_vector_names, pose_vectors_to_local_rotations)
from sequences.bvh_write import pose_vectors_to_motion
from sequences.skeleton import (CMU_JOINT_NAMES, CMU_PARENTS, CMU_REST_OFFSETS, FOLDED,
                                POSE_JOINTS, pose_joint_indices)
from sequences.skeleton_tables import CMU_REST_END_SITES

LEG_JOINTS = ["Hips", "LeftUpLeg", "LeftLeg", "LeftFoot", "RightUpLeg", "RightLeg", "RightFoot"]


def _random_vectors(T: int, seed: int) -> np.ndarray:
    """Pose vectors with unit-norm heading and angles in the canonical Euler ranges."""
    rng = np.random.default_rng(seed)
    v = np.empty((T, POSE_DIM))
    heading = np.radians(rng.uniform(-180, 180, T))
    v[:, 0], v[:, 1] = np.cos(heading), np.sin(heading)
    v[:, 2], v[:, 3] = rng.uniform(-85, 85, T), rng.uniform(-175, 175, T)
    angles = rng.uniform(-175, 175, (T, 17, 3))
    angles[:, :, 1] = rng.uniform(-85, 85, (T, 17))
    v[:, 4:] = angles.reshape(T, 51)
    return v


def _template(T: int = 1) -> Motion:
    channels = [["Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"]]
    channels += [["Zrotation", "Yrotation", "Xrotation"]] * (len(CMU_JOINT_NAMES) - 1)
    return Motion(names=list(CMU_JOINT_NAMES), parents=CMU_PARENTS.copy(),
                  offsets=CMU_REST_OFFSETS.copy(), end_sites=CMU_REST_END_SITES.copy(),
                  channels=[list(c) for c in channels],
                  euler_deg=np.zeros((T, len(CMU_JOINT_NAMES), 3)),
                  root_position=np.tile([0.0, 17.0, 0.0], (T, 1)), fps=30.0)


def _rest_vector(heading: float = 0.0) -> np.ndarray:
    v = np.zeros((1, POSE_DIM))
    v[0, 0], v[0, 1] = np.cos(np.radians(heading)), np.sin(np.radians(heading))
    return v


def _last_members(names) -> list[int]:
    """Per pose joint, the CMU joint whose global rotation is the pose joint's."""
    return [list(names).index(FOLDED.get(j, (j,))[-1]) for j in POSE_JOINTS]


# ------------------------------------------------------------------ layout


def test_names_layout_and_masks_agree():
    names = pose_vector_names()
    assert len(names) == POSE_DIM == 55
    assert names[:7] == ["heading_cos", "heading_sin", "Hips_x", "Hips_z",
                         "Spine1_z", "Spine1_y", "Spine1_x"]
    assert names[-1] == "RightFoot_x"
    assert PART_OF_ENTRY[:2] == ("heading", "heading")
    assert PART_OF_ENTRY[names.index("LeftForeArm_y")] == "left arm"
    assert PART_OF_ENTRY[names.index("Neck_x")] == "head"
    assert PART_OF_ENTRY[names.index("RightLeg_z")] == "right leg"


def test_bad_vectors_are_refused():
    with pytest.raises(PoseVectorError, match=r"\(T, 55\)"):
        heading_deg(np.zeros((3, 54)))
    v = _random_vectors(3, seed=0)
    v[1, 10] = np.nan
    with pytest.raises(PoseVectorError, match="frame 1"):
        pose_vectors_to_local_rotations(v)


# ------------------------------------------------------------------ synthetic round trips


def test_vector_to_rotations_to_vector_is_exact():
    v = _random_vectors(200, seed=1)
    motion = _template(200)
    motion.euler_deg = matrices_to_euler(pose_vectors_to_local_rotations(v, 40.0),
                                         motion.rotation_orders())
    np.testing.assert_allclose(motion_to_pose_vectors(motion, 40.0), v, atol=1e-6, rtol=0)


def test_vector_to_motion_to_bvh_text_and_back_is_exact(tmp_path):
    v = _random_vectors(20, seed=2)
    motion = pose_vectors_to_motion(v, _template(), camera_azimuth_deg=-75.0)
    write_bvh(tmp_path / "estimate.bvh", motion)
    back = read_bvh(tmp_path / "estimate.bvh", fps=None, drop_tpose=False)
    np.testing.assert_allclose(motion_to_pose_vectors(back, -75.0), v, atol=1e-6, rtol=0)


def test_folded_joints_split_evenly():
    v = _random_vectors(5, seed=3)
    rot = pose_vectors_to_local_rotations(v)
    spine = [CMU_JOINT_NAMES.index(n) for n in FOLDED["Spine1"]]
    np.testing.assert_allclose(rot[:, spine[0]], rot[:, spine[1]], atol=1e-12)
    np.testing.assert_allclose(rot[:, spine[0]], rot[:, spine[2]], atol=1e-12)
    assert not np.allclose(rot[:, spine[0]], np.eye(3))
    others = [i for i, n in enumerate(CMU_JOINT_NAMES) if n in ("LHipJoint", "LeftToeBase",
                                                                "RThumb", "LeftFingerBase")]
    np.testing.assert_array_equal(rot[:, others], np.broadcast_to(np.eye(3), (5, 4, 3, 3)))


def test_unnormalised_heading_pair_gives_the_same_rotation():
    v = _random_vectors(4, seed=4)
    scaled = v.copy()
    scaled[:, :2] *= np.array([0.2, 0.7, 1.0, 3.0])[:, None]
    np.testing.assert_allclose(pose_vectors_to_local_rotations(scaled),
                               pose_vectors_to_local_rotations(v), atol=1e-12)
    np.testing.assert_allclose(heading_norm(scaled), [0.2, 0.7, 1.0, 3.0])
    np.testing.assert_allclose(heading_deg(scaled), heading_deg(v))


# ------------------------------------------------------------------ geometry and heading


def test_forward_kinematics_on_a_two_joint_chain():
    quarter_turn_y = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])  # Ry(+90 deg): +Z -> +X
    local = np.stack([quarter_turn_y, quarter_turn_y])[None]
    positions, rotations = forward_kinematics([[0, 0, 0], [1, 0, 0]], [-1, 0], local,
                                              np.array([[5.0, 0, 0]]))
    np.testing.assert_allclose(positions[0], [[5, 0, 0], [5, 0, -1]], atol=1e-12)
    np.testing.assert_allclose(rotations[0, 1], quarter_turn_y @ quarter_turn_y, atol=1e-12)


def test_rest_pose_stands_upright_facing_plus_z_with_left_on_plus_x():
    p = joint_positions(_rest_vector())[0]
    at = {name: p[i] for i, name in enumerate(POSE_JOINTS)}
    assert at["Head"][1] > at["Spine1"][1] > at["Hips"][1] > at["LeftLeg"][1] > at["LeftFoot"][1]
    assert at["LeftUpLeg"][0] > 0 > at["RightUpLeg"][0]
    assert at["LeftHand"][0] > at["LeftForeArm"][0] > 0


def test_positive_heading_turns_the_subject_counter_clockwise_from_above():
    p = joint_positions(_rest_vector(90.0))[0]
    left_hip = p[POSE_JOINTS.index("LeftUpLeg")] - p[POSE_JOINTS.index("RightUpLeg")]
    # Facing +Z with the left hip at +X, a quarter turn about +Y faces +X with the left hip at -Z.
    assert left_hip[2] < -3 and abs(left_hip[0]) < 1e-3  # CMU hips are symmetric to 1e-5


def test_subject_turned_to_the_camera_has_heading_zero():
    for azimuth in (-120.0, 0.0, 35.0, 170.0):
        v = _rest_vector(0.0)
        rot = pose_vectors_to_local_rotations(v, camera_azimuth_deg=azimuth)
        facing = rot[0, 0] @ [0, 0, 1]
        camera = [np.sin(np.radians(azimuth)), 0, np.cos(np.radians(azimuth))]
        np.testing.assert_allclose(facing, camera, atol=1e-12)


# ------------------------------------------------------------------ real CMU motion


@pytest.fixture(scope="module")
def basketball(cmu_bvh_dir) -> Motion:
    return read_bvh(cmu_bvh_dir / "06_10.bvh")  # dribbling with 90-degree turns


def test_cmu_vector_motion_vector_is_exact(basketball):
    v = motion_to_pose_vectors(basketball, 30.0)
    again = pose_vectors_to_motion(v, basketball, basketball.root_position, 30.0)
    np.testing.assert_allclose(motion_to_pose_vectors(again, 30.0), v, atol=1e-6, rtol=0)
    np.testing.assert_allclose(heading_norm(v), 1.0, atol=1e-12)


def test_cmu_motion_through_vectors_keeps_positions_and_rotations(basketball):
    v = motion_to_pose_vectors(basketball, camera_azimuth_deg=-50.0)
    rebuilt = pose_vectors_to_motion(v, basketball, basketball.root_position, -50.0)
    args = (basketball.offsets, basketball.parents)
    p0, r0 = forward_kinematics(*args, basketball.local_rotations(), basketball.root_position)
    p1, r1 = forward_kinematics(*args, rebuilt.local_rotations(), rebuilt.root_position)
    legs = [basketball.names.index(n) for n in LEG_JOINTS]
    np.testing.assert_allclose(p1[:, legs], p0[:, legs], atol=1e-6, rtol=0)
    last = _last_members(basketball.names)
    np.testing.assert_allclose(r1[:, last], r0[:, last], atol=1e-6, rtol=0)
    # Non-folded joints keep their BVH angles as they were.
    arm = basketball.names.index("LeftForeArm")
    np.testing.assert_allclose(rebuilt.euler_deg[:, arm], basketball.euler_deg[:, arm],
                               atol=1e-9)


def test_cmu_joint_positions_match_forward_kinematics_of_the_pose(basketball):
    v = motion_to_pose_vectors(basketball)
    positions = joint_positions(v, basketball, basketball.root_position)
    rebuilt = pose_vectors_to_motion(v, basketball, basketball.root_position)
    p, _ = forward_kinematics(basketball.offsets, basketball.parents,
                              rebuilt.local_rotations(), rebuilt.root_position)
    np.testing.assert_allclose(positions, p[:, pose_joint_indices(basketball.names)],
                               atol=1e-9)
    legs = [POSE_JOINTS.index(n) for n in LEG_JOINTS]
    original, _ = forward_kinematics(basketball.offsets, basketball.parents,
                                     basketball.local_rotations(), basketball.root_position)
    np.testing.assert_allclose(positions[:, legs],
                               original[:, pose_joint_indices(basketball.names)][:, legs],
                               atol=1e-6)


def test_cmu_turning_the_camera_by_30_degrees_changes_heading_by_minus_30(basketball):
    before = heading_deg(motion_to_pose_vectors(basketball, 10.0))
    after = heading_deg(motion_to_pose_vectors(basketball, 40.0))
    change = np.mod(after - before + 180.0, 360.0) - 180.0
    np.testing.assert_allclose(change, -30.0, atol=1e-9)
    # The basketball trial turns: its heading covers a wide range of directions.
    assert np.ptp(np.unwrap(np.radians(before))) > np.radians(90)


def test_cmu_per_frame_azimuth(basketball):
    T = basketball.n_frames
    azimuth = np.linspace(-180, 180, T)
    per_frame = heading_deg(motion_to_pose_vectors(basketball, azimuth))
    fixed = heading_deg(motion_to_pose_vectors(basketball, 0.0))
    np.testing.assert_allclose(np.mod(fixed - azimuth - per_frame + 180, 360) - 180, 0,
                               atol=1e-9)


# ------------------------------------------------------------------ front/back flip

def _other_side(name: str) -> str:
    for a, b in (("Left", "Right"), ("Right", "Left"), ("LHip", "RHip"), ("RHip", "LHip"),
                 ("LThumb", "RThumb"), ("RThumb", "LThumb")):
        if name.startswith(a):
            return b + name[len(a):]
    return name


def _symmetric_offsets(offsets: np.ndarray) -> np.ndarray:
    """Bone offsets (31, 3) made exactly left/right symmetric (mirror: x -> -x)."""
    mirror = np.array([-1.0, 1.0, 1.0])
    swap = [CMU_JOINT_NAMES.index(_other_side(n)) for n in CMU_JOINT_NAMES]
    return 0.5 * (offsets + offsets[swap] * mirror)


def _camera_frame(positions: np.ndarray, azimuth_deg: float) -> np.ndarray:
    """World joints (T, 18, 3) -> camera-aligned (x right of the line of sight, y up, z towards
    the camera at azimuth_deg), relative to the root."""
    a = np.radians(azimuth_deg)
    ry_inv = np.array([[np.cos(a), 0, -np.sin(a)], [0, 1, 0], [np.sin(a), 0, np.cos(a)]])
    return (positions - positions[:, :1]) @ ry_inv.T


POSE_SWAP = [POSE_JOINTS.index(_other_side(j)) for j in POSE_JOINTS]


def test_front_back_flip_twice_is_the_identity_and_frontal_flip_is_plus_180():
    v = _random_vectors(50, seed=3)
    v[:, :2] *= np.linspace(0.1, 1.0, 50)[:, None]        # unnormalised heading pairs too
    np.testing.assert_array_equal(front_back_flip(front_back_flip(v)), v)
    np.testing.assert_allclose(heading_norm(front_back_flip(v)), heading_norm(v))
    # facing the camera <-> back to the camera; in profile only the limbs swap
    np.testing.assert_allclose(heading_deg(front_back_flip(_rest_vector(0.0))), 180.0)
    np.testing.assert_allclose(heading_deg(front_back_flip(_rest_vector(90.0))), 90.0)
    np.testing.assert_allclose(heading_deg(front_back_flip(_rest_vector(30.0))), 150.0)
    np.testing.assert_array_equal(front_back_flip(v[0]), front_back_flip(v)[0])
    with pytest.raises(PoseVectorError):
        front_back_flip(np.zeros(54))


def test_flipped_random_pose_is_the_depth_reflection_of_the_body():
    offsets = _symmetric_offsets(CMU_REST_OFFSETS)
    v = _random_vectors(20, seed=4)
    for az in (0.0, 40.0):
        cam = _camera_frame(joint_positions(v, offsets, camera_azimuth_deg=az), az)
        flipped = _camera_frame(joint_positions(front_back_flip(v), offsets,
                                                camera_azimuth_deg=az), az)
        np.testing.assert_allclose(flipped, cam[:, POSE_SWAP] * [1.0, 1.0, -1.0], atol=1e-9)


def test_image_mirror_is_the_left_right_reflection_of_the_body_in_the_image():
    offsets = _symmetric_offsets(CMU_REST_OFFSETS)
    v = _random_vectors(20, seed=5)
    np.testing.assert_array_equal(image_mirror(image_mirror(v)), v)
    np.testing.assert_allclose(heading_deg(image_mirror(_rest_vector(30.0))), -30.0)
    np.testing.assert_allclose(heading_norm(image_mirror(v)), heading_norm(v))
    for az in (0.0, -70.0):
        cam = _camera_frame(joint_positions(v, offsets, camera_azimuth_deg=az), az)
        mirrored = _camera_frame(joint_positions(image_mirror(v), offsets,
                                                 camera_azimuth_deg=az), az)
        np.testing.assert_allclose(mirrored, cam[:, POSE_SWAP] * [-1.0, 1.0, 1.0], atol=1e-9)


def test_cmu_flipped_poses_give_the_same_silhouette_joints_mirrored_in_depth(cmu_bvh_dir):
    """Real poses (backward dribbling, 06_06) seen from two cameras: the flipped pose's joints
    project to the same image points as the pose's with left and right exchanged, and lie at
    the opposite depth. Exact on a symmetrised skeleton; within 0.75 CMU units (4 cm) on the
    subject's own, whose left and right bones differ by up to that much."""
    motion = read_bvh(cmu_bvh_dir / "06_06.bvh", fps=10.0)
    for az in (25.0, -120.0):
        v = motion_to_pose_vectors(motion, az)
        np.testing.assert_allclose(front_back_flip(front_back_flip(v)), v, atol=1e-12)
        for offsets, tol in ((_symmetric_offsets(motion.offsets), 1e-9), (motion.offsets, 0.75)):
            cam = _camera_frame(joint_positions(v, offsets, camera_azimuth_deg=az), az)
            flipped = _camera_frame(joint_positions(front_back_flip(v), offsets,
                                                    camera_azimuth_deg=az), az)
            np.testing.assert_allclose(flipped, cam[:, POSE_SWAP] * [1.0, 1.0, -1.0],
                                       atol=tol)
