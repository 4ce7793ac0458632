"""scripts/evaluate_jitter.py refuses bad input in one line (exit 2) before its slow work:
absurd numbers, too few frames, a huge size, missing inputs, and outputs (--json, --video and
its sidecar, the --report folder's files) that could not be written or would overwrite an
input or each other. A Ctrl-C ends it with exit 130, leaving the previous --video and its
sidecar as they were, also when it comes while the video is being tracked."""
from __future__ import annotations

import types

import pytest

import lab.evaluation as evaluation
from conftest import cut_run, load_script, refused_in_one_line


@pytest.fixture(scope="module")
def evaluate_jitter():
    return load_script("evaluate_jitter")


@pytest.fixture
def inputs(tmp_path):
    """Stand-ins for a BVH, a model and the paper's data: refused before they are read."""
    files = {name: tmp_path / name for name in ("jv.bvh", "jm.npz", "jp.npz", "ankur.mat")}
    for name, path in files.items():
        path.write_bytes(f"input {name}".encode())
    return files


@pytest.mark.parametrize("option, value", [
    ("--frames", "0"), ("--frames", "-5"), ("--frames", "2"), ("--size", "99999x99999"),
    ("--size", "10x10"), ("--r-scale", "0"), ("--r-scale", "inf"), ("--r-scale", "nan"),
    ("--q-scale", "0"), ("--q-scale", "-1"), ("--ambiguity-threshold", "nan"),
    ("--ambiguity-threshold", "5"), ("--ambiguity-threshold", "-0.1"),
    ("--heading-factor", "0"), ("--joint-factor", "nan"), ("--spiral", "inf")])
@pytest.mark.parametrize("source", ["--bvh", "--ankur"])
def test_absurd_numbers_are_refused_in_one_line(evaluate_jitter, tmp_path, capsys, source,
                                                option, value):
    err = refused_in_one_line(evaluate_jitter, [source, str(tmp_path / "none"), option, value],
                              capsys)
    assert f"{option} must be within" in err


def test_outputs_that_would_overwrite_an_input_are_refused_and_the_input_kept(
        evaluate_jitter, inputs, tmp_path, capsys):
    bvh, model, per_frame, ankur = (str(inputs[n]) for n in ("jv.bvh", "jm.npz", "jp.npz",
                                                              "ankur.mat"))
    before = {name: path.read_bytes() for name, path in inputs.items()}

    def refused(*options):
        return refused_in_one_line(evaluate_jitter, list(options), capsys)
    same = "is the same file as"
    assert same in refused("--bvh", bvh, "--json", bvh)
    assert same in refused("--bvh", bvh, "--model", model, "--json", model)
    assert same in refused("--bvh", bvh, "--per-frame-model", per_frame, "--json", per_frame)
    assert same in refused("--ankur", ankur, "--json", ankur)
    video = str(tmp_path / "same.mp4")
    assert same in refused("--bvh", bvh, "--through-video", "--video", video, "--json", video)
    assert same in refused("--bvh", bvh, "--through-video", "--video", str(tmp_path / "jv.mp4"),
                           "--json", str(tmp_path / "jv.truth.npz"))
    # The report folder's files: here the BVH is the README the report would write.
    folder = tmp_path / "report"
    folder.mkdir()
    readme = folder / "README.md"
    readme.write_bytes(inputs["jv.bvh"].read_bytes())
    assert same in refused("--bvh", str(readme), "--report", str(folder))
    assert readme.read_bytes() == before["jv.bvh"]
    assert "is a file; give a folder" in refused("--bvh", bvh, "--report", bvh)
    assert {name: path.read_bytes() for name, path in inputs.items()} == before
    assert not (tmp_path / "same.mp4").exists() and not (tmp_path / "jv.mp4").exists()


def test_missing_inputs_and_folders_are_refused_before_the_work(evaluate_jitter, inputs,
                                                                tmp_path, capsys):
    bvh = str(inputs["jv.bvh"])

    def refused(*options):
        return refused_in_one_line(evaluate_jitter, list(options), capsys)
    assert "no such file" in refused("--bvh", str(tmp_path / "none.bvh"))
    assert "--model" in refused("--bvh", bvh, "--model", str(tmp_path / "none.npz"))
    assert "no folder" in refused("--bvh", bvh, "--json", str(tmp_path / "nodir2" / "x.json"))
    assert "no folder" in refused("--bvh", bvh, "--through-video", "--video",
                                  str(tmp_path / "nodir3" / "v.mp4"))
    # A report is a folder: made with its missing parents (as track makes --bvh's), unless
    # the nearest that exists cannot take it.
    (tmp_path / "afile").write_text("a file")
    assert "cannot make it" in refused("--bvh", bvh, "--report", str(tmp_path / "afile" / "r"))
    assert "give --through-video" in refused("--bvh", bvh, "--video", str(tmp_path / "v.mp4"))
    assert "give a video name" in refused("--bvh", bvh, "--through-video", "--video",
                                          str(tmp_path / "v.txt"))
    assert not any((tmp_path / name).exists() for name in ("nodir2", "nodir3"))


def test_ctrl_c_keeps_the_previous_video_and_its_sidecar(evaluate_jitter, inputs, tmp_path,
                                                         capsys, monkeypatch):
    video, sidecar = tmp_path / "v.mp4", tmp_path / "v.truth.npz"
    video.write_bytes(b"old video")
    sidecar.write_bytes(b"old ground truth")

    def written_then_interrupted(bvh, *args, video=None, **kwargs):
        video.write_bytes(b"new video, cut short")         # as write_video would have
        video.with_name(video.stem + ".truth.npz").write_bytes(b"new ground truth")
        raise KeyboardInterrupt
    monkeypatch.setattr(evaluate_jitter, "load_pose_model", lambda path: None)
    monkeypatch.setattr(evaluate_jitter, "video_sequence", written_then_interrupted)
    code = evaluate_jitter.main(["--bvh", str(inputs["jv.bvh"]), "--through-video",
                                 "--video", str(video), "--json", str(tmp_path / "r.json")])
    assert code == 130
    err = capsys.readouterr().err.strip()
    assert err == "evaluate_jitter: interrupted; nothing written"
    assert video.read_bytes() == b"old video" and sidecar.read_bytes() == b"old ground truth"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["v.mp4", "v.truth.npz", *inputs])


def test_a_ctrl_c_that_ends_the_tracking_ends_the_evaluation(monkeypatch):
    """track_video takes a Ctrl-C as the end of the video and returns what it tracked;
    track_longest (which --through-video runs) must not hand that cut track on to be measured
    and written as if it were the whole."""
    from tracker import TrackerSettings
    monkeypatch.setattr(evaluation, "open_video", lambda video: types.SimpleNamespace(fps=30.0))
    monkeypatch.setattr(evaluation, "PoseTracker", lambda *args, **kwargs: None)
    monkeypatch.setattr(evaluation, "track_video",
                        lambda *args, **kwargs: cut_run())
    with pytest.raises(KeyboardInterrupt):
        evaluation.track_longest("v.mp4", None, TrackerSettings())


def test_a_run_replaces_its_json_and_report_files_and_keeps_the_others(evaluate_jitter,
                                                                       cmu_bvh_dir, tmp_path,
                                                                       capsys):
    pytest.importorskip("matplotlib")
    out, folder = tmp_path / "r.json", tmp_path / "report"
    out.write_text("old")
    folder.mkdir()
    (folder / "README.md").write_text("old")
    (folder / "notes.txt").write_text("mine")
    assert evaluate_jitter.main(["--bvh", str(cmu_bvh_dir / "16_11.bvh"), "--frames", "3",
                                 "--json", str(out), "--report", str(folder)]) == 0
    assert '"frames": 3' in out.read_text()
    assert (folder / "README.md").read_text().startswith("# Evaluation")
    assert (folder / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json", "report"]
