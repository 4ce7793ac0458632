"""scripts/evaluate_accuracy.py refuses bad options in one line (exit 2) before tracking
anything: a malformed or repeated --model, a model file that does not load, a trial with
neither video nor motion capture, a --json it could not write or that names a model."""
from __future__ import annotations

import pytest

from conftest import load_script
from regressor.pose_model import DEFAULT_MODEL_PATH


@pytest.fixture(scope="module")
def evaluate_accuracy():
    return load_script("evaluate_accuracy")


def _refused(script, argv, capsys) -> str:
    with pytest.raises(SystemExit) as exit_:
        script.main(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    return err


def test_bad_models_are_refused_in_one_line(evaluate_accuracy, tmp_path, capsys):
    good = f"a={DEFAULT_MODEL_PATH}"
    assert "NAME=FILE" in _refused(evaluate_accuracy, ["--model", "nameless"], capsys)
    assert "given twice" in _refused(evaluate_accuracy, ["--model", good, "--model", good],
                                     capsys)
    assert "not found" in _refused(evaluate_accuracy, ["--model", f"a={tmp_path / 'm.npz'}"],
                                   capsys)
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a model")
    assert "--model a:" in _refused(evaluate_accuracy, ["--model", f"a={junk}"], capsys)


def test_bad_trials_and_outputs_are_refused_before_tracking(evaluate_accuracy, tmp_path,
                                                            capsys):
    base = ["--model", f"a={DEFAULT_MODEL_PATH}", "--video-dir", str(tmp_path / "videos"),
            "--bvh-dir", str(tmp_path / "bvh")]
    assert "trial 99_99: neither" in _refused(evaluate_accuracy, base + ["--trials", "99_99"],
                                              capsys)
    assert "no folder" in _refused(evaluate_accuracy,
                                   base + ["--trials", "16_11", "--json",
                                           str(tmp_path / "none" / "r.json")], capsys)
    model_copy = tmp_path / "copy.npz"
    model_copy.write_bytes(DEFAULT_MODEL_PATH.read_bytes())
    err = _refused(evaluate_accuracy, ["--model", f"a={model_copy}", "--json", str(model_copy),
                                       "--trials", "16_11"], capsys)
    assert "is a model file" in err
    assert model_copy.read_bytes() == DEFAULT_MODEL_PATH.read_bytes()
    assert not (tmp_path / "videos").exists()
