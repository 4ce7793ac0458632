"""The silhouette layout block (regressor.layout) and models whose input has it and a projection."""
from __future__ import annotations

import numpy as np
import pytest

from regressor.codebook import Codebook
from regressor.descriptor import DescriptorSettings
from regressor.edges import DegenerateSilhouetteError
from regressor.layout import silhouette_layout
from regressor.mixture import MixtureRegressor
from regressor.model_file import FORMAT_VERSION, checksum, load_model
from regressor.optional_parts import predict_batch
from regressor.pose_model import PoseModel, PoseModelError, load_pose_model
from regressor.model_writer import save_model, save_pose_model


def _figure(scale: int = 1, shift: tuple[int, int] = (0, 0)) -> np.ndarray:
    """A stick figure (legs apart, one arm out) on a canvas, scaled and shifted (pixels)."""
    m = np.zeros((120 * scale + 40, 100 * scale + 40), bool)
    y, x = shift
    s = scale
    m[y + 10 * s:y + 60 * s, x + 40 * s:x + 56 * s] = True            # torso and head
    m[y + 60 * s:y + 110 * s, x + 36 * s:x + 44 * s] = True           # left leg
    m[y + 60 * s:y + 110 * s, x + 54 * s:x + 70 * s] = True           # right leg, wider
    m[y + 20 * s:y + 26 * s, x + 56 * s:x + 90 * s] = True            # an arm out
    return m


def test_layout_is_coverage_on_the_bounding_square_and_ignores_size_and_position():
    a = silhouette_layout(_figure(), 8)
    assert a.shape == (64,) and a.min() == 0 and 0.5 < a.max() <= 1
    np.testing.assert_allclose(silhouette_layout(_figure(shift=(7, 11)), 8), a)
    assert np.abs(silhouette_layout(_figure(scale=3), 8) - a).max() < 0.05
    # The box is made square around the figure: its area share is kept, not stretched.
    box = np.zeros((100, 100), bool)
    box[10:90, 40:60] = True                                           # 80 x 20 bar
    bar = silhouette_layout(box, 4).reshape(4, 4)
    assert bar.mean() == pytest.approx(20 / 80, abs=1e-6)
    np.testing.assert_allclose(bar[:, [0, 3]], 0.0)
    np.testing.assert_allclose(bar[:, 1:3], 0.5)


def test_layout_keeps_the_scene_vertical_and_tells_mirror_images_apart():
    a = silhouette_layout(_figure(), 8)
    assert np.abs(silhouette_layout(_figure()[::-1], 8) - a).max() > 0.5       # upside down
    assert np.abs(silhouette_layout(_figure()[:, ::-1], 8) - a).max() > 0.5    # mirrored


def test_layout_refuses_empty_masks_and_absurd_grids():
    with pytest.raises(DegenerateSilhouetteError):
        silhouette_layout(np.zeros((10, 10), bool), 8)
    for grid in (0, 65):
        with pytest.raises(ValueError, match="grid"):
            silhouette_layout(_figure(), grid)


def _projected_model(k=2, C=6, grid=4, P=5):
    """A small mixture model whose input is C histogram bins + grid^2 layout cells per frame,
    k frames stacked and projected to P values."""
    rng = np.random.default_rng(9)
    D = C + grid * grid
    mean, projection = rng.normal(0, 1, k * D), rng.normal(0, 0.3, (k * D, P))
    x = rng.normal(0, 1, (500, k * D))
    z = (x - mean) @ projection
    y = np.column_stack([np.cos(z[:, 0]), np.sin(z[:, 0]), 10 * np.tanh(z[:, 1:2]) + rng.normal(0, 1, (500, 53))])
    mix = MixtureRegressor(n_experts=2, n_centres=30, gate_centres=20, seed=0).fit(z, y)
    settings = DescriptorSettings()
    model = PoseModel(settings=settings, codebook=Codebook(rng.random((C, settings.context_size)), 0.2),
                      stack_depth=k, transform="sqrt", basis="gaussian", width=None, centres=None,
                      relevance=np.zeros(0, np.int64), coef=np.zeros((0, 55)), intercept=np.zeros(55),
                      angle_centre_deg=np.zeros(53), measurement_covariance=np.eye(54),
                      process_noise=np.ones(54), mixture=mix, layout_grid=grid, layout_weight=2.5,
                      projection=projection, projection_mean=mean)
    return model, x


def test_a_model_with_layout_and_projection_round_trips_and_projects_its_input(tmp_path):
    model, x = _projected_model()
    assert model.descriptor_length == 6 + 16 and model.input_length == 5
    path = tmp_path / "m.npz"
    save_pose_model(path, model)
    loaded = load_pose_model(path)
    assert (loaded.layout_grid, loaded.layout_weight) == (4, 2.5)
    b = predict_batch(model, x[:20])
    assert np.abs(predict_batch(loaded, x[:20]) - b).max() < 0.02 * np.abs(b).max()
    direct = model.mixture.predict((x[:20] - model.projection_mean) @ model.projection)
    np.testing.assert_allclose(b[:, :2], direct[:, :2])
    with pytest.raises(PoseModelError, match=r"\(N, 2 x 22\)"):
        predict_batch(model, x[:2, :-1])


def test_the_layout_block_is_weighted_after_the_histogram_in_describe():
    from regressor.pose_model import DEFAULT_MODEL_PATH
    from dataclasses import replace
    base = load_pose_model(DEFAULT_MODEL_PATH)
    if base.layout_grid:
        base = replace(base, layout_grid=0, projection=None, projection_mean=None)
    with_layout = replace(base, layout_grid=4, layout_weight=3.0)
    mask = _figure(scale=2)
    d0, d1 = base.describe(mask), with_layout.describe(mask)
    assert d1.shape == (base.codebook.n_centres + 16,)
    np.testing.assert_allclose(d1[:len(d0)], d0)
    np.testing.assert_allclose(d1[len(d0):], 3.0 * silhouette_layout(mask, 4))


def _write_unchecked(path, parts):
    """A file with a valid checksum but parts save_model would refuse (an edited model)."""
    np.savez(path, **parts, format_version=np.int64(FORMAT_VERSION),
             checksum=np.str_(checksum(parts)))


def test_a_projection_that_does_not_fit_the_input_is_refused(tmp_path):
    model, _ = _projected_model()
    path = tmp_path / "m.npz"
    save_pose_model(path, model)
    raw = dict(load_model(path).parts)
    with pytest.raises(Exception, match="projection has 43 rows"):
        save_model(tmp_path / "never.npz", dict(raw, projection=raw["projection"][:-1]))
    for bad in (dict(raw, projection=raw["projection"][:-1]),      # one row short
                dict(raw, layout_grid=np.int64(5)),                 # a grid the rows don't fit
                dict(raw, projection=raw["projection"][0])):        # not a matrix
        _write_unchecked(path, bad)
        with pytest.raises(PoseModelError, match="projection"):
            load_pose_model(path)


def test_training_layouts_describe_the_same_noisy_masks_as_the_descriptors():
    """Row i's layout comes from the video-like mask seeded (seed, i), as its descriptor
    does (lab.training), whatever the number of workers."""
    from lab.training import noisy_dataset_layouts, noisy_masks
    masks = np.stack([_figure(scale=2)[:224, :224] for _ in range(3)])
    L1 = noisy_dataset_layouts(masks, 8, seed=2, workers=1)
    L2 = noisy_dataset_layouts(masks, 8, seed=2, workers=2)
    np.testing.assert_array_equal(L1, L2)
    for i in range(3):
        mask = noisy_masks(masks[i:i + 1], 2, start=i)[0]
        np.testing.assert_allclose(L1[i], silhouette_layout(mask, 8))
    assert not np.allclose(L1[0], L1[1])                  # each row its own noise
