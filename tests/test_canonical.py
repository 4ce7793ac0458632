"""Canonical members of {pose, front/back flip} (issue 9): the choice, its training direction,
the model file part and the tracker's use of it."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from regressor.angles import wrap_deg
from regressor.errors import SilhouettePoseError
from regressor.model_file import load_model
from regressor.pose_model import load_pose_model
from regressor.model_writer import save_pose_model
from sequences.pose_conversions import canonical_member, flip_odd_part
from sequences.pose_vector import PoseVectorError, front_back_flip
from tests.test_layout import _projected_model, _write_unchecked
from tests.test_pose_vector import _random_vectors
from lab.training import canonical_direction
from tracker.pipeline import TrackerSettings, filter_factories


def test_the_odd_part_changes_sign_under_the_flip():
    v = _random_vectors(50, seed=3)
    np.testing.assert_allclose(flip_odd_part(front_back_flip(v)), -flip_odd_part(v), atol=1e-9)
    # what the flip keeps (e.g. Hips_x, the heading's sine) has no odd part
    assert np.allclose(flip_odd_part(v)[:, 1], 0.0)


def test_a_pose_and_its_flip_have_one_canonical_member():
    v = _random_vectors(200, seed=4)
    u = np.random.default_rng(0).normal(size=55)
    a, b = canonical_member(v, u), canonical_member(front_back_flip(v), u)
    np.testing.assert_allclose(a[:, :2], b[:, :2], atol=1e-9)
    assert np.abs(wrap_deg(a[:, 2:] - b[:, 2:])).max() < 1e-9
    kept = np.all(a == v, axis=1)
    assert 0.2 < kept.mean() < 0.8                 # both members are chosen, by the sign
    assert np.all(flip_odd_part(a) @ u >= 0)
    with pytest.raises(PoseVectorError, match="55 finite"):
        canonical_member(v, np.ones(3))


def test_the_training_direction_separates_members_of_walk_like_poses():
    """Poses whose legs swing in anti-phase: the direction is mostly the legs' difference, and
    few poses lie near the boundary."""
    rng = np.random.default_rng(5)
    v = _random_vectors(400, seed=6) * 0.05
    phase = rng.uniform(0, 2 * np.pi, 400)
    v[:, 18] += 40 * np.sin(phase)                   # one leg's swing
    v[:, 30] -= 40 * np.sin(phase)                   # the other's, in anti-phase
    u = canonical_direction(v)
    assert u.shape == (55,) and abs(np.linalg.norm(u) - 1) < 1e-9
    assert u[np.argmax(np.abs(u))] > 0
    d = flip_odd_part(v) @ u
    assert np.mean(np.abs(d) < 5) < 0.15
    assert np.abs(u[[18, 30]]).sum() > 1.0


def test_a_canonical_model_round_trips_and_a_bad_direction_is_refused(tmp_path):
    model, _ = _projected_model()
    u = np.linspace(-1, 1, 55)
    model = replace(model, canonical_direction=u)
    path = tmp_path / "m.npz"
    save_pose_model(path, model)
    np.testing.assert_allclose(load_pose_model(path).canonical_direction, u)
    raw = dict(load_model(path).parts)
    for bad in (u[:54], np.zeros(55)):
        _write_unchecked(path, dict(raw, canonical_direction=bad))
        with pytest.raises(SilhouettePoseError, match="canonical_direction"):
            load_pose_model(path)


def test_the_tracker_takes_a_canonical_models_limbs_from_the_chain():
    model, _ = _projected_model()
    assert filter_factories(model, TrackerSettings())[1] is not None
    canonical = replace(model, canonical_direction=np.ones(55))
    assert filter_factories(canonical, TrackerSettings())[1] is None


def test_the_facing_rule_keeps_the_member_facing_the_camera():
    """train.py --canonical facing: direction e0, i.e. the heading cosine's sign."""
    v = _random_vectors(300, seed=7)
    c = canonical_member(v, np.eye(55)[0])
    assert np.all(c[:, 0] >= 0)
    back = v[:, 0] < 0
    np.testing.assert_allclose(c[back], front_back_flip(v[back]))
    np.testing.assert_allclose(c[~back], v[~back])
