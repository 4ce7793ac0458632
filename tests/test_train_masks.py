"""scripts/train.py --masks {noisy,realistic} and --backgrounds: the options reach the data
set's settings (bad combinations are refused in one line: tests/test_train_cli.py), and
realistic masks (already video-like) are learnt from as they are: no hand noise
(sequences.mask_noise) on top, their layouts and mirror images taken from them."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import load_script
from regressor.codebook import Codebook
from regressor.descriptor import DescriptorSettings, descriptor_and_mirror
from sequences.dataset import Dataset, DatasetError
from lab.training import (layouts_for_masks, noisy_dataset_inputs, noisy_dataset_layouts,
                          video_like_masks)


@pytest.fixture(scope="module")
def train():
    return load_script("train")


def _masks(n: int = 6) -> np.ndarray:
    """n person-like silhouettes (a trunk, a head and two legs apart by i pixels), (n, 120, 80)."""
    masks = np.zeros((n, 120, 80), bool)
    for i, m in enumerate(masks):
        m[20:30, 35:45] = True                     # head
        m[30:70, 28:52] = True                     # trunk
        m[70:110, 30:38] = True                    # left leg
        m[70:110, 42 + i:50 + i] = True            # right leg, further out each mask
    return masks


def _codebook(settings: DescriptorSettings) -> Codebook:
    return Codebook(np.random.default_rng(0).random((12, settings.context_size)), 0.3)


def test_realistic_masks_are_described_as_they_are_with_their_layouts_and_mirrors():
    masks, settings = _masks(), DescriptorSettings()
    codebook = _codebook(settings)
    got = noisy_dataset_inputs(masks, settings, codebook, grid=4, mirror=True, workers=1,
                               degrade=False)
    own = np.array([descriptor_and_mirror(m, settings, codebook) for m in masks])
    np.testing.assert_allclose(got["histograms"], own[:, 0])
    np.testing.assert_allclose(got["mirror_histograms"], own[:, 1])
    np.testing.assert_allclose(got["layouts"], layouts_for_masks(masks, 4))
    np.testing.assert_allclose(got["mirror_layouts"], layouts_for_masks(masks[:, :, ::-1], 4))
    np.testing.assert_allclose(noisy_dataset_layouts(masks, 4, workers=1, degrade=False),
                               layouts_for_masks(masks, 4))
    np.testing.assert_array_equal(video_like_masks(masks, 0, degrade=False), masks)
    # The default still degrades: the hand noise changes every mask's layout.
    noisy = noisy_dataset_layouts(masks, 4, workers=1)
    assert np.abs(noisy - layouts_for_masks(masks, 4)).max(axis=1).min() > 0


def _stub_training(train, monkeypatch, dataset=None) -> dict:
    """Stubs train.py's data set steps: no motion capture needed; build_dataset records the
    DatasetConfig and gives ``dataset`` (or stops the run); returns what was recorded."""
    seen: dict = {}
    monkeypatch.setattr(train, "training_files", lambda bvh_dir: [])
    monkeypatch.setattr(train, "prior_files", lambda bvh_dir: [])

    def build(files, config, cache, **kw):
        seen["config"] = config
        if dataset is None:
            raise DatasetError("stopped after the data set's settings")
        return dataset
    monkeypatch.setattr(train, "build_dataset", build)
    return seen


def _argv(tmp_path, *options):
    return [*options, "--bvh-dir", str(tmp_path), "--cache", str(tmp_path / "cache"),
            "--out", str(tmp_path / "model.npz")]


@pytest.mark.parametrize("options, masks, rooms", [
    ([], "plain", ""),
    (["--masks", "noisy"], "plain", ""),
    (["--masks", "realistic"], "realistic", ""),
    (["--masks", "realistic", "--backgrounds", "procedural"], "realistic", ""),
    (["--masks", "realistic", "--backgrounds", "PLATES"], "realistic", "PLATES"),
])
def test_mask_options_reach_the_data_set(train, tmp_path, monkeypatch, capsys, options,
                                         masks, rooms):
    plates = tmp_path / "plates"
    plates.mkdir()
    (plates / "plate-cam01.png").write_bytes(b"")       # plates_folder only looks at names
    options = [str(plates) if o == "PLATES" else o for o in options]
    seen = _stub_training(train, monkeypatch)
    assert train.main(_argv(tmp_path, *options)) == 1
    assert "stopped after the data set's settings" in capsys.readouterr().err
    assert seen["config"].masks == masks
    assert seen["config"].backgrounds == (str(plates.resolve()) if rooms else "")


def _tiny_dataset() -> Dataset:
    masks = _masks(4)
    return Dataset(masks=masks, pose=np.zeros((4, 55)), sequence=np.zeros(4, int),
                   frame=np.arange(4), azimuth_deg=np.zeros(4), elevation_deg=np.zeros(4),
                   trials=["t"], trial_of_sequence=["t"])


@pytest.mark.parametrize("masks, degrade", [("noisy", True), ("realistic", False)])
def test_realistic_masks_skip_the_hand_noise_in_every_input(train, tmp_path, monkeypatch,
                                                            masks, degrade):
    """The codebook, the descriptors with their layouts and mirror images (one pass), and
    layouts made for cached descriptors all take the masks as they are with --masks realistic
    and degrade them with the default noisy masks."""
    _stub_training(train, monkeypatch, _tiny_dataset())
    codebook, calls = _codebook(DescriptorSettings()), {}

    def record(name, result, degrades=None):
        def stub(*args, **kw):
            calls[name] = kw.get("degrade", True) if degrades is None else degrades
            if result is None:
                raise DatasetError("stopped")
            return result
        return stub
    monkeypatch.setattr(train, "fit_noisy_codebook", record("codebook", codebook, True))
    monkeypatch.setattr(train, "fit_dataset_codebook", record("codebook", codebook, False))
    monkeypatch.setattr(train, "noisy_dataset_inputs", record("inputs", None))
    assert train.main(_argv(tmp_path, "--masks", masks)) == 1
    # Descriptors from the cache, layouts not: the layouts are made on their own.
    monkeypatch.setattr(train, "cached_descriptors",
                        lambda cache, key, compute: (np.ones((4, 12)), codebook))
    monkeypatch.setattr(train, "noisy_dataset_layouts", record("layouts", None))
    assert train.main(_argv(tmp_path, "--masks", masks)) == 1
    assert calls == {"codebook": degrade, "inputs": degrade, "layouts": degrade}
