"""Silhouette descriptor: edge sampling, shape contexts, soft histograms, invariances, errors."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from regressor.codebook import Codebook, CodebookError, soft_histogram
from regressor.descriptor import (DescriptorSettings, DescriptorSettingsError, descriptor_for_mask,
                                  mask_contexts)
from regressor.descriptor_batch import descriptors_for_masks
from regressor.model_writer import settings_arrays
from regressor.training import fit_codebook_for_masks
from regressor.edges import DegenerateSilhouetteError, SilhouetteError, sample_edge_points
from regressor.shape_context import shape_contexts

SETTINGS = DescriptorSettings()


def person_mask(height: int = 240, arm_deg: float = 70.0, leg_deg: float = 15.0) -> np.ndarray:
    """A person-like uint8 silhouette (height, 0.75 height): head, torso, legs apart, the right
    arm (image left) hanging and the left arm raised by arm_deg, so it is not mirror-symmetric."""
    h = float(height)
    mask = np.zeros((height, int(0.75 * h)), np.uint8)
    cx = mask.shape[1] / 2

    def limb(start, angle_deg, length, width):
        a = math.radians(angle_deg)
        end = (start[0] + length * math.sin(a), start[1] + length * math.cos(a))
        cv2.line(mask, (int(start[0]), int(start[1])), (int(end[0]), int(end[1])), 1, int(width))
        return end

    cv2.ellipse(mask, (int(cx), int(0.07 * h)), (int(0.045 * h), int(0.06 * h)), 0, 0, 360, 1, -1)
    cv2.ellipse(mask, (int(cx), int(0.30 * h)), (int(0.08 * h), int(0.17 * h)), 0, 0, 360, 1, -1)
    limb(limb((cx - 0.07 * h, 0.17 * h), -10, 0.15 * h, 0.045 * h), -5, 0.14 * h, 0.035 * h)
    limb(limb((cx + 0.07 * h, 0.17 * h), 180 - arm_deg, 0.15 * h, 0.045 * h), 150, 0.14 * h, 0.035 * h)
    for side in (-1, 1):
        knee = limb((cx + side * 0.04 * h, 0.45 * h), side * leg_deg, 0.24 * h, 0.06 * h)
        limb(knee, side * 5, 0.25 * h, 0.05 * h)
    return mask


def training_masks() -> list[np.ndarray]:
    """A small varied set of silhouettes to fit a test codebook on."""
    return [person_mask(240, arm, leg) for arm in (10, 40, 70, 100, 130, 160) for leg in (2, 10, 20, 30)]


@pytest.fixture(scope="module")
def codebook() -> Codebook:
    return fit_codebook_for_masks(training_masks(), SETTINGS, n_centres=100, seed=0)


def mass_moved(a: np.ndarray, b: np.ndarray, total: float = SETTINGS.total) -> float:
    """Fraction of the histogram mass that differs between two descriptors (0 = same, 1 = disjoint)."""
    return 0.5 * float(np.abs(a - b).sum()) / total


def reference_shape_contexts(points, n_angular=12, n_radial=5, r_inner=0.125, r_outer=3.0):
    """Plain-loop shape contexts written straight from the definition, to check the vectorized one."""
    n = len(points)
    rms = math.sqrt(sum(((points[i] - points[j]) ** 2).sum() for i in range(n) for j in range(n) if i != j) / (n * (n - 1)))
    edges = [r_inner * rms * (r_outer / r_inner) ** (k / n_radial) for k in range(n_radial + 1)]
    out = np.zeros((n, n_radial * n_angular))
    for i in range(n):
        for j in range(n):
            if i == j:
                continue
            dx, dy_up = points[j, 0] - points[i, 0], points[i, 1] - points[j, 1]
            sector = int((math.degrees(math.atan2(dy_up, dx)) % 360) // (360 / n_angular))
            r = math.hypot(dx, dy_up)
            ring = min(max(sum(r >= e for e in edges) - 1, 0), n_radial - 1)
            out[i, ring * n_angular + sector] += 1
    return out / (n - 1)


# --- edge sampling -------------------------------------------------------------------------------


def test_edge_points_are_equally_spaced_on_the_boundary():
    mask = np.zeros((200, 200), np.uint8)
    cv2.circle(mask, (100, 100), 60, 1, -1)
    pts = sample_edge_points(mask, n_points=300)
    assert pts.shape == (300, 2)
    radius = np.hypot(pts[:, 0] - 100, pts[:, 1] - 100)
    assert np.all(np.abs(radius - 60) < 1.5)  # on the rim, not inside
    steps = np.hypot(*np.diff(np.vstack([pts, pts[:1]]), axis=0).T)
    assert steps.std() / steps.mean() < 0.1
    assert abs(steps.sum() - 2 * math.pi * 60) < 0.1 * 2 * math.pi * 60


def test_edge_points_follow_the_largest_silhouette_only():
    mask = np.zeros((200, 300), np.uint8)
    cv2.rectangle(mask, (20, 20), (120, 180), 1, -1)
    cv2.rectangle(mask, (200, 50), (220, 70), 1, -1)  # a small second blob: ignored
    pts = sample_edge_points(mask, n_points=200)
    assert pts[:, 0].max() <= 121 and pts[:, 0].min() >= 19


def test_edge_points_of_a_silhouette_touching_the_image_border():
    mask = np.ones((50, 30), np.uint8)
    pts = sample_edge_points(mask, n_points=100)
    assert pts[:, 0].min() == 0 and pts[:, 0].max() == 29 and pts[:, 1].max() == 49


def test_include_holes_adds_points_on_the_hole_boundary():
    mask = np.zeros((200, 200), np.uint8)
    cv2.circle(mask, (100, 100), 80, 1, -1)
    cv2.circle(mask, (100, 100), 30, 0, -1)
    r_outer_only = np.hypot(*(sample_edge_points(mask, 200) - 100).T)
    r_with_holes = np.hypot(*(sample_edge_points(mask, 200, include_holes=True) - 100).T)
    assert np.all(r_outer_only > 75)
    inner = r_with_holes < 40
    assert 40 < inner.sum() < 80  # shared by length: 30 / (30 + 80) of 200 is about 55


# --- shape contexts ------------------------------------------------------------------------------


def test_shape_contexts_match_a_plain_loop_reference():
    rng = np.random.default_rng(3)
    points = rng.random((40, 2)) * np.array([80.0, 200.0]) + 500.0
    np.testing.assert_allclose(shape_contexts(points), reference_shape_contexts(points), atol=1e-12)


@pytest.mark.parametrize("n_angular, n_radial", [(7, 3), (8, 5), (1, 2)])
def test_other_sector_and_ring_counts_match_the_plain_loop_reference(n_angular, n_radial):
    """The sectors' wrap-around folded on the pairs (before counting) for any sector count,
    odd ones and a single sector too."""
    rng = np.random.default_rng(4)
    points = rng.random((30, 2)) * np.array([60.0, 150.0])
    np.testing.assert_allclose(shape_contexts(points, n_angular, n_radial),
                               reference_shape_contexts(points, n_angular, n_radial), atol=1e-12)


def test_each_context_sums_to_one():
    contexts = mask_contexts(person_mask(), SETTINGS)
    assert contexts.shape == (SETTINGS.n_points, 60)
    np.testing.assert_allclose(contexts.sum(axis=1), 1.0, rtol=0, atol=1e-12)


def test_angles_keep_the_scene_vertical():
    # Point 1 straight above point 0 in the image (smaller row): from point 0 it lies at 90 degrees
    # (sector 3 of 12), and point 0 at 270 degrees (sector 9) from point 1.
    points = np.array([[0.0, 10.0], [0.0, 0.0]])
    ctx = shape_contexts(points)
    assert ctx[0].argmax() % 12 == 3 and ctx[1].argmax() % 12 == 9


# --- descriptor ----------------------------------------------------------------------------------


def test_descriptor_sums_to_the_fixed_total_and_is_finite(codebook):
    d = descriptor_for_mask(person_mask(), SETTINGS, codebook)
    assert d.shape == (100,)
    assert np.all(np.isfinite(d)) and np.all(d >= 0)
    assert d.sum() == pytest.approx(100.0, rel=1e-12)


def test_descriptor_is_deterministic(codebook):
    mask = person_mask(240, 55, 12)
    assert np.array_equal(descriptor_for_mask(mask, SETTINGS, codebook), descriptor_for_mask(mask.copy(), SETTINGS, codebook))


def test_translation_invariance(codebook):
    mask = person_mask()
    canvas = np.zeros((700, 900), np.uint8)
    canvas[333 : 333 + mask.shape[0], 411 : 411 + mask.shape[1]] = mask
    # Same boundary pixels, shifted: the descriptor must not move at all (beyond rounding).
    assert mass_moved(descriptor_for_mask(mask, SETTINGS, codebook), descriptor_for_mask(canvas, SETTINGS, codebook)) < 1e-6


def test_scale_invariance(codebook):
    mask = person_mask(240, 100, 20)
    double = cv2.resize(mask, None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST)
    moved = mass_moved(descriptor_for_mask(mask, SETTINGS, codebook), descriptor_for_mask(double, SETTINGS, codebook))
    # Measured about 0.04. Without scale normalization every distance doubles, shifting all
    # contexts by about one ring, which moves well over a third of the mass.
    assert moved < 0.1


def test_upside_down_and_mirrored_silhouettes_differ_clearly(codebook):
    mask = person_mask(240, 100, 20)
    d = descriptor_for_mask(mask, SETTINGS, codebook)
    double = cv2.resize(mask, None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST)
    scale_change = mass_moved(d, descriptor_for_mask(double, SETTINGS, codebook))
    for flipped in (mask[::-1], mask[:, ::-1]):
        moved = mass_moved(d, descriptor_for_mask(flipped, SETTINGS, codebook))
        assert moved > 0.3 and moved > 4 * scale_change


def test_descriptors_for_masks_matches_single_calls_and_reports_progress(codebook):
    masks = [person_mask(240, a, 10) for a in (20, 90, 150)]
    seen = []
    batch = descriptors_for_masks(iter(masks), SETTINGS, codebook, progress=seen.append)
    assert batch.shape == (3, 100)
    for row, mask in zip(batch, masks):
        assert np.array_equal(row, descriptor_for_mask(mask, SETTINGS, codebook))
    assert seen == [1, 2, 3]


def test_descriptors_for_masks_names_the_degenerate_mask(codebook):
    masks = [person_mask(), np.zeros((50, 50), np.uint8), person_mask()]
    with pytest.raises(DegenerateSilhouetteError, match="mask 1"):
        descriptors_for_masks(masks, SETTINGS, codebook)


def test_codebook_that_does_not_match_the_settings_is_refused(codebook):
    with pytest.raises(CodebookError, match="columns"):
        descriptor_for_mask(person_mask(), DescriptorSettings(n_angular=8), codebook)


# --- soft votes ----------------------------------------------------------------------------------


def test_soft_votes_follow_gaussian_weights_on_the_nearest_centres():
    centres = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 2.0], [5.0, 5.0]])
    book = Codebook(centres, sigma=1.0)
    hist = soft_histogram(np.array([[0.0, 0.0]]), book, n_votes=3, total=1.0)
    w = np.exp(-np.array([0.0, 1.0, 4.0]) / 2.0)
    np.testing.assert_allclose(hist, np.append(w / w.sum(), 0.0), atol=1e-12)


def test_one_vote_is_a_hard_assignment_scaled_to_the_total(codebook):
    contexts = mask_contexts(person_mask(), SETTINGS)
    hist = soft_histogram(contexts, codebook, n_votes=1, total=100.0)
    nearest = ((contexts[:, None, :] - codebook.centres[None]) ** 2).sum(axis=2).argmin(axis=1)
    np.testing.assert_allclose(hist, np.bincount(nearest, minlength=100) * 100.0 / len(contexts), atol=1e-9)


@pytest.mark.parametrize("n_votes", [1, 3, 5, 100])
def test_soft_votes_sum_to_the_fixed_total(codebook, n_votes):
    hist = soft_histogram(mask_contexts(person_mask(), SETTINGS), codebook, n_votes=n_votes, total=100.0)
    assert hist.sum() == pytest.approx(100.0, rel=1e-12)


def test_far_contexts_do_not_underflow_to_nan():
    book = Codebook(np.array([[0.0], [1.0]]), sigma=1e-3)
    hist = soft_histogram(np.array([[1000.0]]), book, n_votes=2, total=100.0)
    assert np.all(np.isfinite(hist)) and hist.sum() == pytest.approx(100.0)


# --- bad input -----------------------------------------------------------------------------------


def _line(thickness: int, diagonal: bool) -> np.ndarray:
    mask = np.zeros((200, 200), np.uint8)
    end = (180, 180) if diagonal else (180, 100)
    cv2.line(mask, (20, 100 if not diagonal else 20), end, 1, thickness)
    return mask


@pytest.mark.parametrize(
    "mask, message",
    [
        (np.zeros((100, 80), np.uint8), "empty"),
        (np.pad(np.ones((2, 1), bool), 5), "fewer than"),
        (_line(1, diagonal=False), "line"),
        (_line(1, diagonal=True), "line"),
        (_line(3, diagonal=False), "line"),
    ],
    ids=["empty", "three-pixels", "horizontal-line", "diagonal-line", "thick-line"],
)
def test_degenerate_masks_raise(mask, message, codebook):
    with pytest.raises(DegenerateSilhouetteError, match=message):
        descriptor_for_mask(mask, SETTINGS, codebook)


@pytest.mark.parametrize("mask", [np.ones((4, 4, 3), np.uint8), np.ones((20, 20), np.float32)], ids=["3-d", "float"])
def test_malformed_masks_raise(mask, codebook):
    with pytest.raises(SilhouetteError):
        descriptor_for_mask(mask, SETTINGS, codebook)


def test_small_but_real_silhouette_is_accepted(codebook):
    mask = np.zeros((20, 20), bool)
    mask[5:13, 7:12] = True
    assert np.all(np.isfinite(descriptor_for_mask(mask, SETTINGS, codebook)))


# --- settings storage ----------------------------------------------------------------------------


def test_settings_round_trip_through_npz(tmp_path):
    settings = DescriptorSettings(n_points=250, include_holes=True, r_outer=2.5, n_votes=4)
    np.savez(tmp_path / "s.npz", **settings_arrays(settings))
    with np.load(tmp_path / "s.npz", allow_pickle=False) as stored:
        assert DescriptorSettings.from_arrays(stored) == settings


def test_bad_settings_are_refused():
    with pytest.raises(DescriptorSettingsError, match="r_inner"):
        DescriptorSettings(r_inner=2.0, r_outer=1.0)
    arrays = settings_arrays(DescriptorSettings())
    del arrays["descriptor_n_votes"]
    with pytest.raises(DescriptorSettingsError, match="descriptor_n_votes"):
        DescriptorSettings.from_arrays(arrays)


@pytest.mark.parametrize("name, value", [
    ("descriptor_include_holes", np.str_("False")), ("descriptor_include_holes", np.int64(2)),
    ("descriptor_n_points", np.float64(300.7)), ("descriptor_n_votes", np.str_("5")),
    ("descriptor_r_outer", np.str_("3.0"))])
def test_stored_settings_of_the_wrong_kind_are_refused(name, value):
    """bool("False") is True and int(300.7) 300: a tampered file had been misread silently."""
    arrays = {**settings_arrays(DescriptorSettings()), name: value}
    with pytest.raises(DescriptorSettingsError, match=f"{name} must be"):
        DescriptorSettings.from_arrays(arrays)


def test_a_bad_r_outer_is_named_as_such():
    with pytest.raises(DescriptorSettingsError, match=r"r_outer=0.01 is out of range \(it must "
                                                      r"exceed r_inner=0.125"):
        DescriptorSettings(r_outer=0.01)
