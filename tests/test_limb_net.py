"""The limb network (regressor.limb_net): fitting, prediction, model files, refusals."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("sklearn")

from regressor.angles import wrap_deg                       # noqa: E402
from regressor.limb_net import LimbNet                     # noqa: E402
from regressor.limb_net_training import fit_limb_net     # noqa: E402
from regressor.optional_parts import predict_limbs            # noqa: E402
from regressor.pose_model import PoseModelError, load_pose_model  # noqa: E402
from regressor.model_writer import limb_net_arrays, save_pose_model


def _synthetic(n=3000, P=6, seed=0):
    """Inputs (n, P) and canonical poses (n, 55) that are smooth non-linear functions of them:
    a heading (cos, sin), and angles around 170 degrees that cross +-180 (the wrap)."""
    rng = np.random.default_rng(seed)
    X = rng.normal(0, 1, (n, P))
    h = np.arctan2(X[:, 1], np.abs(X[:, 0]) + 0.5)          # facing the camera's half
    angles = 170.0 + 20.0 * np.tanh(X[:, 2:3] * X[:, 3:4]) + 5.0 * np.sin(X[:, 4:5]) \
        + 0.0 * np.arange(53)
    Y = np.column_stack([np.cos(h), np.sin(h), wrap_deg(angles)])
    return X, Y


def _fitted(members=2, **kw):
    X, Y = _synthetic()
    centre = np.full(53, 170.0)
    return fit_limb_net(X, Y, centre, np.eye(55)[0], members=members, hidden=(32, 16),
                        max_iter=60, **kw), X, Y


def test_a_network_learns_a_non_linear_map_across_the_wrap():
    net, X, Y = _fitted()
    Xt, Yt = _synthetic(500, seed=1)                        # new rows
    out = net.predict(Xt)
    assert out.shape == (500, 55)
    err = np.abs(wrap_deg(out[:, 2:] - Yt[:, 2:])).mean()
    spread = np.abs(wrap_deg(Yt[:, 2:] - 170.0)).mean()
    assert err < 0.3 * spread                               # far better than the centre
    assert np.all(np.abs(out[:, 2:]) <= 180.0)              # wrapped
    assert np.corrcoef(out[:, 1], Yt[:, 1])[0, 1] > 0.9


def test_the_ensemble_is_the_mean_of_its_members_and_a_refit_is_identical():
    net, X, _ = _fitted(members=2)
    parts = [LimbNet([m], net.input_mean, net.input_scale, net.output_mean, net.output_scale,
                     net.angle_centre_deg, net.canonical_direction) for m in net.members]
    off = [wrap_deg(p.predict(X[:50])[:, 2:] - 170.0) for p in parts]
    np.testing.assert_allclose(wrap_deg(net.predict(X[:50])[:, 2:] - 170.0),
                               (off[0] + off[1]) / 2, atol=1e-4)
    assert not np.allclose(off[0], off[1])                  # two different seeds
    again, _, _ = _fitted(members=2)
    for a, b in zip(net.members, again.members):
        for (W, bias), (W2, bias2) in zip(a, b):
            np.testing.assert_array_equal(W, W2)
            np.testing.assert_array_equal(bias, bias2)


def test_input_noise_still_learns_is_seeded_and_makes_the_map_smoother():
    clean, X, _ = _fitted(members=1)
    noisy, _, _ = _fitted(members=1, input_noise=0.5)
    Xt, Yt = _synthetic(500, seed=1)
    err = np.abs(wrap_deg(noisy.predict(Xt)[:, 2:] - Yt[:, 2:])).mean()
    # Blurred by the noise (half of each input's spread on a map of products of inputs), but
    # still far better than the centre.
    assert err < 0.5 * np.abs(wrap_deg(Yt[:, 2:] - 170.0)).mean()
    again, _, _ = _fitted(members=1, input_noise=0.5)
    for (W, _), (W2, _) in zip(noisy.members[0], again.members[0]):
        np.testing.assert_array_equal(W, W2)
    # Trained on inputs blurred by noise, the map changes less for a small step in the input.
    step = np.random.default_rng(2).normal(0, 0.2, Xt.shape)

    def change(net):
        return np.abs(wrap_deg(net.predict(Xt + step)[:, 2:] - net.predict(Xt)[:, 2:])).mean()

    assert change(noisy) < 0.9 * change(clean)
    with pytest.raises(ValueError, match="input_noise"):
        fit_limb_net(X, np.zeros((len(X), 55)), np.zeros(53), np.eye(55)[0], members=1,
                     input_noise=-0.1)


def test_members_of_different_widths_are_averaged_one_by_one():
    """Same-shaped members run as one batched stack (relu_stacked.stacked_members); members
    of different widths cannot, and give the same mean one by one."""
    a, X, _ = _fitted(members=1)
    X2, Y2 = _synthetic(seed=4)
    b = fit_limb_net(X2, Y2, np.full(53, 170.0), np.eye(55)[0], members=1, hidden=(24, 16),
                     max_iter=30)
    mixed = LimbNet([a.members[0], b.members[0]], a.input_mean, a.input_scale, a.output_mean,
                    a.output_scale, a.angle_centre_deg, a.canonical_direction)
    same = LimbNet([a.members[0], a.members[0]], a.input_mean, a.input_scale, a.output_mean,
                   a.output_scale, a.angle_centre_deg, a.canonical_direction)
    assert mixed._stacked is None and same._stacked is not None
    parts = [LimbNet([m], a.input_mean, a.input_scale, a.output_mean, a.output_scale,
                     a.angle_centre_deg, a.canonical_direction) for m in mixed.members]
    off = [wrap_deg(p.predict(X[:50])[:, 2:] - 170.0) for p in parts]
    np.testing.assert_allclose(wrap_deg(mixed.predict(X[:50])[:, 2:] - 170.0),
                               (off[0] + off[1]) / 2, atol=1e-4)
    np.testing.assert_allclose(same.predict(X[:50]), parts[0].predict(X[:50]), atol=1e-4)
    # one row (batched) as several rows (one by one) give it; no rows give no poses
    np.testing.assert_allclose(same.predict(X[3:4]), same.predict(X[:50])[3:4], atol=1e-4)
    for net in (same, mixed):
        assert net.predict(X[:0]).shape == (0, 55)


@pytest.mark.slow
def test_members_fitted_in_parallel_are_the_ones_fitted_one_after_another():
    one, _, _ = _fitted(members=2)
    two, _, _ = _fitted(members=2, workers=2)
    for a, b in zip(one.members, two.members):
        for (W, bias), (W2, bias2) in zip(a, b):
            np.testing.assert_array_equal(W, W2)
            np.testing.assert_array_equal(bias, bias2)
    with pytest.raises(ValueError, match="workers"):
        _fitted(members=2, workers=0)


def _legacy_parts(net: LimbNet) -> dict:
    """The parts as files written before 2026-12-02's int8 weights held them: float16
    weights, no scales."""
    parts = {k: v for k, v in limb_net_arrays(net).items() if not k.startswith("limb_net_S")}
    for m, layers in enumerate(net.members):
        for i, (W, _) in enumerate(layers):
            parts[f"limb_net_W{m}_{i}"] = W.astype(np.float16)
    return parts


def test_file_parts_round_trip_and_broken_parts_are_refused():
    net, X, _ = _fitted()
    parts = limb_net_arrays(net)
    assert parts["limb_net_W0_0"].dtype == np.int8          # a quarter of float32's space
    assert parts["limb_net_S0_0"].shape == (net.members[0][0][0].shape[1],)
    back = LimbNet.from_arrays(parts)
    change = np.abs(wrap_deg(back.predict(X[:200])[:, 2:] - net.predict(X[:200])[:, 2:]))
    spread = np.abs(wrap_deg(net.predict(X[:200])[:, 2:] - 170.0)).mean()
    # 8 bits of each column's range: small beside the poses' own spread
    assert change.mean() < 0.01 * spread and change.max() < 0.05 * spread
    assert LimbNet.from_arrays({"something_else": np.zeros(1)}) is None
    for broken, match in (({"limb_net_W1_0": None}, "incomplete"),
                          ({"limb_net_S1_1": None}, "incomplete"),
                          ({"limb_net_shape": np.array([2.0, 3.0])}, "two integers"),
                          ({"limb_net_W0_1": parts["limb_net_W0_1"][:-1]}, "layer 1"),
                          ({"limb_net_b1_2": np.full(55, np.nan, np.float32)}, "not finite"),
                          ({"limb_net_S0_0": -parts["limb_net_S0_0"]}, "positive finite"),
                          ({"limb_net_S0_0": parts["limb_net_S0_0"][:-1]}, "one per column"),
                          ({"limb_net_S0_2": np.full(55, np.inf, np.float32)}, "positive finite"),
                          ({"limb_net_W0_0": parts["limb_net_W0_0"].astype(np.float32)},
                           "must hold int8"),
                          ({"limb_net_S0_1": parts["limb_net_S0_1"].astype(np.int64)},
                           "must hold floats"),
                          ({"limb_net_input_scale": np.float64(1e-320)}, "non-finite poses"),
                          ({"limb_net_input_mean": parts["limb_net_input_mean"] + 1e300},
                           "non-finite poses"),
                          ({"limb_net_W9_9": parts["limb_net_W0_0"]}, "does not declare"),
                          ({"limb_net_shape": np.array([1, 3])}, "does not declare"),
                          ({"limb_net_input_scale": np.str_("0.5")}, "must hold floats"),
                          ({"limb_net_output_scale": -parts["limb_net_output_scale"]}, "positive"),
                          ({"limb_net_canonical_direction": 2 * np.eye(55)[0]}, "unit vector")):
        bad = {k: v for k, v in {**parts, **broken}.items() if v is not None}
        with pytest.raises(ValueError, match=match):
            LimbNet.from_arrays(bad)


def test_files_with_float16_weights_still_load_and_are_checked():
    net, X, _ = _fitted()
    parts = _legacy_parts(net)
    back = LimbNet.from_arrays(parts)
    assert np.abs(wrap_deg(back.predict(X[:200])[:, 2:] - net.predict(X[:200])[:, 2:])).max() < 0.1
    for broken, match in (({"limb_net_W0_0": parts["limb_net_W0_0"].astype(np.float64) * 1e300},
                           "float32 range"),
                          ({"limb_net_W0_0": parts["limb_net_W0_0"] > 0}, "must hold floats"),
                          ({"limb_net_W0_1": np.zeros((32, 16), np.int8)}, "must hold floats"),
                          ({"limb_net_S0_1": np.ones(16, np.float32)}, "incomplete"),
                          ({"limb_net_W0_0": np.zeros((6, 32), np.int8)}, "incomplete")):
        bad = {**parts, **broken}
        with pytest.raises(ValueError, match=match):
            LimbNet.from_arrays(bad)


def test_scales_that_float32_cannot_hold_are_refused_without_warnings():
    import warnings
    net, _, _ = _fitted()
    parts = limb_net_arrays(net)
    for broken, match in (({"limb_net_S0_0": parts["limb_net_S0_0"].astype(np.float64) * 1e-300},
                           "float32 values"),
                          ({"limb_net_S0_0": np.full_like(parts["limb_net_S0_0"], 3e38)},
                           "up to"),
                          ({"limb_net_S0_0": parts["limb_net_S0_0"] * 0}, "positive"),
                          ({"limb_net_W0_0": parts["limb_net_W0_0"][0]}, "2-D")):
        with warnings.catch_warnings():
            warnings.simplefilter("error")                  # no overflow on the way
            with pytest.raises(ValueError, match=match):
                LimbNet.from_arrays({**parts, **broken})


def test_a_column_of_tiny_weights_is_written_so_that_it_loads():
    from regressor.model_writer import quantised_int8
    from regressor.relu_layers import dequantised_int8
    W = np.array([[1e-44, 0.5, 0.0], [-2e-44, 0.25, 0.0]])
    q, scale = quantised_int8(W)
    back = dequantised_int8(q, scale, "w")                  # refused before: a zero scale
    np.testing.assert_allclose(back[:, 1], W[:, 1], rtol=0.01)
    assert np.all(np.abs(back[:, 0]) < 1e-40) and np.all(back[:, 2] == 0)
    with pytest.raises(ValueError, match="finite"):
        quantised_int8(np.array([[np.nan, 1.0]]))
    with pytest.raises(ValueError, match="matrix"):
        quantised_int8(np.ones(3))


def test_int8_weights_keep_each_columns_range():
    from regressor.model_writer import quantised_int8
    from regressor.relu_layers import dequantised_int8
    W = np.array([[1.0, 0.0, -1e-3], [-0.5, 0.0, 2e-3], [0.25, 0.0, 1e-4]])
    q, scale = quantised_int8(W)
    assert q.dtype == np.int8 and scale.dtype == np.float32 and np.all(scale > 0)
    back = dequantised_int8(q, scale, "w")
    # each column within half a step of its own range, the tiny column too
    assert np.all(np.abs(back - W) <= 0.501 * np.abs(W).max(axis=0) / 127)
    assert np.all(back[:, 1] == 0)
    with pytest.raises(ValueError, match="int8"):
        dequantised_int8(q.astype(np.int16), scale, "w")
    with pytest.raises(ValueError, match="positive"):
        dequantised_int8(q, np.zeros(3, np.float32), "w")


def test_members_must_have_the_same_layers_and_be_few():
    net, _, _ = _fitted(members=2)
    parts = (net.input_mean, net.input_scale, net.output_mean, net.output_scale,
             net.angle_centre_deg, net.canonical_direction)
    with pytest.raises(ValueError, match="same"):
        LimbNet([net.members[0], net.members[1][:1] + net.members[1][1:]] +
                [[(np.zeros((6, 55)), np.zeros(55))]], *parts)
    with pytest.raises(ValueError, match="same"):
        LimbNet([net.members[0]] * 17, *parts)
    with pytest.raises(ValueError, match="members"):
        fit_limb_net(np.zeros((10, 6)), np.zeros((10, 55)), np.zeros(53), np.eye(55)[0],
                     members=0)


def test_the_tracker_never_imports_scikit_learn():
    """Only training needs scikit-learn: loading the shipped model and predicting (limbs and
    the side classifier) does not."""
    import subprocess
    import sys
    code = ("import sys, numpy as np\n"
            "import tracker.cli, tracker.pipeline\n"
            "from regressor.pose_model import load_pose_model, DEFAULT_MODEL_PATH\n"
            "m = load_pose_model(DEFAULT_MODEL_PATH)\n"
            "x = np.full((2, m.stack_depth * m.descriptor_length), 0.1)\n"
            "estimates = m.hypotheses(x, 2)\n"
            "assert estimates.limbs.shape == (2, 55)\n"
            "front = estimates.front\n"
            "print(len(m.limb_net.members), front.shape == (2,), 'sklearn' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    # the default's 8 networks and its side classifier
    assert out.stdout.split() == ["8", "True", "False"]


def test_a_mixture_model_with_a_limb_network_saves_loads_and_gives_its_limbs(tmp_path):
    from test_mixture import _mixture_model
    from regressor.model_file import load_model
    from regressor.model_writer import save_model
    model, x = _mixture_model()                              # input length 8
    rng = np.random.default_rng(3)
    targets = np.column_stack([np.ones(len(x)), np.zeros(len(x)),
                               wrap_deg(40 * np.tanh(x[:, :1]) + rng.normal(0, 1, (len(x), 53)))])
    model.limb_net = fit_limb_net(x, targets, np.zeros(53), np.eye(55)[0], members=1,
                                  hidden=(16,), max_iter=40)
    assert model.has_limbs
    np.testing.assert_allclose(predict_limbs(model, x[:20]), model.limb_net.predict(x[:20]))
    np.testing.assert_array_equal(model.hypotheses(x[:20], 2).limbs, predict_limbs(model, x[:20]))
    path = tmp_path / "net.npz"
    save_pose_model(path, model)
    loaded = load_pose_model(path)
    # int8 weights (model_writer.limb_net_arrays): within 1 degree of limbs spread over +-40
    assert np.abs(wrap_deg(predict_limbs(loaded, x[:20])[:, 2:]
                           - predict_limbs(model, x[:20])[:, 2:])).max() < 1.0
    raw = dict(load_model(path).parts)
    # a network for another input length, or an incomplete one, is refused at load
    other = fit_limb_net(x[:, :5], targets, np.zeros(53), np.eye(55)[0], members=1,
                         hidden=(4,), max_iter=5)
    from test_mixture import _with_limb_head
    _, head, _ = _with_limb_head(model, x)
    both = {**raw, "limbs_coef": head.coef, "limbs_expert_intercept": head.expert_intercept,
            "limbs_angle_centre_deg": head.angle_centre_deg,
            "limbs_canonical_direction": head.canonical_direction}
    for broken, match in ((limb_net_arrays(other), "takes 5 inputs"),
                          (both, "not both"),
                          ({"limb_net_b0_1": None}, "limb network is incomplete"),
                          ({"canonical_direction": np.eye(55)[0]}, "takes no limb head")):
        parts = {k: v for k, v in {**raw, **broken}.items() if v is not None}
        save_model(path, parts)                              # re-checksummed
        with pytest.raises(PoseModelError, match=match):
            load_pose_model(path)
    from test_mixture import _mixture_model as fresh
    plain, _ = fresh()
    assert not plain.has_limbs and predict_limbs(plain, x[:3]) is None


def test_only_a_mixture_carries_a_limb_network(tmp_path):
    from test_mixture import assert_only_a_mixture_carries
    net, _, _ = _fitted(members=1)
    assert_only_a_mixture_carries(tmp_path, "limb_net", net, limb_net_arrays(net))


def _synthetic_rotations(n=3000, P=6, seed=0):
    """As _synthetic, but each joint's middle (y) angle within +-60 degrees (one Euler triple
    per rotation) while the root's tilts still cross +-180."""
    X, Y = _synthetic(n, P, seed)
    Y = Y.copy()
    wave = np.tanh(X[:, 2:3] * X[:, 3:4]) + 0.5 * np.sin(X[:, 4:5])     # (n, 1)
    Y[:, 4:] = np.tile([30.0, 0.0, -40.0], 17)[None] + np.tile([25.0, 40.0, 30.0], 17) * wave
    return X, Y


def test_networks_on_six_d_rotations_learn_the_angles_and_keep_them_in_the_file():
    X, Y = _synthetic_rotations()
    # the last joint never turns but for rounding, as in mirrored training poses
    Y[:, -3:] = 1e-13 * np.random.default_rng(5).normal(size=(len(Y), 3))
    centre = np.r_[170.0, 170.0, np.tile([30.0, 0.0, -40.0], 16), 0.0, 0.0, 0.0]
    lines = []
    net = fit_limb_net(X, Y, centre, np.eye(55)[0], members=2, hidden=(32, 16),
                       max_iter=60, output="rot6d", log=lines.append)
    assert net.output_width == 106 and net.output_mean.shape == (106,)
    scores = [float(line.split("R^2 ")[1].split(",")[0]) for line in lines]
    assert len(scores) == 2 and min(scores) > 0.5           # not swamped by the rounding
    Xt, Yt = _synthetic_rotations(500, seed=1)
    out = net.predict(Xt)
    assert out.shape == (500, 55)
    err = np.abs(wrap_deg(out[:, 2:] - Yt[:, 2:])).mean(axis=0)
    spread = np.abs(wrap_deg(Yt[:, 2:] - centre)).mean(axis=0)[:-3]
    assert np.all(err[:-3] < 0.3 * spread)                  # tilts across the wrap too
    assert np.abs(out[:, -3:]).max() < 1e-3                 # the still joint stays still
    assert np.corrcoef(out[:, 1], Yt[:, 1])[0, 1] > 0.8     # the heading shares the layers
    back = LimbNet.from_arrays(limb_net_arrays(net))
    assert back.output_width == 106
    change = np.abs(wrap_deg(back.predict(Xt[:200])[:, 2:] - out[:200, 2:]))
    assert change.mean() < 0.01 * spread.mean()
    with pytest.raises(ValueError, match="output must be one of"):
        fit_limb_net(X[:100], Y[:100], centre, np.eye(55)[0], members=1, hidden=(4,),
                     max_iter=2, output="quaternion")


def test_networks_of_another_output_width_are_refused():
    net, X, _ = _fitted(members=1)
    parts = limb_net_arrays(net)
    last = len(net.members[0]) - 1
    for key, cut in ((f"limb_net_W0_{last}", np.s_[:, :50]), (f"limb_net_S0_{last}", np.s_[:50]),
                     (f"limb_net_b0_{last}", np.s_[:50]), ("limb_net_output_mean", np.s_[:50]),
                     ("limb_net_output_scale", np.s_[:50])):
        parts[key] = parts[key][cut]
    with pytest.raises(ValueError, match="gives 50 values, not 55 or 106"):
        LimbNet.from_arrays(parts)
