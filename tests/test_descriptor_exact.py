"""The descriptor's fast paths give exactly what their plain numpy formulation gives: shape
contexts (pair differences by sgemm, sectors wrapped in unsigned integers, uint16 or uint32
keys, the point itself taken off bin 0) and the soft histograms of several silhouettes at once
(own and mirror image); edge points of bool masks; streamed stacks."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from regressor.codebook import Codebook, CodebookError, soft_histogram, soft_histograms
from regressor.edges import sample_edge_points
from regressor.layout import silhouette_layout
from regressor.shape_context import mirrored_bins, shape_contexts
from regressor.stacking import FrameStacker, stack_frames


def plain_shape_contexts(points, n_angular=12, n_radial=5, r_inner=0.125, r_outer=3.0):
    """The same float32 steps as shape_contexts, written directly: (N, N) arrays [i, j] by
    broadcast subtraction, the sector wrapped before counting, int64 keys."""
    points = np.asarray(points, dtype=np.float64)
    n = len(points)
    centred = points - points.mean(axis=0)
    scale = np.sqrt(2.0 * n / (n - 1) * (centred**2).sum(axis=1).mean())
    x, y = centred.astype(np.float32).T.copy()
    u = x[None, :] - x[:, None]
    v = y[:, None] - y[None, :]
    angle = np.arctan2(v, u) * np.float32(n_angular / (2 * np.pi)) + np.float32(n_angular)
    sector = angle.astype(np.int64)
    sector[sector >= n_angular] -= n_angular
    with np.errstate(divide="ignore"):
        ring = np.log(u * u + v * v)
    ring = (ring - np.float32(2.0 * np.log(r_inner * scale))) * np.float32(
        0.5 / (np.log(r_outer / r_inner) / n_radial))
    ring = np.clip(ring, np.float32(0.0), np.float32(n_radial - 0.5)).astype(np.int64)
    size = n_radial * n_angular
    counts = np.zeros((n, size + 1), np.int64)
    bins = ring * n_angular + sector
    np.fill_diagonal(bins, size)
    np.add.at(counts, (np.repeat(np.arange(n), n), bins.ravel()), 1)
    return counts[:, :size] / float(n - 1)


def point_sets():
    rng = np.random.default_rng(5)
    yield rng.normal(size=(300, 2)) * 40 + 200                      # uint16 keys
    yield np.round(rng.normal(size=(120, 2)) * 6)                    # equal coordinates, exact sector edges
    dup = rng.normal(size=(80, 2)) * 9
    yield np.vstack([dup, dup])                                      # coincident pairs
    yield rng.normal(size=(1100, 2)) * 30                            # 1100 * 60 keys: uint32
    # -0.0 after centring (x = -0.0 with a mean of +0.0): the plain-subtraction branch.
    yield np.array([[-0.0, 1.0], [0.0, 1.0], [1.0, -1.0], [-1.0, -1.0], [0.0, 2.0], [0.0, -2.0]])


@pytest.mark.parametrize("layout", [(12, 5), (8, 3), (7, 4), (1, 2), (13, 1)])
def test_shape_contexts_equal_the_plain_formulation_exactly(layout):
    n_angular, n_radial = layout
    for points in point_sets():
        fast = shape_contexts(points, n_angular, n_radial)
        np.testing.assert_array_equal(fast, plain_shape_contexts(points, n_angular, n_radial))


def test_negative_zero_coordinates_keep_their_sectors():
    # Two coincident points at x = -0.0 and x = +0.0 (the centroid's x is +0.0): the pair's
    # u = -0.0 - 0.0 is -0.0 and arctan2(+0.0, -0.0) = pi (sector 6), not 0 (sector 0): a sign
    # the sgemm would lose, so such point sets take the plain subtractions.
    points = np.array([[-0.0, 1.0], [0.0, 1.0], [1.0, -1.0], [-1.0, -1.0], [0.0, 2.0],
                       [0.0, -2.0]])
    np.testing.assert_array_equal(shape_contexts(points), plain_shape_contexts(points))


@pytest.fixture(scope="module")
def codebook():
    rng = np.random.default_rng(2)
    return Codebook(rng.dirichlet(np.full(60, 0.3), size=100), sigma=0.12)


def plain_soft_histogram(contexts, codebook, n_votes=5, total=100.0):
    """soft_histogram's steps written directly (one silhouette, 2-D fancy indexing)."""
    centres = codebook.centres
    d2 = (centres * centres).sum(axis=1)[None, :] - 2.0 * (contexts @ centres.T)
    rows = np.arange(len(d2))
    nearest = np.empty((len(d2), n_votes), dtype=np.intp)
    near_d2 = np.empty((len(d2), n_votes))
    for j in range(n_votes):
        nearest[:, j] = d2.argmin(axis=1)
        near_d2[:, j] = d2[rows, nearest[:, j]]
        d2[rows, nearest[:, j]] = np.inf
    weights = np.exp(-(near_d2 - near_d2[:, :1]) / (2.0 * codebook.sigma**2))
    weights /= weights.sum(axis=1, keepdims=True)
    hist = np.bincount(nearest.ravel(), weights=weights.ravel(), minlength=len(centres))
    return hist * (total / hist.sum())


def test_soft_histograms_of_a_silhouette_and_its_mirror_equal_single_calls(codebook):
    rng = np.random.default_rng(3)
    contexts = shape_contexts(rng.normal(size=(300, 2)) * 50)
    mirror = contexts[:, mirrored_bins()]
    both = soft_histograms((contexts, mirror), codebook)
    assert both.shape == (2, 100)
    np.testing.assert_array_equal(both[0], plain_soft_histogram(contexts, codebook))
    np.testing.assert_array_equal(both[1], plain_soft_histogram(mirror, codebook))
    np.testing.assert_array_equal(soft_histogram(mirror, codebook), both[1])
    np.testing.assert_array_equal(soft_histograms([mirror], codebook, n_votes=3, total=1.0)[0],
                                  plain_soft_histogram(mirror, codebook, 3, 1.0))


def test_soft_histograms_refuse_unequal_or_mismatched_contexts(codebook):
    with pytest.raises(CodebookError, match="the same N"):
        soft_histograms((np.full((5, 60), 1 / 60), np.full((4, 60), 1 / 60)), codebook)
    with pytest.raises(CodebookError, match=r"\(N, 60\)"):
        soft_histogram(np.full((5, 59), 1 / 59), codebook)


def test_mirrored_bins_are_made_once_and_read_only():
    order = mirrored_bins(12, 5)
    assert order is mirrored_bins(12, 5)
    assert not order.flags.writeable


def test_edge_points_of_bool_masks_equal_those_of_integer_masks():
    mask = np.zeros((90, 60), np.uint8)
    cv2.ellipse(mask, (30, 45), (18, 38), 10, 0, 360, 255, -1)
    cv2.circle(mask, (30, 40), 6, 0, -1)                 # a hole
    as_bool = mask.astype(bool)
    for holes in (False, True):
        np.testing.assert_array_equal(sample_edge_points(as_bool, 120, holes),
                                      sample_edge_points(mask, 120, holes))
        np.testing.assert_array_equal(sample_edge_points(as_bool[:, ::-1], 120, holes),
                                      sample_edge_points(mask[:, ::-1].copy(), 120, holes))
    assert as_bool.sum() == np.count_nonzero(mask)      # the input is left as it was


def test_streamed_stacks_are_independent_copies():
    X = np.arange(14.0).reshape(7, 2)
    for k, step in ((1, 1), (3, 1), (2, 3)):
        stacker = FrameStacker(k, step)
        streamed = [stacker.push(x) for x in X]
        np.testing.assert_array_equal(np.array(streamed), stack_frames(X, k, step=step))


def plain_layout(mask, grid):
    """silhouette_layout's steps written directly (bounding box from row / column any())."""
    m = np.asarray(mask)
    rows, cols = np.flatnonzero(m.any(axis=1)), np.flatnonzero(m.any(axis=0))
    crop = m[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1] != 0
    h, w = crop.shape
    side = max(h, w)
    square = np.zeros((side, side), np.float32)
    square[(side - h) // 2:(side - h) // 2 + h, (side - w) // 2:(side - w) // 2 + w] = crop
    return cv2.resize(square, (grid, grid), interpolation=cv2.INTER_AREA).astype(np.float64).ravel()


def test_layouts_of_bool_views_and_integer_masks_equal_the_plain_formulation():
    mask = np.zeros((70, 90), np.uint8)
    cv2.ellipse(mask, (40, 30), (12, 25), 20, 0, 360, 7, -1)
    for m in (mask.astype(bool), mask.astype(bool)[:, ::-1], mask.astype(bool)[::-1, 5:],
              mask, mask.astype(np.int64)[:, ::-1] * -3, mask.astype(np.float32)):
        for grid in (16, 5):
            np.testing.assert_array_equal(silhouette_layout(m, grid), plain_layout(m, grid))
