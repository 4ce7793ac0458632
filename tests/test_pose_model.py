"""The pose model file stores the ambiguity threshold it was trained with; the tracker uses it."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from regressor.model_file import load_model, save_model
from regressor.pose_model import (DEFAULT_AMBIGUITY_THRESHOLD, DEFAULT_MODEL_PATH,
                                  load_pose_model, save_pose_model)
from tracker import PoseTracker, TrackerSettings


def test_the_threshold_round_trips_and_older_files_get_the_old_default(tmp_path):
    model = replace(load_pose_model(DEFAULT_MODEL_PATH), ambiguity_threshold=0.35)
    save_pose_model(tmp_path / "m.npz", model)
    assert load_pose_model(tmp_path / "m.npz").ambiguity_threshold == 0.35
    parts = dict(load_model(tmp_path / "m.npz").parts)
    del parts["ambiguity_threshold"]                      # as written before it was stored
    save_model(tmp_path / "old.npz", parts)
    assert load_pose_model(tmp_path / "old.npz").ambiguity_threshold == \
        DEFAULT_AMBIGUITY_THRESHOLD == 0.5


def test_the_tracker_uses_the_models_threshold_unless_told_otherwise():
    model = replace(load_pose_model(DEFAULT_MODEL_PATH), ambiguity_threshold=0.35)
    background = np.zeros((120, 160, 3), np.uint8)
    for settings, expected in ((TrackerSettings(), 0.35),
                               (TrackerSettings(ambiguity_threshold=0.6), 0.6)):
        tracker = PoseTracker(model, 30.0, settings)
        tracker.prime(background)
        assert tracker.filter_factory(30.0).ambiguity_threshold == expected
