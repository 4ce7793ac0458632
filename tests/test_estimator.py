"""The tracker calls a model through regressor.estimator.PoseEstimator's members and no
others: an object holding only those tracks a video exactly as the model itself does."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from regressor.estimator import PoseEstimates, PoseEstimator
from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
from sequences.video import Actor, write_video
from tests.test_track_cli import _walker
from tracker import PoseRecorder, PoseTracker, TrackerSettings, track_video
from tracker.tracks.proposals import propose_sequence

ATTRIBUTES = ("stack_depth", "training_fps", "measurement_covariance", "process_noise",
              "ambiguity_threshold", "canonical_direction", "gives_canonical_pairs",
              "canonical_priors", "limbs_see_mirror")
METHODS = ("describe", "describe_with_mirror", "hypotheses")


class Minimal:
    """PoseEstimator's members, answered by a model, and nothing else (no __dict__: the
    tracker cannot find or leave anything on it). calls: the members asked for."""

    __slots__ = ("_model", "calls")

    def __init__(self, model):
        self._model, self.calls = model, set()

    def _ask(self, name: str):
        self.calls.add(name)
        return getattr(self._model, name)

    def describe(self, mask):
        return self._ask("describe")(mask)

    def describe_with_mirror(self, mask):
        return self._ask("describe_with_mirror")(mask)

    def hypotheses(self, stacked, m=1, mirrored=None, novelty=True) -> PoseEstimates:
        return self._ask("hypotheses")(stacked, m, mirrored=mirrored, novelty=novelty)


for _name in ATTRIBUTES:
    setattr(Minimal, _name, property(lambda self, name=_name: self._ask(name)))


@pytest.fixture(scope="module")
def walk(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("estimator") / "walk.mp4"
    write_video(path, [Actor(_walker(40))], size=(240, 320), noise_sigma=2.0, seed=5)
    return path


@pytest.fixture(scope="module")
def model():
    return load_pose_model(DEFAULT_MODEL_PATH)


def test_the_declared_interface_is_the_stand_ins_and_the_model_has_it(model):
    assert set(PoseEstimator.__annotations__) == set(ATTRIBUTES)
    assert all(callable(getattr(PoseEstimator, name)) for name in METHODS)
    assert isinstance(model, PoseEstimator) and isinstance(Minimal(model), PoseEstimator)
    assert not isinstance(object(), PoseEstimator)
    public = {n for n in dir(Minimal) if not n.startswith("_")} - {"calls"}
    assert public == set(ATTRIBUTES) | set(METHODS)


def _tracked(video, estimator, settings: TrackerSettings) -> list:
    recorder = PoseRecorder()
    track_video(video, PoseTracker(estimator, 30.0, settings), [recorder], workers=1)
    return recorder.poses


@pytest.mark.parametrize("mirror_limbs", [True, False])
def test_the_tracker_runs_on_the_interface_alone_with_the_models_poses(walk, model,
                                                                       mirror_limbs):
    """The shipped model (limb networks, side classifier, heading index) through the stand-in
    and directly: the same poses, novelty and front/back decisions, value for value."""
    settings = TrackerSettings(max_people=1, mirror_limbs=mirror_limbs)
    stand_in = Minimal(model)
    got, want = _tracked(walk, stand_in, settings), _tracked(walk, model, settings)
    assert len(got) == len(want) >= 30
    for a, b in zip(got, want):
        assert (a.frame_index, a.track_id, a.ambiguous) == (b.frame_index, b.track_id,
                                                              b.ambiguous)
        np.testing.assert_array_equal(a.raw, b.raw)
        np.testing.assert_array_equal(a.filtered, b.filtered)
        assert a.novelty == b.novelty and np.isfinite(a.novelty) and a.novelty > 0
    assert "hypotheses" in stand_in.calls
    assert ("describe_with_mirror" in stand_in.calls) == mirror_limbs


def test_a_model_without_optional_parts_goes_through_the_same_calls(walk):
    """The per-frame model (one regressor: no experts, limbs, side classifier or heading
    index) answers the same members; its novelty is unknown (NaN), its limbs None."""
    plain = load_pose_model(DEFAULT_MODEL_PATH.with_name("per_frame_model.npz"))
    assert not plain.gives_canonical_pairs and not plain.limbs_see_mirror
    poses = _tracked(walk, Minimal(plain), TrackerSettings(max_people=1))
    assert len(poses) >= 30 and all(np.isnan(p.novelty) for p in poses)
    masks = [np.pad(np.ones((60, 20), bool), 10)] * 5
    hypotheses = propose_sequence(Minimal(plain), masks)
    assert len(hypotheses) == 5 and all(h.limbs is None and not h.canonical for h in hypotheses)
