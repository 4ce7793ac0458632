"""scripts/evaluate_real.py refuses, before about a minute of tracking, a --max-people below 1
and a --json or --masks it could not write or that is one of the files it reads (nothing
overwritten); a reference or calibration that is not text, or a calibration with a NaN, is one
line naming the file; a tracking run cut short by Ctrl-C stops the evaluation, in one line."""
from __future__ import annotations

import shutil

import cv2
import numpy as np
import pytest

from conftest import cut_run, load_script, refused_in_one_line
from regressor.pose_model import DEFAULT_MODEL_PATH
from sequences.pose2sim import CALIBRATION, REFERENCE_TRC


@pytest.fixture(scope="module")
def evaluate_real():
    return load_script("evaluate_real")


def test_fewer_than_one_person_is_refused(evaluate_real, tmp_path, capsys):
    err = refused_in_one_line(evaluate_real, ["--trial", str(tmp_path), "--max-people", "0"],
                              capsys)
    assert "--max-people must be at least 1, got 0" in err


def test_outputs_that_would_overwrite_an_input_or_fail_late_are_refused(evaluate_real,
                                                                       tmp_path, capsys):
    def refused(argv):
        return refused_in_one_line(evaluate_real, argv, capsys)
    trial = tmp_path / "trial"                      # no real trial needed: refused before it
    (trial / "videos").mkdir(parents=True)
    (trial / "calibration").mkdir()
    video, calibration = trial / "videos" / "cam01.mp4", trial / CALIBRATION
    video.write_bytes(b"a camera's video")
    calibration.write_bytes(b"a calibration")
    model = tmp_path / "model.npz"
    model.write_bytes(DEFAULT_MODEL_PATH.read_bytes())
    base = ["--trial", str(trial), "--model", str(model)]
    for output in (video, calibration, model):
        assert "is the same file as" in refused(base + ["--json", str(output)])
    png_folder = tmp_path / "sheet.png"
    png_folder.mkdir()
    assert "--masks" in refused(base + ["--masks", str(png_folder)])
    assert "no folder" in refused(base + ["--json", str(tmp_path / "none" / "r.json")])
    assert "is a folder" in refused(base + ["--json", str(tmp_path)])
    assert video.read_bytes() == b"a camera's video"
    assert calibration.read_bytes() == b"a calibration"
    assert model.read_bytes() == DEFAULT_MODEL_PATH.read_bytes()


@pytest.fixture
def trial_copy(pose2sim_trial, tmp_path):
    """The reference and calibration of the Pose2Sim trial (no videos), to spoil."""
    copy = tmp_path / "balancing"
    for name in (REFERENCE_TRC, CALIBRATION):
        (copy / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(pose2sim_trial / name, copy / name)
    return copy


def _one_line_error(evaluate_real, trial, capsys) -> str:
    assert evaluate_real.main(["--trial", str(trial)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    return err


@pytest.mark.parametrize("name", [CALIBRATION, REFERENCE_TRC])
def test_a_file_of_the_trial_that_is_not_text_is_one_line_naming_it(evaluate_real, trial_copy,
                                                                    capsys, name):
    (trial_copy / name).write_bytes(bytes(range(256)) * 8)
    err = _one_line_error(evaluate_real, trial_copy, capsys)
    assert err.startswith(f"evaluate_real: error: {trial_copy / name}: not a text file")


def test_a_nan_in_the_calibration_is_one_line_naming_it(evaluate_real, trial_copy, capsys):
    path = trial_copy / CALIBRATION
    text = path.read_text()
    start = text.index("matrix = [ [ ") + len("matrix = [ [ ")
    path.write_text(text[:start] + "nan" + text[text.index(",", start):])
    err = _one_line_error(evaluate_real, trial_copy, capsys)
    assert err.startswith(f"evaluate_real: error: {path}: camera cam01 has a number that is "
                          f"not finite")


def test_ctrl_c_ends_the_run_in_one_line(evaluate_real, tmp_path, capsys, monkeypatch):
    def interrupted(root):
        raise KeyboardInterrupt
    monkeypatch.setattr(evaluate_real, "checked_trial", interrupted)
    assert evaluate_real.main(["--trial", str(tmp_path)]) == 130
    assert capsys.readouterr().err == "evaluate_real: interrupted\n"


def test_a_tracking_run_cut_short_by_ctrl_c_stops_the_evaluation(evaluate_real, tmp_path,
                                                                  monkeypatch):
    """track_video ends early on Ctrl-C and says so in its result: the view's poses were then
    measured as if the video had ended there."""
    import tracker
    from regressor.pose_model import load_pose_model
    video = tmp_path / "still.mp4"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (320, 240))
    for _ in range(5):
        writer.write(np.full((240, 320, 3), 100, np.uint8))
    writer.release()
    monkeypatch.setattr(tracker, "track_video",
                        lambda *args, **kwargs: cut_run())
    with pytest.raises(KeyboardInterrupt):
        evaluate_real._track_view(video, load_pose_model(DEFAULT_MODEL_PATH), None)
