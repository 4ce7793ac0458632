"""Realistic training masks: a coloured body over a room, H.264, cut out by the tracker."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sequences.backgrounds import background_view, procedural_plates
from sequences.body import Skinner, load_body
from sequences.dataset import DatasetConfig, DatasetError, render_trial
from sequences.render import silhouette_mask
from sequences.scene_render import (SceneConfig, body_parts, clip_bounds, draw_body, film_clip,
                                    extract_people, h264_round_trip, in_frame, on_canvas,
                                    placed_camera, realistic_masks, sample_look, scene_camera)
from tests.synthetic import gait_walk

BODY = load_body()


def _walk(T: int):
    """Posed vertices (T, V, 3) of a synthetic walk across the view and the standing height."""
    motion = gait_walk(T, 90.0)
    skinner = Skinner(BODY, offsets=motion.offsets, names=motion.names,
                      end_sites=motion.end_sites)
    verts = skinner.pose(motion.local_rotations(), skinner.root_from_bvh(motion.root_position))
    standing = skinner.pose(skinner.rest_local_rotations(), skinner.rest_root_m)
    return verts, float(np.ptp(standing[:, 1]))


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max((a | b).sum(), 1))


def test_textured_body_cut_out_by_the_tracker_gives_the_plain_mask():
    """Shaded body over a textured room, H.264 at CRF 20, the tracker's own extractor: its
    masks match the plain renderer's within the extractor's error (on the shipped sample's
    video the extractor's masks have IoU 0.79 with the clean renders, sequences.mask_noise)."""
    verts, height = _walk(48)
    rng = np.random.default_rng(1)
    config = SceneConfig()
    view = {**scene_camera(rng, config), "centre_u": 70.0}     # the walker crosses the room
    look = sample_look(rng)
    background = background_view(procedural_plates(1), config.frame_size, rng)
    frames, plain = film_clip(verts, BODY, body_parts(BODY), view, 0.0, height, background,
                              look, rng, config)
    people = extract_people(h264_round_trip(frames, crf=20))
    ious = [_iou(in_frame(p, config.frame_size), m) for p, m in zip(people, plain)]
    assert all(p is not None for p in people)
    assert np.median(ious) >= 0.75, np.round(ious, 2)


def test_shading_and_colours_are_deterministic_under_a_seed():
    verts, height = _walk(2)
    parts = body_parts(BODY)
    images = []
    for seed in (5, 5, 6):
        rng = np.random.default_rng(seed)
        look = sample_look(rng)
        camera = placed_camera(verts[0], 30.0, 15.0, 4.0, 150.0, height, (240, 320), 160, 220)
        canvas = np.zeros((240, 320, 4), np.uint8)
        draw_body(canvas, verts[0], BODY, parts[0], camera, look)
        images.append(canvas)
    assert np.array_equal(images[0], images[1])
    assert not np.array_equal(images[0][..., :3], images[2][..., :3])
    # The drawn body covers exactly the plain silhouette (same triangles, same fill rule).
    plain = silhouette_mask(verts[0], BODY.faces, BODY.patch_start, camera)
    assert np.array_equal(images[0][..., 3] > 0, plain)
    # Shading: the body is not one flat colour per part.
    assert len(np.unique(images[0][images[0][..., 3] > 0][:, :3], axis=0)) > 20


def test_placed_camera_puts_the_feet_where_asked():
    verts, height = _walk(1)
    camera = placed_camera(verts[0], 0.0, 20.0, 4.0, 150.0, height, (240, 320), 100.0, 200.0)
    mask = silhouette_mask(verts[0], BODY.faces, BODY.patch_start, camera)
    ys, xs = np.nonzero(mask)
    assert abs(ys.max() - 200) <= 2 and abs((xs.min() + xs.max()) / 2 - 100) <= 2


def test_clips_and_canvas():
    assert clip_bounds(10, 4) == [(0, 3), (3, 7), (7, 10)]
    assert clip_bounds(3, 150) == [(0, 3)]
    tall = np.zeros((300, 50), bool)
    tall[10:290, 20:30] = True
    canvas = on_canvas(tall, (224, 224))
    ys, xs = np.nonzero(canvas)
    assert canvas.shape == (224, 224) and ys.max() - ys.min() + 1 <= 216
    assert abs((ys.min() + ys.max()) / 2 - 111.5) <= 1


def test_realistic_masks_of_a_sequence_have_the_canvas_shape_and_repeat_under_a_seed():
    verts, height = _walk(20)
    runs = [realistic_masks(lambda a, b: verts[a:b], 20, BODY, 0.0, height,
                            procedural_plates(1), np.random.default_rng(0),
                            SceneConfig(clip_frames=10), mask_size=(96, 128)) for _ in range(2)]
    masks, info = runs[0]
    assert np.array_equal(masks, runs[1][0])
    assert masks.shape == (20, 96, 128) and masks.dtype == bool
    assert masks.reshape(20, -1).any(axis=1).all()
    assert info["iou"].shape == (20,) and 5 <= info["elevation_deg"] <= 30


def test_data_set_hook_makes_realistic_masks(tmp_path):
    from sequences.bvh import write_bvh
    path = tmp_path / "02_01.bvh"
    write_bvh(path, gait_walk(12, 90.0))
    config = DatasetConfig(views_per_trial=1, masks="realistic", person_px=100.0,
                           mask_size=(224, 224))
    trial = render_trial(path, config)
    assert trial.masks.shape == (12, 224, 224) and trial.masks.dtype == bool
    assert trial.masks.reshape(12, -1).any(axis=1).all()
    assert trial.pose.shape[0] == 12 and trial.elevation_deg.min() >= 5
    # Plain data sets keep their cache key; a realistic one gets its own.
    assert DatasetConfig().digest() == DatasetConfig(backgrounds="x").digest()
    assert DatasetConfig(masks="realistic").digest() != DatasetConfig().digest()
    with pytest.raises(DatasetError, match="masks must be one of"):
        DatasetConfig(masks="fancy")


def test_build_dataset_refuses_backgrounds_without_realistic_masks(tmp_path):
    run = subprocess.run([sys.executable, "scripts/build_dataset.py", "--backgrounds",
                          str(tmp_path), "--cache", str(tmp_path / "c")],
                         capture_output=True, text=True, cwd=Path(__file__).resolve().parents[1])
    assert run.returncode == 2
    assert "--backgrounds needs --masks realistic" in run.stderr
    assert "Traceback" not in run.stderr


def test_measure_render_gap_refuses_bad_options_in_one_line(tmp_path):
    root = Path(__file__).resolve().parents[1]
    for args, message in ((["--frames", "0"], "--frames must be 1..10000"),
                          (["--bvh-dir", str(tmp_path / "none")], "--bvh-dir: folder not found")):
        run = subprocess.run([sys.executable, "scripts/measure_render_gap.py", *args],
                             capture_output=True, text=True, cwd=root)
        assert run.returncode == 2 and message in run.stderr, run.stderr
        assert "Traceback" not in run.stderr and len(run.stderr.strip().splitlines()) == 1


def test_measure_render_gap_tracks_its_clips_with_the_model_it_measures(tmp_path, monkeypatch):
    """The "through track" novelty is the --model's (as the real views' is), not the default
    model's: track is run with --model."""
    from conftest import load_script
    gap = load_script("measure_render_gap")
    seen = []

    def fake_run(argv, **kw):
        seen.append(argv)
        Path(argv[argv.index("--json") + 1]).write_text('{"tracks": {"1": {"novelty": [0.5]}}}')
        return subprocess.CompletedProcess(argv, 0, "", "")
    monkeypatch.setattr(subprocess, "run", fake_run)
    model = tmp_path / "other_model.npz"
    assert gap.tracked_novelty([tmp_path / "a-0.mp4"], model) == {"a-0": 0.5}
    assert seen[0][seen[0].index("--model") + 1] == str(model)
