"""Data-set builder: held-out trials stay out, seeds reproduce, caches round-trip."""
from __future__ import annotations

import numpy as np
import pytest

from sequences.bvh import write_bvh
from sequences.dataset import (HELD_OUT_TRIALS, DatasetConfig, DatasetError, build_dataset,
                               load_trial, render_trial, training_files, view_settings)
from sequences.pose_vector import heading_deg
from sequences.skeleton import CMU_JOINT_NAMES
from tests.synthetic import cmu_motion

SMALL = dict(views_per_trial=2, person_px=48.0, mask_size=(64, 64))


def _write_trial(folder, name: str, T: int = 6, swing: float = 20.0):
    """A short synthetic BVH (legs swinging) named like a CMU trial."""
    J = len(CMU_JOINT_NAMES)
    euler = np.zeros((T, J, 3))
    euler[:, CMU_JOINT_NAMES.index("LeftUpLeg"), 2] = swing * np.sin(np.arange(T))
    motion = cmu_motion(euler, np.tile([0.0, 17.0, 0.0], (T, 1)))
    path = folder / f"{name}.bvh"
    write_bvh(path, motion)
    return path


@pytest.fixture
def bvh_folder(tmp_path):
    folder = tmp_path / "bvh"
    folder.mkdir()
    for name in ("02_01", "05_01", "16_11"):
        _write_trial(folder, name)
    return folder


def test_training_files_exclude_held_out_trials(bvh_folder):
    assert "16_11" in HELD_OUT_TRIALS
    names = [p.stem for p in training_files(bvh_folder)]
    assert names == ["02_01", "05_01"]


def test_held_out_trial_is_refused_in_a_training_set(bvh_folder, tmp_path):
    with pytest.raises(DatasetError, match="16_11"):
        build_dataset([bvh_folder / "16_11.bvh"], DatasetConfig(**SMALL), tmp_path / "cache")


def test_same_seed_reproduces_and_other_seed_differs(bvh_folder, tmp_path):
    a = render_trial(bvh_folder / "02_01.bvh", DatasetConfig(seed=3, **SMALL))
    b = render_trial(bvh_folder / "02_01.bvh", DatasetConfig(seed=3, **SMALL))
    c = render_trial(bvh_folder / "02_01.bvh", DatasetConfig(seed=4, **SMALL))
    assert np.array_equal(a.masks, b.masks) and np.array_equal(a.pose, b.pose)
    assert not np.allclose(a.azimuth_deg, c.azimuth_deg)


def test_views_spread_azimuth_and_pose_is_relative_to_the_camera(bvh_folder):
    config = DatasetConfig(**{**SMALL, "views_per_trial": 4})
    views = view_settings(config, "02_01")
    az = np.sort([v["azimuth_deg"] for v in views])
    assert np.allclose(np.diff(az), 90.0)
    trial = render_trial(bvh_folder / "02_01.bvh", config)
    # The synthetic subject faces +Z (yaw 0): heading = -azimuth of the view's camera.
    expected = (-trial.azimuth_deg + 180) % 360 - 180
    diff = (heading_deg(trial.pose) - expected + 180) % 360 - 180
    assert np.abs(diff).max() < 1e-6
    # Each view shows a person: non-empty silhouettes of plausible size.
    area = trial.masks.reshape(len(trial.masks), -1).sum(axis=1)
    assert area.min() > 100


def test_build_uses_cache_and_numbers_sequences(bvh_folder, tmp_path):
    config = DatasetConfig(**SMALL)
    seen = []
    files = training_files(bvh_folder)
    first = build_dataset(files, config, tmp_path / "cache",
                          progress=lambda trial, done, total: seen.append((trial, done, total)))
    assert seen == [("02_01", 1, 2), ("05_01", 2, 2)]
    assert sorted(set(first.sequence)) == [0, 1, 2, 3]
    assert first.trial_of_sequence == ["02_01", "02_01", "05_01", "05_01"]
    cached = sorted((tmp_path / "cache").glob("*.npz"))
    assert len(cached) == 2
    again = build_dataset(files, config, tmp_path / "cache")
    assert np.array_equal(first.masks, again.masks) and np.array_equal(first.pose, again.pose)
    loaded = load_trial(cached[0])
    assert loaded.masks.dtype == bool and loaded.masks.shape[1:] == (64, 64)


def test_corrupt_cache_is_refused(tmp_path):
    bad = tmp_path / "x.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(DatasetError, match="unreadable"):
        load_trial(bad)


def test_bad_config_is_refused():
    with pytest.raises(DatasetError, match="views_per_trial"):
        DatasetConfig(views_per_trial=0)
    with pytest.raises(DatasetError, match="elevation"):
        DatasetConfig(elevation_deg=(30.0, 10.0))


def test_real_training_set_lists_all_but_held_out(cmu_bvh_dir):
    names = {p.stem for p in training_files(cmu_bvh_dir)}
    assert names.isdisjoint(HELD_OUT_TRIALS)
    assert len(names) == len(list(cmu_bvh_dir.glob("*.bvh"))) - len(HELD_OUT_TRIALS)
