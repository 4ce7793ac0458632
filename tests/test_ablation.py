"""scripts/ablation.py: the default variant's replay is the ``track`` run itself, every
variant's toggle changes the tracker's output (member_path's: the chain the smoother uses, as
with the sparse-RVM model the chain equals the per-frame pick on this clip), and the toggles
leave nothing changed after."""
from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

import tracker.tracks.hypotheses as hyp
from regressor.pose_model import load_pose_model
from sequences.video import Actor, write_video
from tests.conftest import ROOT
from tests.synthetic import gait_walk



def _load():
    """scripts/ablation.py as a module, registered (its dataclasses need that)."""
    import importlib.util
    import sys
    spec = importlib.util.spec_from_file_location("ablation", ROOT / "scripts" / "ablation.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["ablation"] = module
    spec.loader.exec_module(module)
    return module


ablation = _load()
ORIGINAL_MEMBERS_OVER_TIME = hyp.members_over_time


def _walker(T=45):
    """A walk along +X, legs and arms swinging at 1 Hz, the body turning 300 degrees over the
    clip (through both profiles, facing the camera and away: every mechanism has work)."""
    return gait_walk(T, np.linspace(-60.0, 240.0, T))


@pytest.fixture(scope="module")
def one_thread():
    """Small matrices: BLAS threads cost far more than they save (as the script runs)."""
    with threadpool_limits(1):
        yield


@pytest.fixture(scope="module")
def captured(tmp_path_factory, one_thread):
    path = tmp_path_factory.mktemp("ablation") / "walk.mp4"
    write_video(path, [Actor(_walker())], size=(240, 320), noise_sigma=2.0, seed=5)
    model = load_pose_model()
    return model, ablation.capture(path, model)


def _outputs(poses, smoothed):
    return (np.array([p.raw for p in poses]), np.array([p.filtered for p in poses]),
            np.concatenate([smoothed[t] for t in sorted(smoothed)]))


def test_the_default_variant_replays_the_track_run_exactly(captured):
    model, cap = captured
    assert len(cap.poses) > 30
    with ablation.applied(ablation.BY_NAME["present"], model) as (m, settings):
        assert m is model
        poses, smoothed = ablation.replay(cap, m, settings)
    assert [(p.frame_index, p.track_id) for p in poses] == \
        [(p.frame_index, p.track_id) for p in cap.poses]
    for mine, theirs in zip(_outputs(poses, smoothed), _outputs(cap.poses, cap.smoothed)):
        np.testing.assert_allclose(mine, theirs, atol=1e-9)


def test_every_toggle_changes_the_output_and_is_undone(captured):
    model, cap = captured
    saved = (hyp.canonical_hypotheses, hyp.transition_matrix, hyp.members_over_time,
             model.canonical_priors,
             model.limb_net, model.side_classifier)
    with ablation.applied(ablation.BY_NAME["present"], model) as (m, settings):
        base = _outputs(*ablation.replay(cap, m, settings))
    for variant in ablation.VARIANTS[1:]:
        with ablation.applied(variant, model) as (m, settings):
            out = _outputs(*ablation.replay(cap, m, settings, variant.mirror,
                                            variant.describe))
        changed = [a.shape != b.shape or not np.allclose(a, b, atol=1e-6)
                   for a, b in zip(base, out)]
        if variant.name != "member_path":
            assert any(changed), variant.name
    assert saved == (hyp.canonical_hypotheses, hyp.transition_matrix, hyp.members_over_time,
                     model.canonical_priors,
                     model.limb_net, model.side_classifier)


def test_the_member_path_toggle_replaces_the_chain_the_smoother_uses(captured, monkeypatch):
    """Whether the chain of members differs from the per-frame pick depends on the clip (on
    this one it need not), so the toggle is checked where it acts: the smoothed output is made
    from the per-frame pick by the smoothed heading, not from the chain."""
    model, cap = captured
    calls = []
    with ablation.applied(ablation.BY_NAME["member_path"], model) as (m, settings):
        patched = hyp.members_over_time
        assert patched is not ORIGINAL_MEMBERS_OVER_TIME

        def spy(*args, **kwargs):
            calls.append(1)
            return patched(*args, **kwargs)
        monkeypatch.setattr(hyp, "members_over_time", spy)
        ablation.replay(cap, m, settings)
        monkeypatch.undo()
    assert calls, "the smoother never asked for the members over time"
    assert hyp.members_over_time is ORIGINAL_MEMBERS_OVER_TIME
