"""The pose model file stores the ambiguity threshold it was trained with; the tracker uses it;
edited model files are refused at load."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from regressor.model_file import load_model
from regressor.pose_model import (DEFAULT_AMBIGUITY_THRESHOLD, DEFAULT_MODEL_PATH, PoseModelError,
                                  load_pose_model)
from regressor.model_writer import save_model, save_pose_model
from tracker import PoseTracker, TrackerSettings
from tracker.tracks.hypotheses import chain_options


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


def test_the_tracker_stacks_and_tempers_at_the_models_training_frame_rate():
    """The shipped model learned its stacked input and its front/back chain's per-frame
    figures on 30 fps sequences (its description says so): a 60 fps video stacks every
    second frame and its chain counts each frame as half of a 30 fps one; a model whose
    description names another rate (or none: 30) is taken at its word."""
    model = load_pose_model(DEFAULT_MODEL_PATH)
    assert model.training_fps == 30.0
    for fps, step in ((30.0, 1), (60.0, 2), (120.0, 4)):
        tracker = PoseTracker(model, fps, TrackerSettings())
        tracker.prime(np.zeros((120, 160, 3), np.uint8))
        assert tracker.stack_step == step
        state = tracker._state(0)
        assert state.stacker.step == step
        assert state.hypotheses.frame_rate_ratio == 30.0 / fps
    described = replace(model, description={**model.description,
                                            "dataset": {**model.description["dataset"],
                                                        "fps": 60.0}})
    assert described.training_fps == 60.0
    assert PoseTracker(described, 60.0, TrackerSettings()).stack_step == 1
    assert chain_options(described)["reference_fps"] == 60.0
    assert replace(model, description={}).training_fps == 30.0
    assert chain_options(replace(model, description={}))["reference_fps"] == 30.0


# ------------------------------------------------------------------ edited model files


def _edited(path, **changes):
    """The shipped model with some parts changed or (value None) removed and its checksum
    recomputed, as a deliberate edit would be; returns the path."""
    import json as _json
    from regressor.model_file import FORMAT_VERSION, checksum
    with np.load(DEFAULT_MODEL_PATH, allow_pickle=False) as npz:
        parts = {k: npz[k] for k in npz.files if k not in ("format_version", "checksum")}
    for name, value in changes.items():
        if name == "dataset_fps":
            description = _json.loads(str(parts["description"]))
            description["dataset"]["fps"] = value
            parts["description"] = np.str_(_json.dumps(description))
        elif value is None:
            del parts[name]
        else:
            parts[name] = value(parts[name]) if callable(value) else value
    np.savez(path, **parts, format_version=np.int64(FORMAT_VERSION),
             checksum=np.str_(checksum(parts)))
    return path


@pytest.mark.parametrize("changes, says", [
    (dict(descriptor_include_holes=np.str_("False")), "descriptor_include_holes is stored as"),
    (dict(mixture_top_experts=np.float64(2.5)), "mixture_top_experts is stored as"),
    (dict(ambiguity_threshold=np.str_("0.5")), "ambiguity_threshold is stored as"),
    (dict(coef=None), "part 'coef' is missing"),
    (dict(dataset_fps=1e-4), "data set fps 0.0001 is not a frame rate"),
    (dict(codebook_centres=lambda c: c[:, :59].copy()), "centres have 59 columns"),
    (dict(codebook_sigma=np.float64(1e300)), "codebook sigma must be within"),
    (dict(descriptor_r_outer=np.float64(0.01)), "r_outer=0.01 is out of range"),
], ids=["bool-as-text", "int-as-float", "float-as-text", "missing-part", "fps-1e-4",
        "codebook-columns", "sigma-1e300", "r-outer"])
def test_an_edited_model_is_refused_at_load_naming_the_problem(tmp_path, changes, says):
    """Each had loaded (misread: bool("False") is True) and then given wrong poses, a
    traceback, minutes and gigabytes (fps 1e-4), or a run-time error blaming the video."""
    path = _edited(tmp_path / "edited.npz", **changes)
    with pytest.raises(PoseModelError, match="edited.npz") as info:
        load_pose_model(path)
    assert says in str(info.value)


def test_an_archive_member_that_is_not_an_array_is_refused(tmp_path):
    import zipfile
    path = _edited(tmp_path / "extra.npz")
    with zipfile.ZipFile(path, "a") as archive:
        archive.writestr("notes.txt", b"hello")
    with pytest.raises(PoseModelError, match="member 'notes.txt' of the archive is not an "
                                             "array"):
        load_pose_model(path)


def test_what_track_asks_of_the_model_loads_no_training_or_batch_code():
    """Loading the shipped model and asking what ``track`` asks (stacked frames with their
    mirror images) loads none of the modules that only training, evaluation, whole-sequence
    stacking, 6-D rotations, one-row batching or BVH output need."""
    import subprocess
    import sys
    optional = ["regressor.rotation6d", "regressor.relu_stacked", "regressor.stacking_batch",
                "regressor.model_writer",
                "regressor.optional_parts", "sequences.skeleton_tables",
                "sequences.pose_conversions"]
    code = ("import sys, numpy as np\n"
            "import tracker.pipeline, tracker.tracks.hypotheses, sequences.pose_vector\n"
            "from regressor.pose_model import load_pose_model\n"
            "m = load_pose_model()\n"
            "x = np.full((1, m.stack_depth * m.descriptor_length), 0.1)\n"
            "assert m.hypotheses(x, 2, mirrored=x).mirror_limbs.shape == (1, 55)\n"
            f"print([name for name in {optional!r} if name in sys.modules])\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"
