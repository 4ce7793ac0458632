"""The 8 limb angles (knee, elbow, hip and shoulder; sequences.measures) on hand-made bodies with
known answers, from the reference keypoints, from our forward kinematics and from MediaPipe's
landmark layout; their measures; the swings reference; MediaPipe's scoring path on stubs."""
from __future__ import annotations

import numpy as np
import pytest

from sequences import mediapipe_peer
from sequences.measures import (LIMB_ANGLE_NAMES, LIMB_POINTS, MeasureError, angle_measures,
                                limb_angles_deg, limb_angles_from_points)
from sequences.pose2sim import (VIEWS, Reference, Trial, load_trial, project_reference,
                                reference_limb_angles, video_frames)
from sequences.pose2sim_measures import peer_view_measures, pooled_limb_measures
from sequences.pose_vector import pose_vector_names
from sequences.skeleton import CMU_JOINT_NAMES, CMU_REST_OFFSETS

#: L knee 30, R knee 0, L elbow 60, R elbow 90, L hip 0, R hip 40 (abducted), L shoulder 90
#: (arm raised sideways), R shoulder 0 (arm hanging).
EXPECTED = [30.0, 0.0, 60.0, 90.0, 0.0, 40.0, 90.0, 0.0]


def _unit(deg_from_down: float, plane: str) -> np.ndarray:
    """A unit vector at deg_from_down from straight down (0, -1, 0), tilted towards +z
    ("front") or -x ("right": the subject's right, who faces +z with the left at +x)."""
    a = np.radians(deg_from_down)
    return (np.array([0.0, -np.cos(a), np.sin(a)]) if plane == "front"
            else np.array([-np.sin(a), -np.cos(a), 0.0]))


def hand_made_body() -> dict[str, np.ndarray]:
    """A standing body (metres, Y up, facing +z, left at +x) with EXPECTED's angles."""
    p = {"LHip": np.array([0.1, 1.0, 0.0]), "RHip": np.array([-0.1, 1.0, 0.0]),
         "LShoulder": np.array([0.2, 1.5, 0.0]), "RShoulder": np.array([-0.2, 1.5, 0.0])}
    p["LKnee"] = p["LHip"] + 0.45 * _unit(0, "front")
    p["LAnkle"] = p["LKnee"] + 0.45 * _unit(-30, "front")          # shank back: knee bent 30
    p["RKnee"] = p["RHip"] + 0.45 * _unit(40, "right")              # thigh out sideways 40
    p["RAnkle"] = p["RKnee"] + 0.45 * _unit(40, "right")
    p["LElbow"] = p["LShoulder"] + 0.3 * np.array([1.0, 0.0, 0.0])  # arm out sideways
    p["LWrist"] = p["LElbow"] + 0.25 * np.array([np.cos(np.pi / 3), np.sin(np.pi / 3), 0.0])
    p["RElbow"] = p["RShoulder"] + 0.3 * _unit(0, "front")          # arm hanging
    p["RWrist"] = p["RElbow"] + 0.25 * np.array([0.0, 0.0, 1.0])    # forearm forward: 90
    return p


def test_the_angles_of_a_hand_made_body_from_points():
    p = hand_made_body()
    points = np.stack([p[n] for n in LIMB_POINTS])
    np.testing.assert_allclose(limb_angles_from_points(points), EXPECTED, atol=1e-9)
    # Any axes and unit: turned, moved and in millimetres, the same angles.
    turn = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    np.testing.assert_allclose(limb_angles_from_points(1000 * points @ turn.T + 5.0),
                               EXPECTED, atol=1e-9)
    with pytest.raises(MeasureError):
        limb_angles_from_points(points[:10])


def test_the_angles_from_the_reference_keypoint_layout():
    """Reference keypoints in their own order, with keypoints the angles do not use."""
    p = hand_made_body()
    names = ("Neck", *reversed(LIMB_POINTS), "Head")
    points = np.stack([p.get(n, np.zeros(3)) for n in names])[None].repeat(3, axis=0)
    reference = Reference(names, np.arange(1, 4), np.arange(3) / 60, points)
    angles = reference_limb_angles(Trial(None, reference, {}), [0, 2])
    np.testing.assert_allclose(angles, [EXPECTED, EXPECTED], atol=1e-9)


def _clean_template() -> np.ndarray:
    """CMU bone offsets made simple: spine straight up, legs and arms hanging straight down
    from hip and shoulder joints set out sideways (so rest angles are all 0)."""
    offsets = CMU_REST_OFFSETS.copy()
    for name, offset in {"LeftUpLeg": (1.5, 0, 0), "RightUpLeg": (-1.5, 0, 0),
                         "LeftLeg": (0, -7, 0), "RightLeg": (0, -7, 0), "LeftFoot": (0, -7, 0),
                         "RightFoot": (0, -7, 0), "Spine": (0, 2, 0), "Spine1": (0, 2, 0),
                         "LeftArm": (2, 0, 0), "RightArm": (-2, 0, 0),
                         "LeftForeArm": (0, -3, 0), "RightForeArm": (0, -3, 0),
                         "LeftHand": (0, -3, 0), "RightHand": (0, -3, 0)}.items():
        offsets[CMU_JOINT_NAMES.index(name)] = offset
    return offsets


def test_the_angles_from_our_forward_kinematics():
    """A pose vector bending the same joints by known angles gives them back."""
    names = pose_vector_names()
    v = np.zeros((2, len(names)))
    v[:, 0] = 1.0
    np.testing.assert_allclose(limb_angles_deg(v[:1], _clean_template()), np.zeros((1, 8)),
                               atol=1e-9)
    for column, value in (("LeftLeg_x", 30), ("LeftForeArm_x", 60), ("RightForeArm_x", -90),
                          ("RightUpLeg_z", -40), ("LeftArm_z", 90)):
        v[:, names.index(column)] = value
    v[1, 1], v[1, 0] = 1.0, 0.0                     # heading 90: the same body angles
    np.testing.assert_allclose(limb_angles_deg(v, _clean_template()), [EXPECTED] * 2,
                               atol=1e-9)


def test_angle_measures_of_known_signals():
    t = np.arange(100)
    truth = 40 + 10 * np.sign(np.sin(2 * np.pi * (t + 0.5) / 20))    # +-10 square wave
    truth = np.stack([truth] * 8, axis=1)
    m = angle_measures(truth + 5, truth, LIMB_ANGLE_NAMES, constant=np.full(8, 20.0))
    assert m["corr"] == pytest.approx(1.0) and m["error"] == pytest.approx(5.0)
    assert m["truth_mean_error_mean"] == pytest.approx(10.0)
    assert m["constant_error_mean"] == pytest.approx(20.0)
    assert m["frames"] == 100 and m["names"] == list(LIMB_ANGLE_NAMES)
    assert angle_measures(80 - truth, truth, LIMB_ANGLE_NAMES)["corr"] == pytest.approx(-1.0)
    assert angle_measures(np.full_like(truth, 40.0), truth, LIMB_ANGLE_NAMES)["corr"] == 0.0
    with pytest.raises(MeasureError, match="shape"):
        angle_measures(truth[:, :4], truth, LIMB_ANGLE_NAMES)


def _mediapipe_landmarks(p: dict, yaw_deg: float = 0.0) -> np.ndarray:
    """A body's points in MediaPipe's world layout (33, 3): hip-centred, x right, y down,
    z away from a camera at +z of the body's frame; yaw_deg turns the body about the
    vertical (counter-clockwise seen from above); unused landmarks NaN."""
    a = np.radians(yaw_deg)
    turn = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    hip = (p["LHip"] + p["RHip"]) / 2
    out = np.full((33, 3), np.nan)
    for name, index in mediapipe_peer.MEDIAPIPE_INDEX.items():
        out[index] = (turn @ (p[name] - hip)) * [1.0, -1.0, -1.0]
    return out


def test_mediapipe_landmarks_give_the_angles_and_heading():
    p = hand_made_body()
    world = np.stack([_mediapipe_landmarks(p), _mediapipe_landmarks(p, 90.0),
                      _mediapipe_landmarks(p, -150.0), np.full((33, 3), np.nan)])
    angles = mediapipe_peer.limb_angles(world)
    np.testing.assert_allclose(angles[:3], [EXPECTED] * 3, atol=1e-9)
    assert np.isnan(angles[3]).all()               # nobody found
    np.testing.assert_allclose(mediapipe_peer.heading_deg(world)[:3], [0.0, 90.0, -150.0],
                               atol=1e-9)
    with pytest.raises(mediapipe_peer.PeerError, match="33"):
        mediapipe_peer.limb_angles(world[:, :20])


def test_mediapipe_follows_the_subject_only_inside_the_reference_box():
    image = np.full((3, 33, 3), np.nan)
    image[0, [23, 24], :2] = [[100, 200], [120, 200]]        # mid-hip (110, 200): inside
    image[1, [23, 24], :2] = [[400, 200], [420, 200]]        # someone else
    boxes = mediapipe_peer.keypoint_boxes(np.array([[[100, 50], [150, 400]]] * 3))
    np.testing.assert_allclose(boxes[0], [90, -20, 160, 470])
    assert mediapipe_peer.subject_frames(image, boxes).tolist() == [True, False, False]


def test_mediapipe_results_are_written_and_read_without_pickle(tmp_path):
    results = {"world": np.zeros((4, 33, 3)), "image": np.ones((4, 33, 3)),
               "frames": np.arange(4)}
    mediapipe_peer.write_results(tmp_path / "cam01.npz", results)
    back = mediapipe_peer.read_results(tmp_path / "cam01.npz")
    assert all(np.array_equal(back[k], results[k]) for k in results)
    np.savez(tmp_path / "bad.npz", world=np.zeros((4, 20, 3)), image=np.zeros((4, 33, 3)),
             frames=np.arange(4))
    for name in ("bad.npz", "none.npz"):
        with pytest.raises(mediapipe_peer.PeerError, match=name):
            mediapipe_peer.read_results(tmp_path / name)


def test_the_swings_reference_reads_with_balancing_calibration(pose2sim_swings):
    trial = load_trial(pose2sim_swings)
    names = trial.reference.names
    assert len(names) == 20 and {"Neck", "Hip", "LBigToe", "RHeel"} <= set(names)
    assert sorted(trial.cameras) == list(VIEWS)
    frames = video_frames(trial)
    assert frames.tolist() == list(range(100))
    p = trial.points(frames)
    shoulders = p[:, [names.index("LShoulder"), names.index("RShoulder")]].mean(axis=1)
    np.testing.assert_allclose(p[:, names.index("Neck")], shoulders, atol=1e-5)
    angles = reference_limb_angles(trial, frames)
    assert angles.shape == (100, 8)
    # The data README's constant (the reference's own mean angle): 11.6 degrees.
    assert np.abs(angles - angles.mean(axis=0)).mean() == pytest.approx(11.6, abs=0.05)
    # It moves most at the hips, arms and trunk: every angle moves by several degrees.
    assert (angles.std(axis=0) > 8).all()


def _landmarks_from_reference(trial, view: str, frames) -> dict:
    """MediaPipe-shaped results made from the reference itself: its keypoints in the view's
    camera axes (hip-centred), and projected into its pixels."""
    names, camera = trial.reference.names, trial.camera(view)
    world_calibration = trial.points(frames)[..., [2, 0, 1]]
    in_camera = world_calibration @ camera.R.T + camera.t
    px = project_reference(view, frames, trial)
    world = np.full((len(frames), 33, 3), np.nan)
    image = np.full_like(world, np.nan)
    for name, index in mediapipe_peer.MEDIAPIPE_INDEX.items():
        world[:, index] = in_camera[:, names.index(name)]
        image[:, index, :2] = px[:, names.index(name)]
    world -= world[:, [23, 24]].mean(axis=1, keepdims=True)
    return {"world": world, "image": image, "frames": np.asarray(frames)}


def test_mediapipe_scoring_path_on_the_reference_itself(pose2sim_swings):
    """Landmarks that are the reference score correlation 1 and error 0 on the frames asked
    for; the heading is right up to the camera's tilt and the subject off the optical axis."""
    trial = load_trial(pose2sim_swings)
    frames = video_frames(trial)
    results = _landmarks_from_reference(trial, "cam02", frames)
    results["image"][5] += 1000                         # MediaPipe followed someone else
    m = peer_view_measures(trial, "cam02", results, frames[:50])
    assert m["frames"] == 49 and m["series"][0].tolist() == [f for f in range(50) if f != 5]
    assert m["limbs"]["corr"] == pytest.approx(1.0) and m["limbs"]["error"] < 1e-6
    assert m["heading"]["rms_deg"] < 15
    pooled = pooled_limb_measures(trial, {"cam02": m["series"][0]}, {"cam02": m["series"][1]})
    assert pooled["pooled"]["corr"] == pytest.approx(1.0)
    assert pooled["mean"]["error"] == pytest.approx(0.0, abs=1e-6)


class _FakePose:
    """Stands in for mediapipe's legacy Pose: on a frame greyed outside the subject's box it
    finds the subject (mid-hip in the box) and follows it from then on; otherwise it finds
    someone else (mid-hip in the top-left corner)."""

    made = 0

    def __init__(self, **settings):
        assert settings["model_complexity"] == 1 and not settings["static_image_mode"]
        type(self).made += 1
        self.following = False

    def process(self, rgb):
        from types import SimpleNamespace
        self.following = self.following or bool((rgb[0, 0] == 127).all())
        x, y = (0.5, 0.5) if self.following else (0.02, 0.02)
        marks = [SimpleNamespace(x=x, y=y, z=0.0) for _ in range(33)]
        return SimpleNamespace(pose_landmarks=SimpleNamespace(landmark=marks),
                               pose_world_landmarks=SimpleNamespace(landmark=marks))

    def close(self):
        pass


def test_mediapipe_is_started_on_the_subject_masked_outside_its_box(tmp_path, monkeypatch):
    """run_view's subject picking, with a stand-in for mediapipe (not needed here)."""
    import sys
    from types import SimpleNamespace

    import cv2
    video = tmp_path / "v.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10, (64, 48))
    for _ in range(5):
        writer.write(np.full((48, 64, 3), 30, np.uint8))
    writer.release()
    fake = SimpleNamespace(solutions=SimpleNamespace(pose=SimpleNamespace(Pose=_FakePose)))
    monkeypatch.setitem(sys.modules, "mediapipe", fake)
    boxes = np.tile([16.0, 12.0, 48.0, 36.0], (5, 1))          # holds the centre (32, 24)
    results = mediapipe_peer.run_view(video, boxes)
    assert _FakePose.made == 1                       # started once, on the subject, and kept
    np.testing.assert_allclose(results["image"][:, 23, :2], [[32.0, 24.0]] * 5)
    assert mediapipe_peer.subject_frames(results["image"], boxes).all()
    assert results["frames"].tolist() == list(range(5))
