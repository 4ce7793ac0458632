"""scripts/reproduce_paper.py, scripts/bench_track.py and scripts/bench_view.py refuse bad input
in one line (exit 2) before their long work: a missing or foreign data file, a --json they could
not write or that names the data, a missing or undecodable video or model, an absurd frame
count or lag."""
from __future__ import annotations

import numpy as np
import scipy.io

from conftest import load_script, refused_in_one_line
from lab.evaluation import ANKUR_SHAPES


def test_reproduce_paper_refuses_what_is_not_the_papers_data(tmp_path, capsys):
    script = load_script("reproduce_paper")

    def refused(argv):
        return refused_in_one_line(script, argv, capsys)
    assert "cannot read it" in refused(["--data", str(tmp_path / "none.mat")])
    text = tmp_path / "notes.mat"
    text.write_text("not a MATLAB file")
    assert "cannot read it" in refused(["--data", str(text)])
    other = tmp_path / "other.mat"
    scipy.io.savemat(other, {"A": np.zeros((2, 2))})
    assert "no Y, Z, Y_test, Z_test" in refused(["--data", str(other)])
    assert "no folder" in refused(["--data", str(other), "--json",
                                   str(tmp_path / "none" / "r.json")])
    before = other.read_bytes()
    assert "is the same file as --data" in refused(["--data", str(other), "--json", str(other)])
    assert other.read_bytes() == before
    assert "--methods: unknown method kernel_svm; choose from mean_pose" in refused(
        ["--data", str(other), "--methods", "kernel_rvm,kernel_svm"])


def _paper_data(path, **arrays) -> None:
    """A .mat file of the paper's four arrays at their shapes (zeros), some replaced."""
    data = {key: np.zeros(shape) for key, shape in ANKUR_SHAPES.items()}
    scipy.io.savemat(path, {**data, **arrays})


def test_reproduce_paper_refuses_a_json_that_is_the_data_by_a_hard_link_or_a_folder(tmp_path,
                                                                                 capsys):
    script = load_script("reproduce_paper")
    data = tmp_path / "paper.mat"
    _paper_data(data)
    link = tmp_path / "hard.json"
    link.hardlink_to(data)
    before = data.read_bytes()
    err = refused_in_one_line(script, ["--data", str(data), "--json", str(link)], capsys)
    assert "is the same file as --data" in err and data.read_bytes() == before
    err = refused_in_one_line(script, ["--data", str(data), "--json", str(tmp_path)], capsys)
    assert "is a folder" in err


def test_reproduce_paper_names_the_file_and_the_problem_of_data_that_is_not_the_papers(
        tmp_path, capsys):
    script = load_script("reproduce_paper")

    def refused(path):
        return refused_in_one_line(script, ["--data", str(path)], capsys)
    real = tmp_path / "real.mat"
    _paper_data(real)
    cut = tmp_path / "cut.mat"                           # a header cut short: an IndexError
    cut.write_bytes(real.read_bytes()[:120])
    assert f"--data {cut}: cannot read it as a MATLAB file" in refused(cut)
    strings = tmp_path / "strings.mat"
    scipy.io.savemat(strings, {"Y": "abc", "Z": "a", "Y_test": "b", "Z_test": "c"})
    assert f"--data {strings}: not the paper's data (Y holds no numbers)" in refused(strings)
    rows = tmp_path / "rows.mat"
    scipy.io.savemat(rows, {"Y": np.zeros((5, 100)), "Z": np.zeros((5, 63)),
                            "Y_test": np.zeros((3, 100)), "Z_test": np.zeros((3, 63))})
    assert "(Y is 5x100, expected 1927x100)" in refused(rows)
    nan = tmp_path / "nan.mat"
    _paper_data(nan, Z=np.full((1927, 63), np.nan))
    assert "Z holds a number that is not finite" in refused(nan)


def test_reproduce_paper_ends_in_one_line_on_data_the_regressors_refuse_and_on_ctrl_c(
        tmp_path, capsys, monkeypatch):
    script = load_script("reproduce_paper")
    zeros = tmp_path / "zeros.mat"                       # the paper's shapes, all zeros
    _paper_data(zeros)
    assert script.main(["--data", str(zeros)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith(
        f"reproduce_paper: error: --data {zeros}: ")

    def interrupted(data, names=None):
        raise KeyboardInterrupt
    monkeypatch.setattr(script, "_reproduce", interrupted)
    assert script.main(["--data", str(zeros)]) == 130
    assert capsys.readouterr().err == "reproduce_paper: interrupted\n"


def test_reproduce_paper_writes_its_json_whole(tmp_path, capsys, monkeypatch):
    script = load_script("reproduce_paper")
    data, out = tmp_path / "paper.mat", tmp_path / "r.json"
    _paper_data(data)
    monkeypatch.setattr(script, "_reproduce", lambda d, names=None: {"n_train": len(d["Y"])})
    assert script.main(["--data", str(data), "--json", str(out)]) == 0
    assert out.read_text() == '{\n  "n_train": 1927\n}'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["paper.mat", "r.json"]


def test_bench_track_refuses_missing_inputs_and_absurd_frame_counts(tmp_path, capsys):
    script = load_script("bench_track")

    def refused(argv):
        return refused_in_one_line(script, argv, capsys)
    assert "no such file" in refused(["--video", str(tmp_path / "v.mp4")])
    assert "--model" in refused(["--model", str(tmp_path / "m.npz")])
    assert "--frames must be" in refused(["--frames", "0"])


def test_bench_view_refuses_missing_or_broken_videos_and_absurd_lags(tmp_path, capsys):
    script = load_script("bench_view")

    def refused(argv):
        return refused_in_one_line(script, argv, capsys)
    assert "no such file" in refused(["--video", str(tmp_path / "v.mp4")])
    broken = tmp_path / "broken.mp4"
    broken.write_bytes(b"not a video" * 100)
    assert "decode" in refused(["--video", str(broken)])
    for lag in ("-1", "nan", "inf", "11"):
        assert "--lag" in refused(["--lag", lag])


def test_bench_view_says_so_in_one_line_when_nobody_is_drawn(tmp_path, capsys):
    import cv2
    video = tmp_path / "empty.mp4"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 30, (160, 120))
    for _ in range(20):
        writer.write(np.full((120, 160, 3), 128, np.uint8))
    writer.release()
    assert load_script("bench_view").main(["--video", str(video), "--lag", "0"]) == 1
    err = capsys.readouterr().err.strip()
    assert "no gaps to measure" in err and len(err.splitlines()) == 1


def test_reproduce_papers_held_out_blocks_are_decoded_as_the_pieces_of_sequences_they_hold():
    script = load_script("reproduce_paper")
    ids = np.repeat([0, 1], [6, 4])                      # two training sequences, 6 and 4 frames
    # Rows 0-2 and 5-9 (the block 3-4 held out): the cut and the new sequence at 6 both break.
    assert script.run_labels(np.array([0, 1, 2, 5, 6, 7, 8, 9]), ids).tolist() == [0, 0, 0, 1,
                                                                                   2, 2, 2, 2]


def test_the_bagged_mixture_averages_mixtures_that_differ_by_their_seed():
    script = load_script("reproduce_paper")
    rng = np.random.default_rng(0)
    X = rng.normal(size=(120, 4))
    Y = np.column_stack([np.sin(X[:, 0]), X[:, 1] ** 2, X[:, 2] * X[:, 3]])
    script.MixtureRVM.rvm_params = {"width_scale": 0.5, "noise": 0.05, "min_gain": 400.0}
    mix = {"n_experts": 4, "overlap": 0.5, "gate": "neighbours", "gate_neighbours": 3}
    bag = script.BaggedMixture(3, **mix).fit(X, Y)
    answers = [member.predict(X[:20]) for member in bag.members_]
    assert [m.seed for m in bag.members_] == [0, 1, 2]
    assert not np.allclose(answers[0], answers[1])             # different partitions
    np.testing.assert_allclose(bag.predict(X[:20]), np.mean(answers, axis=0))
    assert bag.n_basis_ == sum(m.n_basis_ for m in bag.members_)
