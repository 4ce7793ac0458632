"""Synthetic videos: readable mp4, shaded people over a textured scene, consistent ground truth."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from sequences.bvh import Motion
from sequences.pose_vector import heading_deg
from sequences.skeleton import CMU_JOINT_NAMES
from tests.synthetic import cmu_motion
from sequences.video import (Actor, VideoWriteError, load_truth, textured_background,
                             write_video)

SIZE = (120, 160)


def _walker(T: int = 8, step: float = 1.0, fps: float = 30.0) -> Motion:
    J = len(CMU_JOINT_NAMES)
    euler = np.zeros((T, J, 3))
    euler[:, CMU_JOINT_NAMES.index("LeftUpLeg"), 2] = 20 * np.sin(np.arange(T) / 2)
    root = np.column_stack([step * np.arange(T), np.full(T, 17.0), np.zeros(T)])
    return cmu_motion(euler, root, fps=fps, source="walker")


def _read_all(path):
    cap = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        frames.append(frame)
    return frames


def test_video_is_readable_with_its_ground_truth(tmp_path):
    path = tmp_path / "walk.mp4"
    write_video(path, [Actor(_walker())], size=SIZE, noise_sigma=2.0, seed=1)
    frames = _read_all(path)
    assert len(frames) == 8 and frames[0].shape == (*SIZE, 3)
    truth = load_truth(path)
    assert truth["pose"].shape == (8, 1, 55) and truth["bbox_px"].shape == (8, 1, 4)
    x, y, w, h = truth["bbox_px"][0, 0]
    # A T-posed person (arm span ~ height) filling most of the frame's height, inside it.
    assert h > 0.6 * SIZE[0] and 0.6 * h < w < 1.5 * h
    assert x >= 0 and y >= 0 and x + w <= SIZE[1] and y + h <= SIZE[0]
    # The person is where the ground truth says: pixels inside the box differ from the scene.
    scene = cv2.cvtColor(textured_background(SIZE, seed=1), cv2.COLOR_RGB2BGR).astype(float)
    diff = np.abs(frames[0].astype(float) - scene).sum(axis=2)
    inside = diff[y:y + h, x:x + w].mean()
    outside = np.delete(diff, np.s_[x:x + w], axis=1).mean()
    assert inside > 2.5 * outside                     # a box that missed the person: ~1x


def test_camera_facing_subject_has_heading_near_zero(tmp_path):
    path = tmp_path / "front.mp4"
    write_video(path, [Actor(_walker(step=0.0))], size=SIZE, azimuth_deg=0.0, noise_sigma=0)
    h = heading_deg(load_truth(path)["pose"][:, 0])
    assert np.abs(h).max() < 2.0                      # line of sight nearly along +Z
    path = tmp_path / "side.mp4"
    write_video(path, [Actor(_walker(step=0.0))], size=SIZE, azimuth_deg=90.0, noise_sigma=0)
    h = heading_deg(load_truth(path)["pose"][:, 0])
    assert np.abs(h + 90.0).max() < 2.0


def test_two_people_get_separate_boxes_and_positions(tmp_path):
    path = tmp_path / "two.mp4"
    actors = [Actor(_walker(), offset_m=(-1.5, 0.0)), Actor(_walker(), offset_m=(1.5, 0.0))]
    write_video(path, actors, size=SIZE, noise_sigma=1.0)
    truth = load_truth(path)
    assert truth["bbox_px"].shape == (8, 2, 4)
    left, right = truth["centroid_px"][:, 0, 0], truth["centroid_px"][:, 1, 0]
    assert np.all(right - left > 30)
    assert np.allclose(truth["hips_m"][:, 1, 0] - truth["hips_m"][:, 0, 0], 3.0)


def test_noise_is_seeded(tmp_path):
    a, b, c = tmp_path / "a.mp4", tmp_path / "b.mp4", tmp_path / "c.mp4"
    for p, seed in ((a, 5), (b, 5), (c, 6)):
        write_video(p, [Actor(_walker(T=2))], size=SIZE, noise_sigma=3.0, seed=seed)
    fa, fb, fc = _read_all(a)[0], _read_all(b)[0], _read_all(c)[0]
    assert np.array_equal(fa, fb)
    assert not np.array_equal(fa, fc)


def test_bad_options_are_refused(tmp_path):
    with pytest.raises(VideoWriteError, match="fps"):
        write_video(tmp_path / "x.mp4", [Actor(_walker(fps=120.0))], size=SIZE)
    with pytest.raises(VideoWriteError, match="at least one actor"):
        write_video(tmp_path / "x.mp4", [], size=SIZE)
    with pytest.raises(VideoWriteError, match="size"):
        write_video(tmp_path / "x.mp4", [Actor(_walker())], size=(8, 8))
    with pytest.raises(VideoWriteError, match="cannot read ground truth"):
        load_truth(tmp_path / "missing.mp4")


def test_replace_video_writes_the_pair_whole_or_leaves_the_old_one(tmp_path):
    """sequences.video.replace_video: an interrupted render leaves the old video and sidecar
    as they were and no temporary file; a finished one replaces both."""
    from sequences.video import replace_video, truth_path
    path = tmp_path / "walk.mp4"

    def render(partial, stop=False):
        partial.write_bytes(b"new frames")
        if stop:                                    # Ctrl-C before the ground truth
            raise KeyboardInterrupt
        truth_path(partial).write_bytes(b"new truth")
    with pytest.raises(KeyboardInterrupt):
        replace_video(path, lambda partial: render(partial, stop=True))
    assert list(tmp_path.iterdir()) == []           # nothing was there, nothing is
    path.write_bytes(b"old frames")
    truth_path(path).write_bytes(b"old truth")
    with pytest.raises(KeyboardInterrupt):
        replace_video(path, lambda partial: render(partial, stop=True))
    assert path.read_bytes() == b"old frames" and truth_path(path).read_bytes() == b"old truth"
    replace_video(path, render)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["walk.mp4", "walk.truth.npz"]
    assert path.read_bytes() == b"new frames" and truth_path(path).read_bytes() == b"new truth"
