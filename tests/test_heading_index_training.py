"""train_mixture_model builds the heading index, and the filter's R ignores it (synthetic data)."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from regressor.codebook import Codebook
from regressor.descriptor import DescriptorSettings
from regressor.stacking import stack_frames
from sequences.dataset import Dataset
from lab.training import train_mixture_model, validation_mask
from regressor.optional_parts import predict_batch, predict_limbs
from regressor.pose_model import frame_descriptors
from regressor.training import MixtureOptions, measurement_noise


def _dataset(seed=0):
    rng = np.random.default_rng(seed)
    trials = ["02_02", "08_03", "t1", "t2", "t3", "t4"]        # two validation trials
    n = 100
    heading = np.concatenate([np.cumsum(rng.normal(0, 4, n)) + rng.uniform(-180, 180)
                              for _ in trials])
    pose = np.zeros((len(heading), 55))
    pose[:, 0], pose[:, 1] = np.cos(np.radians(heading)), np.sin(np.radians(heading))
    pose[:, 2:] = rng.normal(0, 10, (len(heading), 53))
    # Histograms that say the heading (non-negative, as the sqrt transform needs).
    X = np.column_stack([1.2 + pose[:, 0], 1.2 + pose[:, 1], np.ones(len(heading)),
                         np.ones(len(heading))]) + rng.uniform(0, 0.05, (len(heading), 4))
    data = Dataset(masks=np.zeros((len(heading), 1, 1), bool), pose=pose,
                   sequence=np.repeat(np.arange(len(trials)), n),
                   frame=np.tile(np.arange(n), len(trials)),
                   azimuth_deg=np.zeros(len(heading)), elevation_deg=np.zeros(len(heading)),
                   trials=trials, trial_of_sequence=trials)
    settings = DescriptorSettings()
    codebook = Codebook(rng.random((4, settings.context_size)), 0.2)
    return data, X, codebook, settings


def _options(**kw):
    return MixtureOptions(n_experts=2, n_centres=20, gate_centres=20, layout_grid=0,
                          components=6, limb_head="none", heading_index_rows=150,
                          heading_index_dims=4, heading_index_k=5, **kw)


def test_training_builds_the_index_and_takes_R_from_the_experts_own_heading():
    data, X, codebook, settings = _dataset()
    model, _ = train_mixture_model(data, X, codebook, settings, _options(), 30.0,
                                        log=lambda m: None)
    index = model.heading_index
    assert index is not None and index.inputs.shape == (150, 4) and index.k == 5
    assert np.all(np.abs(index.folded_deg) <= 90)
    # R: the experts' own heading on the validation rows, not the index's.
    val = validation_mask(data)
    Xs = stack_frames(frame_descriptors(X, model.transform), model.stack_depth,
                      sequence_ids=data.sequence)[val]
    model.heading_index = None
    R, _ = measurement_noise(predict_batch(model, Xs), data.pose[val], 0.5)
    np.testing.assert_allclose(model.measurement_covariance, R)


def test_no_index_when_asked_and_none_without_a_projection():
    data, X, codebook, settings = _dataset()
    model, _ = train_mixture_model(data, X, codebook, settings,
                                   replace(_options(), heading_index_rows=0), 30.0,
                                   log=lambda m: None)
    assert model.heading_index is None
    with pytest.raises(ValueError, match="heading index"):
        train_mixture_model(data, X, codebook, settings, replace(_options(), components=0),
                            30.0, log=lambda m: None)


@pytest.mark.slow
def test_training_fits_limb_networks_instead_of_the_limb_head_when_asked():
    pytest.importorskip("sklearn")
    from sequences.pose_conversions import canonical_member
    data, X, codebook, settings = _dataset()
    logged = []
    model, report = train_mixture_model(
        data, X, codebook, settings,
        replace(_options(), limb_head="facing", limb_net_members=2, limb_net_hidden=(8,),
                limb_net_mirror=False),
        30.0, log=logged.append)
    assert model.limb_head is None and model.limb_net is not None
    assert len(model.limb_net.members) == 2 and model.limb_net.input_length == 6
    assert sum(m.startswith("  limb network ") for m in logged) == 2     # a line per network
    assert "validation_limb_head_at_true_heading" in report
    # the networks as the file holds them (int8): what that changed is reported, and a
    # file round trip changes nothing more
    assert 0 <= report["limb_net_int8_max_deg"] < 5
    from regressor.limb_net import LimbNet
    from regressor.model_writer import limb_net_arrays
    again = LimbNet.from_arrays(limb_net_arrays(model.limb_net))
    for a, b in zip(model.limb_net.members, again.members):
        for (W, _), (W2, _) in zip(a, b):
            np.testing.assert_array_equal(W, W2)
    # Its outputs are canonical members: headings facing the camera's half, as its targets.
    val = validation_mask(data)
    Xs = stack_frames(frame_descriptors(X, model.transform), model.stack_depth,
                      sequence_ids=data.sequence)
    limbs = predict_limbs(model, Xs)
    assert (limbs[:, 0] > 0).mean() > 0.9
    np.testing.assert_allclose(model.limb_net.canonical_direction, np.eye(55)[0])
    # ... and they follow the validation rows' canonical members better than their mean does
    members = canonical_member(data.pose[val], np.eye(55)[0])
    err = np.abs(limbs[val, 1] - members[:, 1]).mean()
    assert err < np.abs(members[:, 1] - members[:, 1].mean()).mean()
    # Without networks the experts' limb head as before (a head of dls experts' weights).
    plain, _ = train_mixture_model(data, X, codebook, settings,
                                   replace(_options(), limb_head="facing", expert="dls",
                                           limb_net_members=0), 30.0,
                                   log=lambda m: None)
    assert plain.limb_head is not None and plain.limb_net is None


def _capture_limb_net_fit(monkeypatch) -> dict:
    """Make regressor.training's fit_limb_net record the rows and targets it is given (in the dict
    returned) and then fit as usual."""
    import regressor.training as training
    seen = {}
    real_fit = training.fit_limb_net

    def fit(inputs, targets, *args, **kwargs):
        seen["inputs"], seen["targets"] = inputs, targets
        return real_fit(inputs, targets, *args, **kwargs)
    monkeypatch.setattr(training, "fit_limb_net", fit)
    return seen


def test_limb_networks_also_fit_every_training_rows_mirror_image(monkeypatch):
    """With limb_net_mirror the networks see each training row and its mirror image: the
    mirrored masks' inputs, stacked and projected as the row's own, with the canonical member
    of the mirrored pose (image_mirror); without the mirrored inputs training refuses."""
    pytest.importorskip("sklearn")
    from sequences.pose_conversions import canonical_member
    from sequences.pose_vector import image_mirror
    data, X, codebook, settings = _dataset()
    # The synthetic histograms say the heading as (cos, sin): a mirror image says -heading.
    X_mirror = X.copy()
    X_mirror[:, 1] = 2.4 - X[:, 1]
    options = replace(_options(), limb_head="facing", limb_net_members=1, limb_net_hidden=(8,))
    with pytest.raises(ValueError, match="mirror"):
        train_mixture_model(data, X, codebook, settings, options, 30.0, log=lambda m: None)
    seen = _capture_limb_net_fit(monkeypatch)
    logged = []
    model, _ = train_mixture_model(data, X, codebook, settings, options, 30.0,
                                   log=logged.append, mirrored=(X_mirror, None))
    train_rows = np.flatnonzero(~validation_mask(data))
    n = len(train_rows)
    assert seen["inputs"].shape == (2 * n, 6) and any("mirror images" in m for m in logged)
    direction = np.eye(55)[0]
    np.testing.assert_allclose(seen["targets"][:n], canonical_member(data.pose[train_rows],
                                                                     direction))
    np.testing.assert_allclose(seen["targets"][n:],
                               canonical_member(image_mirror(data.pose[train_rows]), direction))
    stacked = stack_frames(frame_descriptors(X_mirror, model.transform), model.stack_depth,
                           sequence_ids=data.sequence)[train_rows]
    np.testing.assert_allclose(seen["inputs"][n:], model._stacked(stacked), atol=1e-9)
    with pytest.raises(ValueError, match="mirror"):                 # shapes must match
        train_mixture_model(data, X, codebook, settings, options, 30.0, log=lambda m: None,
                            mirrored=(X_mirror[:-1], None))


def test_rows_played_backwards_stack_the_following_frames_within_each_sequence():
    from lab.training import _time_reversed_rows, reversed_in_sequence
    sequence = np.array([0, 0, 0, 0, 1, 1, 1])
    order = reversed_in_sequence(sequence)
    assert order.tolist() == [3, 2, 1, 0, 6, 5, 4] and order[order].tolist() == list(range(7))
    data = Dataset(masks=np.zeros((7, 1, 1), bool), pose=np.zeros((7, 55)), sequence=sequence,
                   frame=np.array([0, 1, 2, 3, 0, 1, 2]), azimuth_deg=np.zeros(7),
                   elevation_deg=np.zeros(7), trials=["a", "b"], trial_of_sequence=["a", "b"])
    X = np.arange(1.0, 8.0)[:, None]
    rows = _time_reversed_rows(data, X, "none", 3, None, 0.0)
    assert rows.tolist() == [[1, 2, 3], [2, 3, 4], [3, 4, 4], [4, 4, 4],
                             [5, 6, 7], [6, 7, 7], [7, 7, 7]]


def test_limb_networks_also_fit_a_share_of_the_rows_played_backwards(monkeypatch):
    """limb_net_reversed: that share of the training rows (and their mirror images) is added
    with its stacked frames in reverse order and the same targets."""
    pytest.importorskip("sklearn")
    from lab.training import _time_reversed_rows
    from sequences.pose_conversions import canonical_member
    from sequences.pose_vector import image_mirror
    data, X, codebook, settings = _dataset()
    X_mirror = X.copy()
    X_mirror[:, 1] = 2.4 - X[:, 1]
    seen = _capture_limb_net_fit(monkeypatch)
    options = replace(_options(), limb_head="facing", limb_net_members=1, limb_net_hidden=(8,),
                      limb_net_reversed=0.5)
    logged = []
    model, _ = train_mixture_model(data, X, codebook, settings, options, 30.0,
                                   log=logged.append, mirrored=(X_mirror, None))
    train_rows = np.flatnonzero(~validation_mask(data))
    n = len(train_rows)
    picked = train_rows[np.random.default_rng(options.seed).random(n) < 0.5]
    m = len(picked)
    assert 0.35 * n < m < 0.65 * n
    assert seen["inputs"].shape == (2 * n + 2 * m, 6)
    assert any(f"{m} of them played backwards" in line for line in logged)
    direction = np.eye(55)[0]
    np.testing.assert_allclose(seen["targets"][2 * n:2 * n + m],
                               canonical_member(data.pose[picked], direction))
    np.testing.assert_allclose(seen["targets"][2 * n + m:],
                               canonical_member(image_mirror(data.pose[picked]), direction))
    for k, hist in enumerate((X, X_mirror)):
        played_back = _time_reversed_rows(data, hist, model.transform,
                                          model.stack_depth, None, 0.0)[picked]
        block = seen["inputs"][2 * n + k * m:2 * n + (k + 1) * m]
        np.testing.assert_allclose(block, model._stacked(played_back), atol=1e-9)
        forwards = stack_frames(frame_descriptors(hist, model.transform), model.stack_depth,
                                sequence_ids=data.sequence)[picked]
        assert not np.allclose(block, model._stacked(forwards))


def test_training_caches_are_written_whole_and_a_damaged_one_is_made_again(tmp_path,
                                                                          monkeypatch):
    """A cut-off cache file (as an interrupted run used to leave) is reported in a warning and
    computed again; a run interrupted while writing leaves no file behind."""
    from regressor.codebook import Codebook
    from lab.training import cached_descriptors, cached_layouts
    calls = []

    def layouts():
        calls.append(1)
        return np.full((3, 4), 0.5)
    (tmp_path / "layouts-k-g2.npz").write_bytes(b"PK\x03\x04 cut off")
    with pytest.warns(UserWarning, match="unreadable"):
        np.testing.assert_allclose(cached_layouts(tmp_path, "k", 2, layouts), 0.5)
    np.testing.assert_allclose(cached_layouts(tmp_path, "k", 2, layouts), 0.5)   # now cached
    assert len(calls) == 1

    codebook = Codebook(np.ones((2, 3)), 0.5)
    real_save = np.savez_compressed

    def cut_off(file, **arrays):                # Ctrl-C halfway through the write
        Path(file).write_bytes(b"PK\x03\x04 half")
        raise KeyboardInterrupt
    monkeypatch.setattr(np, "savez_compressed", cut_off)
    with pytest.raises(KeyboardInterrupt):
        cached_descriptors(tmp_path, "d", lambda: (np.zeros((3, 2)), codebook))
    assert not (tmp_path / "descriptors-d.npz").exists()
    monkeypatch.setattr(np, "savez_compressed", real_save)
    X, got = cached_descriptors(tmp_path, "d", lambda: (np.arange(6.0).reshape(3, 2), codebook))
    X2, got2 = cached_descriptors(tmp_path, "d", lambda: 1 / 0)
    np.testing.assert_array_equal(X2, X)
    np.testing.assert_array_equal(got2.centres, codebook.centres)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["descriptors-d.npz", "layouts-k-g2.npz"]
