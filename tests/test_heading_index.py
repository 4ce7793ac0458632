"""The nearest-neighbour heading (regressor.heading_index) and its place in a mixture model."""
from __future__ import annotations

import numpy as np
import pytest

from regressor.heading_index import HeadingIndex
from regressor.heading_index_training import build_heading_index, fold_heading_deg
from regressor.model_file import FORMAT_VERSION, ModelFileError, checksum, load_model
from regressor.pose_model import PoseModelError, load_pose_model
from regressor.model_writer import save_model, save_pose_model
from sequences.pose_vector import front_back_flip, heading_deg
from tests.test_mixture import _mixture_model


def test_fold_maps_a_heading_and_its_front_back_partner_to_one_value():
    h = np.linspace(-179.5, 180.0, 720)
    f = fold_heading_deg(h)
    assert np.all(np.abs(f) <= 90.0)
    np.testing.assert_allclose(f, fold_heading_deg(180.0 - h), atol=1e-9)
    # The partner is the front/back flip's heading (sequences.pose_vector).
    pose = np.zeros((len(h), 55))
    pose[:, 0], pose[:, 1] = np.cos(np.radians(h)), np.sin(np.radians(h))
    np.testing.assert_allclose(fold_heading_deg(heading_deg(front_back_flip(pose))), f, atol=1e-6)


def test_index_finds_the_folded_heading_of_nearby_training_rows():
    rng = np.random.default_rng(1)
    # Inputs that encode the folded heading (a circle in two components) plus noise columns.
    heading = rng.uniform(-180, 180, 4000)
    f = np.radians(fold_heading_deg(heading))
    X = np.column_stack([np.cos(2 * f), np.sin(2 * f), 0.01 * rng.normal(size=(4000, 3))])
    index = build_heading_index(X, heading, rows=3000, dims=2, k=9, limit_deg=45.0)
    assert index.inputs.shape == (3000, 2) and index.dims == 2
    query = np.radians(np.array([-40.0, -5.0, 30.0, 60.0]))
    Q = np.column_stack([np.cos(2 * query), np.sin(2 * query), np.zeros((4, 3))])
    folded = np.median(index.folded_deg[index._nearest(Q)[0]], axis=1)   # the k nearest rows'
    np.testing.assert_allclose(folded, np.degrees(query), atol=2.0)


def test_bad_index_settings_are_refused():
    with pytest.raises(ValueError, match="heading index"):
        build_heading_index(np.zeros((5, 3)), np.zeros(5), rows=5, dims=2, k=0)
    with pytest.raises(ValueError, match="heading index"):
        build_heading_index(np.zeros((5, 3)), np.zeros(5), rows=5, dims=2, k=3, limit_deg=120)


def _indexed_model():
    model, x = _mixture_model()
    heading = np.degrees(np.arctan2(np.sin(x[:, 0]), np.cos(x[:, 0])))
    model.heading_index = build_heading_index(x, heading, rows=400, dims=3, k=5,
                                              limit_deg=90.0)
    return model, x


def test_mixture_model_with_an_index_round_trips_and_its_poses_are_the_experts(tmp_path):
    """The index gives novelty only: the poses are the experts' own, index or not."""
    model, x = _indexed_model()
    poses = model.hypotheses(x[:30], 2).poses
    own = _mixture_model()[0].hypotheses(x[:30], 2).poses
    np.testing.assert_allclose(poses, own, atol=1e-9)
    assert np.all(np.isfinite(model.hypotheses(x[:30]).novelty))
    path = tmp_path / "indexed.npz"
    save_pose_model(path, model)
    loaded = load_pose_model(path)
    assert loaded.heading_index is not None and loaded.heading_index.k == 5
    np.testing.assert_allclose(loaded.heading_index.folded_deg, model.heading_index.folded_deg,
                               atol=1e-4)
    a = loaded.hypotheses(x[:30], 2).poses       # the file keeps some parts as float16
    assert np.abs(heading_deg(a[:, 0]) - heading_deg(poses[:, 0])).max() < 1.0


def test_a_broken_index_is_refused(tmp_path):
    model, _ = _indexed_model()
    path = tmp_path / "indexed.npz"
    save_pose_model(path, model)
    raw = {k: v for k, v in load_model(path).parts.items()}
    for broken, match in (({"heading_index_k": None}, "heading index is incomplete"),
                          ({"heading_index_inputs": raw["heading_index_inputs"][:, :0]},
                           "heading index shapes"),
                          ({"heading_index_folded_deg": raw["heading_index_folded_deg"][:-1]},
                           "heading index shapes"),
                          ({"heading_index_folded_deg": raw["heading_index_folded_deg"] + 200},
                           "within \\+-90"),
                          ({"heading_index_limit_deg": np.float64(0.0)}, "limit"),
                          ({"heading_index_k": np.int64(10**9)}, "k = 1000000000"),
                          ({"description": np.str_("[1, 2]")}, "must be a JSON object"),
                          ({"descriptor_n_points": np.int64(10**12)}, "n_points")):
        parts = {k: v for k, v in {**raw, **broken}.items() if v is not None}
        save_model(path, parts)                                    # re-checksummed
        with pytest.raises(PoseModelError, match=match):
            load_pose_model(path)


def test_only_a_mixture_carries_an_index(tmp_path):
    from regressor.pose_model import DEFAULT_MODEL_PATH
    single = load_pose_model(DEFAULT_MODEL_PATH.parent / "per_frame_model.npz")
    single.heading_index = HeadingIndex(np.zeros((3, 2)), np.zeros(3), 1)
    with pytest.raises(PoseModelError, match="only a mixture"):
        save_pose_model(tmp_path / "single.npz", single)
    single.heading_index = None
    save_pose_model(tmp_path / "single.npz", single)
    raw = dict(load_model(tmp_path / "single.npz").parts)
    save_model(tmp_path / "single.npz", {**raw, "heading_index_k": np.int64(3)})
    with pytest.raises(PoseModelError, match="only a mixture"):
        load_pose_model(tmp_path / "single.npz")


def test_long_queries_go_in_blocks_with_the_same_answer():
    rng = np.random.default_rng(3)
    index = HeadingIndex(rng.normal(size=(500, 4)), rng.uniform(-90, 90, 500), k=7)
    X = rng.normal(size=(700, 4))
    whole = index._nearest(X)[0]
    np.testing.assert_array_equal(whole[600:], index._nearest(X[600:])[0])
    with pytest.raises(ValueError, match="integer k"):
        HeadingIndex(np.zeros((3, 2)), np.zeros(3), 2.5)


def test_a_non_integer_k_in_a_file_is_refused(tmp_path):
    model, _ = _indexed_model()
    path = tmp_path / "indexed.npz"
    save_pose_model(path, model)
    raw = dict(load_model(path).parts)
    edited = {**raw, "heading_index_k": np.float64(2.7)}
    # Refused as saved, and as loaded when written by hand with a matching checksum.
    with pytest.raises(ModelFileError, match="heading_index_k is stored as float64"):
        save_model(path, edited)
    np.savez(path, **edited, format_version=np.int64(FORMAT_VERSION),
             checksum=np.str_(checksum(edited)))
    with pytest.raises(PoseModelError, match="heading_index_k is stored as float64"):
        load_pose_model(path)


def _leave_one_out_p99(rows: np.ndarray, k: int) -> float:
    """By brute force: the 99th percentile over rows of the mean distance to the k nearest
    other rows."""
    own = np.sqrt(((rows[:, None] - rows[None]) ** 2).sum(-1))
    np.fill_diagonal(own, np.inf)
    return float(np.percentile(np.sort(own, axis=1)[:, :k].mean(axis=1), 99))


def test_novelty_is_low_near_training_rows_and_high_far_from_them():
    """Novelty: mean distance to the k nearest training rows over the rows' own 99th
    percentile (each row left out of its own neighbours)."""
    rng = np.random.default_rng(4)
    rows = rng.normal(0, 1, (600, 4))
    index = HeadingIndex(rows, np.zeros(600), k=5)
    assert index.typical_distance() == pytest.approx(_leave_one_out_p99(rows, 5), rel=1e-4)
    near = rows[:50] + rng.normal(0, 0.01, (50, 4))
    far = rows[:50] + 6.0
    assert np.median(index.novelty(near)) < 0.7 and (index.novelty(far) > 1.5).all()
    np.testing.assert_allclose(index.distance(rows[:3]),
                               np.sort(np.sqrt(((rows[:3, None] - rows[None]) ** 2).sum(-1)),
                                       axis=1)[:, :5].mean(axis=1), rtol=1e-4, atol=1e-4)
    with pytest.raises(ValueError, match="4 input columns"):
        index.novelty(rows[:3, :2])


def test_a_model_reports_novelty_only_with_an_index():
    model, x = _indexed_model()
    n = model.hypotheses(x[:20]).novelty
    assert n.shape == (20,) and np.isfinite(n).all() and np.median(n) < 1.0
    assert (model.hypotheses(x[:20] + 50.0).novelty > 1.0).all()
    assert np.isnan(_mixture_model()[0].hypotheses(x[:5]).novelty).all()
    assert np.isnan(model.hypotheses(x[:5], novelty=False).novelty).all()    # not asked


def test_typical_distance_leaves_each_row_out_also_with_duplicates_and_few_rows():
    rows = np.repeat(np.random.default_rng(5).normal(0, 1, (40, 3)), 2, axis=0)  # each twice
    index = HeadingIndex(rows, np.zeros(80), k=3)
    assert index.typical_distance() == pytest.approx(_leave_one_out_p99(rows, 3), rel=1e-4)
    assert np.isnan(HeadingIndex(rows[:3], np.zeros(3), k=3).typical_distance())


def test_the_typical_distance_travels_with_the_model_file(tmp_path):
    """Saved as the index read back from the file computes it (float16 inputs), so loading
    does not recompute it; a file without it (before 2026-12-02) computes the same value."""
    model, x = _indexed_model()
    path = tmp_path / "indexed.npz"
    save_pose_model(path, model)
    raw = dict(load_model(path).parts)
    loaded = load_pose_model(path).heading_index
    fresh = HeadingIndex(loaded.inputs, loaded.folded_deg, loaded.k, loaded.limit_deg)
    assert float(raw["heading_index_typical_distance"]) == fresh.typical_distance()
    assert loaded._typical[(99.0, 2000)] == fresh.typical_distance()   # stored, not computed
    np.testing.assert_allclose(loaded.novelty(x[:10]), fresh.novelty(x[:10]), rtol=1e-12)
    save_model(path, {k: v for k, v in raw.items() if k != "heading_index_typical_distance"})
    older = load_pose_model(path).heading_index
    assert (99.0, 2000) not in older._typical
    assert older.typical_distance() == fresh.typical_distance()


def test_a_tampered_typical_distance_is_refused(tmp_path):
    """(NaN and infinite parts the model file itself refuses, for every part.)"""
    model, _ = _indexed_model()
    path = tmp_path / "indexed.npz"
    save_pose_model(path, model)
    raw = dict(load_model(path).parts)
    for value, match in ((np.float64(-1.0), "positive and finite"),
                         (np.float64(0.0), "positive and finite"),
                         (np.array([1.0, 2.0]), "one number"),
                         (np.float64(raw["heading_index_typical_distance"]) * 100, "implausible"),
                         (np.float64(raw["heading_index_typical_distance"]) / 100, "implausible"),
                         (np.int64(3), "one number")):
        save_model(path, {**raw, "heading_index_typical_distance": value})
        with pytest.raises(PoseModelError, match=match):
            load_pose_model(path)
    without_index = {k: v for k, v in raw.items()
                     if not k.startswith("heading_index_") or k.endswith("typical_distance")}
    save_model(path, without_index)
    with pytest.raises(PoseModelError, match="heading index is incomplete"):
        load_pose_model(path)


def test_a_small_index_without_a_typical_distance_still_saves_and_loads(tmp_path):
    model, x = _mixture_model()
    heading = np.degrees(np.arctan2(np.sin(x[:, 0]), np.cos(x[:, 0])))
    model.heading_index = build_heading_index(x, heading, rows=4, dims=3, k=5)
    save_pose_model(tmp_path / "small.npz", model)
    assert "heading_index_typical_distance" not in load_model(tmp_path / "small.npz").parts
    assert np.isnan(load_pose_model(tmp_path / "small.npz").hypotheses(x[:3]).novelty).all()


def test_novelty_distances_without_indices_are_the_neighbours_distances_bit_for_bit():
    """distance() partitions the values only (_nearest_d2): the same squared distances, in
    the same order, as the neighbour search, and the product as q @ rows' gives, for one
    query row (a matrix-vector product) and several, with a tie and with k = R."""
    rng = np.random.default_rng(8)
    rows = rng.normal(0, 1, (300, 6)).astype(np.float32)
    rows[7] = rows[3]                                           # a tie in distance
    index = HeadingIndex(rows, rng.uniform(-90, 90, 300), k=9)
    for n in (1, 2, 8, 300):
        q = rows[:n] + rng.normal(0, 0.1, (n, 6)).astype(np.float32)
        old = index._squared[None] - 2.0 * (q @ index.inputs.T)
        np.testing.assert_array_equal(index._partial_d2(q), old)
        np.testing.assert_array_equal(index._nearest_d2(q), index._nearest(q)[1])
    small = HeadingIndex(rows[:5], np.zeros(5), k=9)            # k above R: all rows
    np.testing.assert_array_equal(small._nearest_d2(rows[:3]), small._nearest(rows[:3])[1])
