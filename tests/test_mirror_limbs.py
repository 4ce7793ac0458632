"""Limbs averaged with the limbs of the mirror image (tracker.tracks.mirror_limbs): the mirrored
shape contexts, the model's mirror descriptor, the average, and the tracker's use of it."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from regressor.optional_parts import predict_limbs
from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
from regressor.shape_context import mirrored_bins, shape_contexts
from sequences.pose_vector import image_mirror
from synthetic import cmu_motion, joint
from tracker.tracks.mirror_limbs import mirror_mean, sees_mirror


@pytest.fixture(scope="module")
def model():
    return load_pose_model(DEFAULT_MODEL_PATH)


@pytest.fixture(scope="module")
def masks():
    """Six frames of a body stepping with its right arm raised sideways (not left/right
    symmetric), rendered side-on."""
    from lab.evaluation import CameraOptions, render_silhouettes
    T = 6
    euler = np.zeros((T, 31, 3))
    euler[:, joint("RightArm"), 0] = 70.0
    euler[:, joint("LeftUpLeg"), 2] = np.linspace(-30, 30, T)
    euler[:, joint("RightUpLeg"), 2] = np.linspace(20, -20, T)
    root = np.zeros((T, 3))
    root[:, 1] = 17.0
    root[:, 2] = np.linspace(0, 10, T)
    masks, _, _ = render_silhouettes(cmu_motion(euler, root), CameraOptions())
    return masks


def test_mirrored_bins_give_the_contexts_of_the_mirror_image():
    rng = np.random.default_rng(0)
    points = rng.normal(size=(150, 2)) * [40, 90]
    order = mirrored_bins(12, 5)
    np.testing.assert_array_equal(shape_contexts(points)[:, order],
                                  shape_contexts(points * [-1, 1]))
    np.testing.assert_array_equal(order[order], np.arange(60))      # its own inverse
    assert not np.array_equal(order, np.arange(60))
    with pytest.raises(ValueError, match="even number of sectors"):
        mirrored_bins(9, 5)


def test_describe_with_mirror_gives_the_frame_and_near_the_flipped_masks_descriptor(model,
                                                                                    masks):
    mask = masks[3]
    own, mirror = model.describe_with_mirror(mask)
    np.testing.assert_array_equal(own, model.describe(mask))
    flipped = model.describe(mask[:, ::-1])
    # the same shape, its edge sampled from another start: far nearer the flipped mask's
    # descriptor than the frame's own is
    assert np.linalg.norm(mirror - flipped) < 0.25 * np.linalg.norm(own - flipped)


def test_training_describes_mirror_images_as_the_tracker_does(model, masks):
    """lab.training.noisy_dataset_inputs: one pass gives the video-like masks'
    histograms and layouts exactly as describing them one by one does, and their mirror images'
    inputs as the tracker makes a frame's (the contexts reflected, the layout flipped)."""
    from regressor.descriptor import descriptor_and_mirror
    from regressor.descriptor_batch import descriptors_for_masks
    from regressor.layout import silhouette_layout
    from lab.training import noisy_dataset_inputs, noisy_dataset_layouts, noisy_masks
    settings, codebook = model.settings, model.codebook
    made = noisy_dataset_inputs(masks, settings, codebook, grid=8, mirror=True, seed=3,
                                workers=2)
    assert set(made) == {"histograms", "layouts", "mirror_histograms", "mirror_layouts"}
    np.testing.assert_array_equal(made["histograms"], descriptors_for_masks(
        noisy_masks(masks, 3), settings, codebook))
    np.testing.assert_array_equal(made["layouts"], noisy_dataset_layouts(masks, 8, seed=3,
                                                                         workers=1))
    for i in (0, 4):
        noisy = noisy_masks(masks[i:i + 1], 3, start=i)[0]
        np.testing.assert_array_equal(made["mirror_histograms"][i],
                                      descriptor_and_mirror(noisy, settings, codebook)[1])
        np.testing.assert_allclose(made["mirror_layouts"][i], silhouette_layout(noisy[:, ::-1], 8))
        assert not np.allclose(made["mirror_layouts"][i], made["layouts"][i])  # not symmetric
    plain = noisy_dataset_inputs(masks, settings, codebook, grid=0, seed=3, workers=1)
    assert set(plain) == {"histograms"}
    np.testing.assert_array_equal(plain["histograms"], made["histograms"])


def test_the_mean_mirrors_back_and_averages_angles_on_the_circle():
    rng = np.random.default_rng(1)
    pose = np.concatenate([[0.6, 0.8], rng.uniform(-60, 60, 53)])[None]
    # the mirror image's own body, exactly: the mean is the pose itself
    np.testing.assert_allclose(mirror_mean(pose, image_mirror(pose)), pose, atol=1e-12)
    other = pose.copy()
    other[0, 5] = pose[0, 5] + 20.0
    np.testing.assert_allclose(mirror_mean(pose, image_mirror(other))[0, 5], pose[0, 5] + 10.0)
    pose[0, 5], other[0, 5] = 170.0, -170.0           # across the wrap: 180, not 0
    assert abs(mirror_mean(pose, image_mirror(other))[0, 5]) == pytest.approx(180.0)
    with pytest.raises(ValueError, match="55"):
        mirror_mean(pose, pose[:, :54])


def test_only_a_model_whose_networks_saw_mirror_images_sees_mirrors(model):
    assert model.limbs_see_mirror and sees_mirror(model)
    assert not sees_mirror(model, enabled=False)
    options = {**model.description["options"], "limb_net_mirror": False}
    unmirrored = replace(model, description={**model.description, "options": options})
    assert not unmirrored.limbs_see_mirror and not sees_mirror(unmirrored)
    assert not replace(model, description={"options": "tampered"}).limbs_see_mirror


def test_the_proposals_average_the_networks_answer_for_the_mirror_image(model, masks):
    from regressor.stacking import stack_frames
    from tracker.tracks.proposals import propose_sequence
    plain = propose_sequence(model, masks, mirror=False)
    seen = propose_sequence(model, masks)
    pairs = [model.describe_with_mirror(m) for m in masks]
    X, M = (stack_frames(np.array([p[i] for p in pairs]), model.stack_depth) for i in (0, 1))
    expected = mirror_mean(predict_limbs(model, X), predict_limbs(model, M))
    for t in range(len(masks)):
        # the chain's member is the averaged limbs (one body of the pair; its flip the other);
        # the proposals pass a frame and its mirror image through the float32 networks in one
        # batch, which sums in another order than two single rows (differences ~1e-6 deg)
        np.testing.assert_allclose(seen[t].poses[0, 2:], expected[t, 2:], atol=1e-4)
        assert not np.allclose(seen[t].poses[0, 2:], plain[t].poses[0, 2:], atol=0.01)


def test_one_pass_for_the_frames_and_their_mirror_images_gives_each_ones_answer(model,
                                                                                  masks):
    from regressor.pose_model import PoseModelError
    from regressor.stacking import stack_frames
    pairs = [model.describe_with_mirror(m) for m in masks]
    X, M = (stack_frames(np.array([p[i] for p in pairs]), model.stack_depth) for i in (0, 1))
    both, alone = model.hypotheses(X, mirrored=M), model.hypotheses(X)
    assert alone.mirror_limbs is None
    for name in ("poses", "probabilities", "limbs", "front", "novelty"):
        np.testing.assert_allclose(getattr(both, name), getattr(alone, name), atol=1e-4)
    np.testing.assert_allclose(both.mirror_limbs, predict_limbs(model, M), atol=1e-4)
    assert not np.allclose(both.mirror_limbs[:, 2:], both.limbs[:, 2:], atol=1.0)
    with pytest.raises(PoseModelError, match="mirror"):
        model.hypotheses(X, mirrored=M[:2])


@pytest.mark.slow
def test_the_tracker_describes_the_mirror_frame_by_frame_as_offline(model, masks):
    """The streaming path (a second stacker of the mirror images' descriptors) proposes what
    propose_sequence does for the whole sequence."""
    from tracker import PoseTracker, TrackerSettings
    from tracker.tracks.proposals import propose_sequence
    from tracker.video.silhouettes import PersonMask
    for mirror in (True, False):
        tracker = PoseTracker(model, 30.0, TrackerSettings(mirror_limbs=mirror))
        tracker.prime(np.zeros((240, 320, 3), np.uint8))
        frames = []
        for i, mask in enumerate(masks):
            ys, xs = np.nonzero(mask)
            person = PersonMask(mask, (0, 0, mask.shape[1], mask.shape[0]),
                                (float(xs.mean()), float(ys.mean())), int(mask.sum()))
            frames.append((i, i / 30.0, [person], [tracker.describe(person)]))
        proposed = [pose.raw for poses, _ in tracker.track_frames(frames) for pose in poses]
        assert len(proposed) == len(masks)
        assert (tracker.tracks[0].mirror_stacker is not None) == mirror
        offline = propose_sequence(model, masks, mirror=mirror)
        np.testing.assert_allclose(proposed, [h.raw for h in offline], atol=1e-9)
