"""scripts/evaluate_accuracy.py refuses bad options in one line (exit 2) before tracking
anything: a malformed or repeated --model, a model file that does not load, a trial with
neither video nor motion capture, a --json it could not write or that names a model."""
from __future__ import annotations

import pytest

from conftest import load_script, refused_in_one_line
from regressor.pose_model import DEFAULT_MODEL_PATH


@pytest.fixture(scope="module")
def evaluate_accuracy():
    return load_script("evaluate_accuracy")


def test_bad_models_are_refused_in_one_line(evaluate_accuracy, tmp_path, capsys):
    def refused(argv):
        return refused_in_one_line(evaluate_accuracy, argv, capsys)
    good = f"a={DEFAULT_MODEL_PATH}"
    assert "NAME=FILE" in refused(["--model", "nameless"])
    assert "given twice" in refused(["--model", good, "--model", good])
    assert "not found" in refused(["--model", f"a={tmp_path / 'm.npz'}"])
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a model")
    assert "--model a:" in refused(["--model", f"a={junk}"])


def test_bad_trials_and_outputs_are_refused_before_tracking(evaluate_accuracy, tmp_path,
                                                            capsys):
    def refused(argv):
        return refused_in_one_line(evaluate_accuracy, argv, capsys)
    base = ["--model", f"a={DEFAULT_MODEL_PATH}", "--video-dir", str(tmp_path / "videos"),
            "--bvh-dir", str(tmp_path / "bvh")]
    assert "trial 99_99: neither" in refused(base + ["--trials", "99_99"])
    assert "no folder" in refused(base + ["--trials", "16_11", "--json",
                                          str(tmp_path / "none" / "r.json")])
    model_copy = tmp_path / "copy.npz"
    model_copy.write_bytes(DEFAULT_MODEL_PATH.read_bytes())
    err = refused(["--model", f"a={model_copy}", "--json", str(model_copy), "--trials", "16_11"])
    assert "is a model file" in err
    assert model_copy.read_bytes() == DEFAULT_MODEL_PATH.read_bytes()
    assert not (tmp_path / "videos").exists()


def test_absurd_frame_rates_are_refused_and_others_get_their_own_videos(evaluate_accuracy,
                                                                        tmp_path, capsys):
    base = ["--model", f"a={DEFAULT_MODEL_PATH}", "--video-dir", str(tmp_path / "videos")]
    for fps in ("5", "1000", "nan"):
        assert "--fps must be between 10 and 240" in refused_in_one_line(
            evaluate_accuracy, base + ["--fps", fps], capsys)
    assert evaluate_accuracy.video_path("16_11", tmp_path) == evaluate_accuracy.SAMPLE
    assert evaluate_accuracy.video_path("02_02", tmp_path).name == "02_02_spiral30.mp4"
    assert evaluate_accuracy.video_path("16_11", tmp_path, 60.0).name == \
        "16_11_spiral30_60fps.mp4"


def test_absurd_lags_are_refused(evaluate_accuracy, tmp_path, capsys):
    base = ["--model", f"a={DEFAULT_MODEL_PATH}", "--video-dir", str(tmp_path / "videos")]
    for lag in ("0", "-1", "nan", "11"):
        assert "--lag must be above 0" in refused_in_one_line(
            evaluate_accuracy, base + ["--lag", lag], capsys)
