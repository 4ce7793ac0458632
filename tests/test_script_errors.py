"""scripts/reproduce_paper.py and scripts/bench_track.py refuse bad input in one line (exit 2)
before their long work: a missing or foreign data file, a --json they could not write or that
names the data, a missing video or model, an absurd frame count."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.io

from conftest import load_script


def _refused(script, argv, capsys) -> str:
    with pytest.raises(SystemExit) as exit_:
        script.main(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    return err


def test_reproduce_paper_refuses_what_is_not_the_papers_data(tmp_path, capsys):
    script = load_script("reproduce_paper")
    assert "cannot read it" in _refused(script, ["--data", str(tmp_path / "none.mat")], capsys)
    text = tmp_path / "notes.mat"
    text.write_text("not a MATLAB file")
    assert "cannot read it" in _refused(script, ["--data", str(text)], capsys)
    other = tmp_path / "other.mat"
    scipy.io.savemat(other, {"A": np.zeros((2, 2))})
    assert "no Y, Z, Y_test, Z_test" in _refused(script, ["--data", str(other)], capsys)
    assert "no folder" in _refused(script, ["--data", str(other), "--json",
                                            str(tmp_path / "none" / "r.json")], capsys)
    before = other.read_bytes()
    assert "would be overwritten" in _refused(script, ["--data", str(other), "--json",
                                                       str(other)], capsys)
    assert other.read_bytes() == before


def test_bench_track_refuses_missing_inputs_and_absurd_frame_counts(tmp_path, capsys):
    script = load_script("bench_track")
    assert "no such file" in _refused(script, ["--video", str(tmp_path / "v.mp4")], capsys)
    assert "--model" in _refused(script, ["--model", str(tmp_path / "m.npz")], capsys)
    assert "--frames must be" in _refused(script, ["--frames", "0"], capsys)
