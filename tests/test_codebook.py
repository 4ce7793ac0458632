"""k-means codebook: reproducible fitting, storage as plain arrays, validation."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from regressor.codebook import Codebook, CodebookError
from regressor.descriptor import DescriptorSettings
from regressor.descriptor_batch import contexts_for_masks
from regressor.model_writer import codebook_arrays
from regressor.training import fit_codebook, fit_codebook_for_masks, kmeans


def blobs(seed: int = 0, per_blob: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """Points around 4 well-separated 3-D centres: (4 * per_blob, 3) points and the (4, 3) centres."""
    rng = np.random.default_rng(seed)
    truth = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0], [0.0, 0.0, 10.0]])
    x = np.repeat(truth, per_blob, axis=0) + rng.normal(scale=0.5, size=(4 * per_blob, 3))
    return x, truth


def random_contexts(seed: int, n: int = 3000, d: int = 60) -> np.ndarray:
    """Histogram-like rows (each sums to 1), as shape contexts are."""
    return np.random.default_rng(seed).dirichlet(np.full(d, 0.3), size=n)


def test_kmeans_recovers_separated_clusters():
    x, truth = blobs()
    centres, labels = kmeans(x, 4, seed=1)
    order = np.argsort(((truth[:, None] - centres[None]) ** 2).sum(axis=2), axis=1)[:, 0]
    assert sorted(order) == [0, 1, 2, 3]  # one centre per blob
    np.testing.assert_allclose(centres[order], truth, atol=0.15)
    assert np.all(np.bincount(labels) == 200)


def test_same_seed_gives_identical_centres():
    contexts = random_contexts(0)
    a = fit_codebook(contexts, n_centres=20, seed=7, max_samples=1000)
    b = fit_codebook(contexts.copy(), n_centres=20, seed=7, max_samples=1000)
    assert np.array_equal(a.centres, b.centres) and a.sigma == b.sigma


def test_different_seeds_give_different_centres():
    contexts = random_contexts(0)
    a = fit_codebook(contexts, n_centres=20, seed=7, max_samples=1000)
    b = fit_codebook(contexts, n_centres=20, seed=8, max_samples=1000)
    assert not np.allclose(a.centres, b.centres)


def test_sigma_is_the_rms_distance_to_the_nearest_centre():
    contexts = random_contexts(1, n=500)
    book = fit_codebook(contexts, n_centres=10, seed=0)
    d2 = ((contexts[:, None, :] - book.centres[None]) ** 2).sum(axis=2).min(axis=1)
    assert book.sigma == pytest.approx(np.sqrt(d2.mean()), rel=1e-9)
    assert book.centres.shape == (10, 60)


def test_repeated_points_do_not_give_nan_centres():
    x = np.repeat(np.eye(3), 10, axis=0)  # only 3 distinct points for 5 centres
    centres, labels = kmeans(x, 5, seed=0)
    assert np.all(np.isfinite(centres)) and labels.shape == (30,)


def test_too_few_contexts_are_refused():
    with pytest.raises(CodebookError, match="at least n_centres"):
        fit_codebook(random_contexts(0, n=50), n_centres=100)


def test_codebook_round_trips_through_npz(tmp_path):
    book = fit_codebook(random_contexts(2, n=400), n_centres=8, seed=3)
    np.savez(tmp_path / "cb.npz", **codebook_arrays(book))
    with np.load(tmp_path / "cb.npz", allow_pickle=False) as stored:
        loaded = Codebook.from_arrays(stored)
    assert np.array_equal(loaded.centres, book.centres) and loaded.sigma == book.sigma


@pytest.mark.parametrize(
    "arrays, message",
    [
        ({"codebook_centres": np.zeros((4, 60))}, "missing"),
        ({"codebook_centres": np.zeros(60), "codebook_sigma": np.array(0.1)}, "shape"),
        ({"codebook_centres": np.full((4, 60), np.nan), "codebook_sigma": np.array(0.1)}, "NaN"),
        ({"codebook_centres": np.zeros((4, 60)), "codebook_sigma": np.array(0.0)}, "sigma"),
        ({"codebook_centres": np.zeros((4, 60)), "codebook_sigma": np.array([0.1, 0.2])}, "sigma"),
    ],
    ids=["missing-sigma", "1-d-centres", "nan", "zero-sigma", "vector-sigma"],
)
def test_malformed_codebook_arrays_are_refused(arrays, message):
    with pytest.raises(CodebookError, match=message):
        Codebook.from_arrays(arrays)


def _ellipse_masks() -> list[np.ndarray]:
    masks = []
    for axes in ((20, 60), (40, 50), (15, 70), (30, 30)):
        m = np.zeros((160, 120), np.uint8)
        cv2.ellipse(m, (60, 80), axes, 20, 0, 360, 1, -1)
        cv2.rectangle(m, (55, 0), (65, 80), 1, -1)
        masks.append(m)
    return masks


def test_contexts_for_masks_keeps_per_mask_samples_and_is_seeded():
    settings = DescriptorSettings(n_points=120)
    masks = _ellipse_masks()
    a = contexts_for_masks(masks, settings, per_mask=30, seed=4)
    b = contexts_for_masks(masks, settings, per_mask=30, seed=4)
    assert a.shape == (4 * 30, 60) and np.array_equal(a, b)
    assert not np.array_equal(a, contexts_for_masks(masks, settings, per_mask=30, seed=5))


def test_fit_codebook_for_masks_is_reproducible():
    settings = DescriptorSettings(n_points=120)
    a = fit_codebook_for_masks(_ellipse_masks(), settings, n_centres=12, seed=2, per_mask=40)
    b = fit_codebook_for_masks(_ellipse_masks(), settings, n_centres=12, seed=2, per_mask=40)
    assert a.centres.shape == (12, 60) and np.array_equal(a.centres, b.centres)
