"""Mixture of experts (regressor.mixture): known modes, the gate, model files, video-like masks."""
from __future__ import annotations

import numpy as np
import pytest

from regressor.codebook import Codebook
from regressor.descriptor import DescriptorSettings
from regressor.mixture import DampedKernelRegressor, MixtureRegressor, SoftmaxGate
from regressor.mixture_fit import kmeans
from regressor.neighbour_gate import NeighbourGate
from regressor.optional_parts import (gives_variance, predict_batch, predict_limbs,
                                      predict_variance)
from regressor.pose_model import PoseModel, PoseModelError, load_pose_model
from regressor.model_writer import save_pose_model
from regressor.sparse_rvm import SparseRVMRegressor

SMALL = dict(n_centres=40, gate_centres=30, gate_l2=1e-2, overlap=0.0)


def _two_modes(n=1200, seed=0):
    """Descriptors x (n, 6) that say nothing about which of two poses (front / back) made
    them, plus one output that x does determine."""
    rng = np.random.default_rng(seed)
    x = rng.normal(0, 1, (n, 6))
    mode = rng.integers(0, 2, n)
    y = np.column_stack([np.where(mode == 1, 3.0, -3.0), np.sin(x[:, 1])])
    return x, y, mode


def test_two_poses_with_one_descriptor_give_both_hypotheses_near_half():
    x, y, _ = _two_modes()
    mix = MixtureRegressor(n_experts=2, **{**SMALL, "gate_l2": 0.1}).fit(x, y)
    x = _two_modes(seed=9)[0]                        # new silhouettes
    poses, prob = mix.predict_hypotheses(x[:50], 2)
    assert poses.shape == (50, 2, 2) and prob.shape == (50, 2)
    np.testing.assert_allclose(prob.sum(axis=1), 1.0)
    assert np.all(np.abs(prob - 0.5) < 0.15)
    # The two hypotheses are the two poses, not their average.
    np.testing.assert_allclose(np.sort(poses[:, :, 0], axis=1), [[-3.0, 3.0]] * 50, atol=0.3)
    # Each expert still follows the part of the pose the descriptor determines.
    assert np.corrcoef(poses[:, 0, 1], np.sin(x[:50, 1]))[0, 1] > 0.8
    # predict() is the most probable hypothesis.
    np.testing.assert_allclose(mix.predict(x[:50]), poses[:, 0])


def test_distinct_descriptors_pick_their_expert():
    rng = np.random.default_rng(1)
    mode = rng.integers(0, 3, 1500)
    x = rng.normal(0, 0.3, (1500, 4)) + np.eye(4)[mode] * 3.0
    y = np.column_stack([mode * 10.0 + x[:, 0], np.cos(x[:, 1])])
    mix = MixtureRegressor(n_experts=3, **SMALL).fit(x, y)
    poses, prob = mix.predict_hypotheses(x, 3)
    assert np.mean(prob[:, 0] > 0.9) > 0.95
    assert np.abs(mix.predict(x)[:, 0] - y[:, 0]).mean() < 0.5


def test_gate_learns_separable_classes_and_is_a_distribution():
    rng = np.random.default_rng(2)
    labels = rng.integers(0, 4, 800)
    x = rng.normal(0, 0.5, (800, 3)) + np.array([[0, 0, 0], [4, 0, 0], [0, 4, 0], [0, 0, 4]])[labels]
    gate = SoftmaxGate(n_centres=20, l2=1e-3).fit(x, labels, n_classes=4)
    P = gate.predict_proba(x)
    assert P.shape == (800, 4) and np.allclose(P.sum(axis=1), 1) and np.all(P >= 0)
    assert (gate.predict(x) == labels).mean() > 0.97


def test_neighbour_gate_gives_the_shares_of_the_nearest_rows_classes():
    x = np.array([[0.0], [1.0], [2.0], [10.0], [11.0]])
    gate = NeighbourGate(n_neighbours=3).fit(x, [0, 0, 1, 2, 2], n_classes=4)
    P = gate.predict_proba(np.array([[0.4], [10.6], [1.6]]))
    np.testing.assert_allclose(P, [[2 / 3, 1 / 3, 0, 0], [0, 1 / 3, 2 / 3, 0],
                                   [2 / 3, 1 / 3, 0, 0]], atol=1e-5)
    # A tie (one vote each) goes to the nearer neighbour's class.
    one_each = NeighbourGate(n_neighbours=2).fit(x, [0, 1, 1, 2, 2])
    assert one_each.predict(np.array([[0.4], [0.6]])).tolist() == [0, 1]
    # Chunked distances give the same answer.
    q = np.random.default_rng(0).uniform(-1, 12, (50, 1))
    np.testing.assert_array_equal(NeighbourGate(3, chunk_rows=7).fit(x, [0, 0, 1, 2, 2])
                                  .predict_proba(q), gate.predict_proba(q)[:, :3])
    with pytest.raises(ValueError, match="n_neighbours"):
        NeighbourGate(n_neighbours=6).fit(x, [0, 0, 1, 2, 2])


def test_prototype_gate_keeps_centres_that_vote_with_their_rows_classes():
    """With prototypes P the gate stores P k-means centres, not the rows; each centre votes
    with the classes of the rows nearest it, so a query near a cluster gets its class mix."""
    rng = np.random.default_rng(2)
    centres = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    x = np.repeat(centres, 40, axis=0) + rng.normal(0, 0.1, (120, 2))
    labels = np.repeat([0, 1, 2], 40)
    labels[40:50] = 0                                   # cluster 1 is a quarter class 0
    gate = NeighbourGate(n_neighbours=1, prototypes=3).fit(x, labels, n_classes=4)
    assert gate.X_.shape == (3, 2) and gate.counts_.sum() == 120
    P = gate.predict_proba(np.array([[0.2, 0.1], [9.8, 0.3], [0.1, 9.7]]))
    np.testing.assert_allclose(P, [[1, 0, 0, 0], [0.25, 0.75, 0, 0], [0, 0, 1, 0]], atol=1e-5)
    mix = MixtureRegressor(n_experts=3, gate="neighbours", gate_prototypes=3, gate_neighbours=1,
                           **SMALL).fit(x, np.column_stack([labels * 1.0, x[:, 0]]))
    assert len(mix.gate_.X_) == 3
    with pytest.raises(ValueError, match="prototypes"):
        NeighbourGate(prototypes=500).fit(x, labels)


def test_neighbour_gated_mixture_keeps_both_modes_and_picks_distinct_experts():
    x, y, _ = _two_modes()
    mix = MixtureRegressor(n_experts=2, gate="neighbours", gate_neighbours=200,
                           **SMALL).fit(x, y)
    poses, prob = mix.predict_hypotheses(_two_modes(seed=9)[0][:50], 2)
    assert np.all(np.abs(prob - 0.5) < 0.15)
    np.testing.assert_allclose(np.sort(poses[:, :, 0], axis=1), [[-3.0, 3.0]] * 50, atol=0.3)
    rng = np.random.default_rng(1)
    mode = rng.integers(0, 3, 1500)
    x = rng.normal(0, 0.3, (1500, 4)) + np.eye(4)[mode] * 3.0
    y = np.column_stack([mode * 10.0 + x[:, 0], np.cos(x[:, 1])])
    mix = MixtureRegressor(n_experts=3, gate="neighbours", **SMALL).fit(x, y)
    assert isinstance(mix.gate_, NeighbourGate)
    assert np.abs(mix.predict(x)[:, 0] - y[:, 0]).mean() < 0.5
    with pytest.raises(ValueError, match="gate must be one of"):
        MixtureRegressor(gate="nearest").fit(x, y)


def test_a_sequence_keeps_the_pose_its_clear_frames_showed():
    from lab.evaluation import mixture_path
    """Descriptors that settle the mode only when x0 > 1.5 (else either pose): per frame the
    gate guesses on the ambiguous frames, the most probable chain keeps the mode the clear
    frames showed, and without continuity it is the per-frame answer."""
    rng = np.random.default_rng(3)
    x = rng.normal(0, 1, (2000, 3))
    mode = np.where(x[:, 0] > 1.5, 1, rng.integers(0, 2, 2000))
    y = np.column_stack([np.where(mode == 1, 3.0, -3.0), np.sin(x[:, 1])])
    mix = MixtureRegressor(n_experts=2, gate="neighbours", gate_neighbours=20,
                           **SMALL).fit(x, y)
    T = 60
    seq = np.column_stack([np.where(np.arange(T) < 5, 2.5, rng.uniform(-1, 1, T)),
                           np.linspace(-1, 1, T), rng.normal(0, 1, T)])
    per_frame = mix.predict(seq)[:, 0]
    assert np.mean(per_frame[5:] < 0) > 0.2                 # the gate guesses
    step_var = float(np.mean(np.diff(np.sin(seq[:, 1])) ** 2))
    path = mixture_path(mix, seq, step_var)
    np.testing.assert_allclose(path[:, 0], 3.0, atol=0.3)    # the mode frames 0-4 showed
    np.testing.assert_allclose(mixture_path(mix, seq, step_var, continuity=0.0),
                               mix.predict(seq))


def test_estimator_conventions():
    mix = MixtureRegressor(n_experts=3, lam=0.5)
    assert mix.get_params()["lam"] == 0.5 and not hasattr(mix, "gate_")
    assert mix.set_params(n_experts=4) is mix and mix.n_experts == 4
    with pytest.raises(ValueError, match="not fitted"):
        mix.predict(np.zeros((1, 3)))
    x = np.random.default_rng(3).normal(size=(200, 3))
    reg = DampedKernelRegressor(n_centres=20)
    assert reg.fit(x, x[:, 0] ** 2) is reg and reg.predict(x).shape == (200,)
    assert kmeans(x, 5).shape == (5, 3)


def test_sparse_rvm_experts_give_each_pose_a_spread_and_the_mean_the_hypotheses_spread():
    x, y, _ = _two_modes()
    mix = MixtureRegressor(n_experts=2, expert="sparse_rvm", width_scale=1.0,
                           **{**SMALL, "gate_l2": 0.1, "n_centres": 30}).fit(x, y)
    new = _two_modes(seed=9)[0][:50]
    pose, std = mix.predict(new, return_std=True)            # the most probable expert's
    assert pose.shape == std.shape == (50, 2)
    assert np.all(np.abs(np.abs(pose[:, 0]) - 3.0) < 0.3) and np.all(std[:, 0] < 0.3)
    mean, spread = mix.set_params(combine="mean").predict(new, return_std=True)
    # Two equally likely poses +-3: the mixture's mean is near 0, its spread near 3.
    assert np.all(np.abs(mean[:, 0]) < 1.0) and np.all(np.abs(spread[:, 0] - 3.0) < 0.3)
    np.testing.assert_array_equal(mean, mix.predict(new))


def test_return_std_needs_experts_with_a_variance_and_combine_is_checked():
    x, y, _ = _two_modes(n=300)
    ridge = MixtureRegressor(n_experts=2, **SMALL).fit(x, y)
    with pytest.raises(ValueError, match="expert='sparse_rvm'"):
        ridge.predict(x, return_std=True)
    with pytest.raises(ValueError, match="combine"):
        MixtureRegressor(n_experts=2, combine="median", **SMALL).fit(x, y)


def _mixture_model(k=2, D=4, **gate):
    rng = np.random.default_rng(4)
    x = rng.normal(0, 1, (600, k * D))
    y = np.column_stack([np.cos(x[:, 0]), np.sin(x[:, 0]), 10 * rng.normal(size=(600, 53))])
    y[:, 2:] += 20 * np.sin(x[:, 1:2])
    mix = MixtureRegressor(n_experts=3, **SMALL, **gate).fit(x, y)
    settings = DescriptorSettings()
    model = PoseModel(settings=settings, codebook=Codebook(rng.random((D, settings.context_size)), 0.2),
                      stack_depth=k, transform="sqrt", basis="gaussian", width=None, centres=None,
                      relevance=np.zeros(0, np.int64), coef=np.zeros((0, 55)),
                      intercept=np.zeros(55), angle_centre_deg=rng.uniform(-20, 20, 53),
                      measurement_covariance=np.eye(54), process_noise=np.ones(54),
                      description={"source": "synthetic"}, mixture=mix)
    return model, x


def test_mixture_model_file_round_trip(tmp_path):
    model, x = _mixture_model()
    path = tmp_path / "mixture.npz"
    save_pose_model(path, model)
    loaded = load_pose_model(path)
    assert loaded.mixture is not None and len(loaded.mixture.experts_) == 3
    # Centres are stored as float16, weights as float32: predictions agree closely.
    a, b = predict_batch(loaded, x[:20]), predict_batch(model, x[:20])
    assert np.abs(a - b).max() < 0.02 * np.abs(b).max()
    w0 = model.hypotheses(x[:20], 2).probabilities
    w1 = loaded.hypotheses(x[:20], 2).probabilities
    np.testing.assert_allclose(w1, w0, atol=1e-2)
    assert loaded.summary()["basis"] == "mixture" and loaded.description["source"] == "synthetic"


def test_sparse_rvm_experts_round_trip_with_their_variance(tmp_path):
    from regressor.describe import describe_model
    model, x = _mixture_model(expert="sparse_rvm")
    path = tmp_path / "rvm.npz"
    save_pose_model(tmp_path / "plain.npz", model)   # without its variance: a smaller file
    plain = load_pose_model(tmp_path / "plain.npz")
    assert not gives_variance(plain)
    assert all(isinstance(e, SparseRVMRegressor) for e in plain.mixture.experts_)
    np.testing.assert_allclose(predict_batch(plain, x[:20]), predict_batch(model, x[:20]),
                               atol=0.02 * np.abs(predict_batch(model, x[:20])).max())
    model.variance_calibration = 0.01
    save_pose_model(path, model)
    assert path.stat().st_size > (tmp_path / "plain.npz").stat().st_size
    loaded = load_pose_model(path)
    experts = describe_model(loaded)["regressor"]["experts"]
    kept = [len(e.relevance_) for e in model.mixture.experts_]
    assert [e["kind"] for e in experts] == ["rvm"] * 3
    assert [e["relevance_vectors"] for e in experts] == kept and max(kept) < SMALL["n_centres"]
    a, b = predict_batch(loaded, x[:20]), predict_batch(model, x[:20])
    assert np.abs(a - b).max() < 0.02 * np.abs(b).max()
    np.testing.assert_allclose(predict_variance(loaded, x[:20]), predict_variance(model, x[:20]),
                               rtol=1e-3)
    _, std = model.mixture.predict(x[:20], return_std=True)
    np.testing.assert_allclose(predict_variance(loaded, x[:20]), (std[:, 2:] ** 2).mean(1),
                               rtol=1e-3)
    assert loaded.variance_calibration == 0.01
    assert not gives_variance(_mixture_model()[0])                 # damped least squares


def test_a_broken_sparse_rvm_expert_part_is_refused_in_one_line(tmp_path):
    from regressor.model_file import load_model
    from regressor.model_writer import save_model
    model, _ = _mixture_model(expert="sparse_rvm")
    model.variance_calibration = 0.01
    path = tmp_path / "rvm.npz"
    save_pose_model(path, model)
    raw = dict(load_model(path).parts)
    assert_refused_when_changed(path, [
        ({"mixture_expert_sigma": raw["mixture_expert_sigma"][:-1]}, "variance parts do not"),
        ({"mixture_variance_calibration": np.float64(0.0)}, "calibration must be positive"),
        ({"mixture_expert_sigma": None}, "variance is incomplete"),
        ({"mixture_expert_beta": -raw["mixture_expert_beta"]}, "must be positive"),
        ({"mixture_expert_y_scale": None}, "incomplete"),
        ({"mixture_expert_kind": np.str_("ridge")}, "must be 'rvm'"),
        ({"mixture_expert_rows": 0 * raw["mixture_expert_rows"]}, "must be positive"),
        ({"mixture_params": raw["mixture_params"].item().replace("sparse_rvm", "ridge")},
         "holds sparse RVM experts")])
    for name in ("mixture_expert_kind", "mixture_expert_sigma", "mixture_expert_phi_mean",
                 "mixture_expert_beta", "mixture_expert_rows", "mixture_expert_y_scale"):
        save_model(path, {k: v for k, v in raw.items() if k != name})
        with pytest.raises(PoseModelError) as refused:
            load_pose_model(path)
        assert len(str(refused.value).splitlines()) == 1


def test_a_version_1_file_of_damped_least_squares_experts_still_loads(tmp_path):
    from regressor.model_file import checksum, load_model
    model, x = _mixture_model()
    path = tmp_path / "old.npz"
    save_pose_model(path, model)
    parts = dict(load_model(path).parts)
    np.savez(path, **parts, format_version=np.int64(1), checksum=np.str_(checksum(parts)))
    loaded = load_pose_model(path)
    assert load_model(path).format_version == 1 and not gives_variance(loaded)
    np.testing.assert_allclose(predict_batch(loaded, x[:5]), predict_batch(model, x[:5]),
                               atol=0.02 * np.abs(predict_batch(model, x[:5])).max())


def test_a_neighbour_gated_mixture_is_not_saved_into_a_model_file(tmp_path):
    model, _ = _mixture_model(gate="neighbours")
    with pytest.raises(PoseModelError, match="softmax gate"):
        save_pose_model(tmp_path / "mixture.npz", model)
    assert not (tmp_path / "mixture.npz").exists()


def test_tampered_mixture_file_is_refused(tmp_path):
    model, _ = _mixture_model()
    path = tmp_path / "mixture.npz"
    save_pose_model(path, model)
    with np.load(path, allow_pickle=False) as z:
        raw = {k: z[k] for k in z.files}
    raw["mixture_gate_weights"] = raw["mixture_gate_weights"] * 1.0001
    np.savez(path, **raw)
    with pytest.raises(PoseModelError, match="checksum"):
        load_pose_model(path)


def test_inconsistent_mixture_file_is_refused(tmp_path):
    from regressor.model_writer import save_model
    model, _ = _mixture_model()
    path = tmp_path / "mixture.npz"
    save_pose_model(path, model)
    with np.load(path, allow_pickle=False) as z:
        raw = {k: z[k] for k in z.files if k not in ("format_version", "checksum")}
    raw["mixture_expert_offsets"] = raw["mixture_expert_offsets"][:-1]   # re-checksummed
    save_model(path, raw)
    with pytest.raises(PoseModelError, match="expert offsets"):
        load_pose_model(path)


def _with_limb_head(model, x, seed=5):
    """The model's mixture refitted with a limb head as training does: partitioned on the
    inputs, one joint fit on [own targets, canonical members' targets] split back
    (lab.training.split_expert_outputs), the head's angles about non-zero centres.
    Returns (mixture, head, members: the head's regression targets (N, 55))."""
    from regressor.optional_parts import LimbHead
    from sequences.pose_conversions import canonical_member
    from regressor.training import split_expert_outputs
    rng = np.random.default_rng(seed)
    own = model.mixture.predict(x)
    members = canonical_member(own + np.concatenate([[0, 0], rng.normal(0, 1, 53)]),
                               np.eye(55)[0])
    joint = MixtureRegressor(n_experts=3, **SMALL).fit(x, np.hstack([own, members]), x)
    coef, intercept = split_expert_outputs(joint, 55)
    return joint, LimbHead(coef, intercept, rng.uniform(-30, 30, 53), np.eye(55)[0]), members


def test_a_joint_fit_splits_into_the_own_head_and_the_limb_head():
    """Ridge columns are independent and the experts' centres and gate depend on the inputs
    only, so the split joint fit is the plain fit plus a second head fitted on the members."""
    model, x = _mixture_model()
    joint, head, members = _with_limb_head(model, x)
    own = model.mixture.predict(x)
    plain = MixtureRegressor(n_experts=3, **SMALL).fit(x, own, x)
    np.testing.assert_allclose(joint.predict(x), plain.predict(x), atol=1e-8)
    assert joint.n_outputs_ == 55 and all(e.coef_.shape[1] == 55 for e in joint.experts_)
    alone = MixtureRegressor(n_experts=3, **SMALL).fit(x, members, x)
    offsets = np.cumsum([0] + [len(e.centres_) for e in alone.experts_])
    for e, expert in enumerate(alone.experts_):
        np.testing.assert_allclose(head.coef[offsets[e]:offsets[e + 1]], expert.coef_,
                                   atol=1e-6)
        np.testing.assert_allclose(head.expert_intercept[e], expert.intercept_, atol=1e-6)


def test_limb_head_round_trips_and_a_broken_one_is_refused(tmp_path):
    from regressor.angles import wrap_deg
    from regressor.model_file import load_model
    from regressor.model_writer import save_model
    model, x = _mixture_model()
    model.mixture, model.limb_head, members = _with_limb_head(model, x)
    assert predict_limbs(_mixture_model()[0], x[:3]) is None        # no head, no limbs
    # Each row's limbs: the head's own fit (the mixture fitted on the members alone, same
    # experts), its centres added.
    alone = MixtureRegressor(n_experts=3, **SMALL).fit(x, members, x)
    expected = alone.predict(x[:50])
    expected[:, 2:] = wrap_deg(expected[:, 2:] + model.limb_head.angle_centre_deg)
    np.testing.assert_allclose(predict_limbs(model, x[:50]), expected, atol=1e-6)
    # the tracker's one-pass call gives the limbs as the separate one does
    estimates = model.hypotheses(x[:50], 2)
    assert estimates.poses.shape == (50, 2, 55) and estimates.front is None
    np.testing.assert_array_equal(estimates.limbs, predict_limbs(model, x[:50]))
    path = tmp_path / "mixture.npz"
    save_pose_model(path, model)
    loaded = load_pose_model(path)
    np.testing.assert_allclose(loaded.limb_head.canonical_direction, np.eye(55)[0])
    a = predict_limbs(loaded, x[:50])                        # float16 centres, float32 weights
    assert a.shape == (50, 55)
    assert np.abs(wrap_deg(a[:, 2:] - expected[:, 2:])).max() < 0.02 * np.abs(members).max()
    raw = dict(load_model(path).parts)
    for broken, match in (({"limbs_coef": raw["limbs_coef"][:-1]}, "limb head shapes"),
                          ({"limbs_coef": None}, "limb head is incomplete"),
                          ({"limbs_expert_intercept": raw["limbs_expert_intercept"][:2]},
                           "limb head shapes"),
                          ({"limbs_canonical_direction": 2 * np.eye(55)[0]}, "unit vector"),
                          ({"canonical_direction": np.eye(55)[0]}, "takes no limb head")):
        parts = {k: v for k, v in {**raw, **broken}.items() if v is not None}
        save_model(path, parts)                                   # re-checksummed
        with pytest.raises(PoseModelError, match=match):
            load_pose_model(path)


def assert_refused_when_changed(path, cases) -> None:
    """For each (changes, match) in cases: the model file at path with its parts updated by
    changes (a part mapped to None is removed; re-checksummed, so only the model's own
    checks can refuse it) fails to load with a PoseModelError matching match."""
    from regressor.model_file import load_model
    from regressor.model_writer import save_model
    raw = dict(load_model(path).parts)
    for changes, match in cases:
        save_model(path, {k: v for k, v in {**raw, **changes}.items() if v is not None})
        with pytest.raises(PoseModelError, match=match):
            load_pose_model(path)


def assert_only_a_mixture_carries(tmp_path, attribute: str, value, parts: dict):
    """The single-RVM model with ``attribute`` set to ``value`` refuses to be saved, and its
    file with ``parts`` added refuses to load (both: "only a mixture")."""
    from regressor.model_file import load_model
    from regressor.model_writer import save_model
    from regressor.pose_model import DEFAULT_MODEL_PATH
    single = load_pose_model(DEFAULT_MODEL_PATH.parent / "per_frame_model.npz")
    setattr(single, attribute, value)
    with pytest.raises(PoseModelError, match="only a mixture"):
        save_pose_model(tmp_path / "single.npz", single)
    setattr(single, attribute, None)
    save_pose_model(tmp_path / "single.npz", single)
    raw = dict(load_model(tmp_path / "single.npz").parts)
    save_model(tmp_path / "single.npz", {**raw, **parts})
    with pytest.raises(PoseModelError, match="only a mixture"):
        load_pose_model(tmp_path / "single.npz")


def test_only_a_mixture_carries_a_limb_head(tmp_path):
    mixture, x = _mixture_model()
    _, head, _ = _with_limb_head(mixture, x)
    assert_only_a_mixture_carries(tmp_path, "limb_head", head,
                                  {"limbs_coef": np.zeros((3, 7), np.float32)})


def test_single_rvm_model_still_gives_one_hypothesis():
    from regressor.pose_model import DEFAULT_MODEL_PATH
    model = load_pose_model(DEFAULT_MODEL_PATH.with_name("per_frame_model.npz"))   # one RVM
    assert model.mixture is None
    x = np.full((2, model.stack_depth * model.descriptor_length), 0.5)
    estimates = model.hypotheses(x, 3)
    assert estimates.poses.shape == (2, 1, 55) and np.all(estimates.probabilities == 1)
    np.testing.assert_array_equal(estimates.poses[:, 0], predict_batch(model, x))
    assert estimates.limbs is None and estimates.front is None
    assert np.isnan(estimates.novelty).all()                      # no heading index


def test_mask_noise_is_reproducible_and_video_like():
    from sequences.mask_noise import MaskNoise, degrade
    mask = np.zeros((200, 120), bool)
    mask[20:180, 40:80] = True                       # a body
    mask[60:120, 25:40] = True                       # an arm, 0 px from it
    a = degrade(mask, np.random.default_rng(5), MaskNoise(height_px=(100, 100)))
    b = degrade(mask, np.random.default_rng(5), MaskNoise(height_px=(100, 100)))
    assert np.array_equal(a, b)
    assert 95 <= a.shape[0] <= 112                   # shrunk to ~100 px (dilated a little)


def test_training_masks_pass_through_the_trackers_own_cleaning():
    """lab.training.noisy_masks wires the extractor's cleaning into degrade: the
    crops are reproducible per row, person-sized, and a separate speck never survives as the
    person (the cleaning keeps the largest person)."""
    from lab.training import noisy_masks
    mask = np.zeros((224, 224), bool)
    mask[30:190, 90:130] = True                      # a body
    mask[70:130, 75:90] = True                       # an arm
    masks = np.stack([mask, mask])
    a, b = noisy_masks(masks, seed=3), noisy_masks(masks, seed=3)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not np.array_equal(a[0], a[1])            # each row its own noise
    for crop in a:
        assert crop.dtype == bool and 55 <= crop.shape[0] <= 160
        assert crop.mean() > 0.3                     # the body fills its box: not a speck


def test_experts_fitted_at_once_are_the_experts_fitted_in_turn():
    x, y, _ = _two_modes(n=400)
    one = MixtureRegressor(n_experts=3, expert="sparse_rvm", **SMALL).fit(x, y)
    two = MixtureRegressor(n_experts=3, expert="sparse_rvm", **SMALL).fit(x, y, workers=2)
    for a, b in zip(one.experts_, two.experts_):
        np.testing.assert_array_equal(a.relevance_, b.relevance_)
        np.testing.assert_allclose(a.coef_, b.coef_, rtol=1e-9)
    np.testing.assert_array_equal(one.expert_rows_, two.expert_rows_)
