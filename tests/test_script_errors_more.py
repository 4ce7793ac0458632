"""More scripts refuse bad input in one line, before their long work (exit 2 for options, 1 for
data, 130 for Ctrl-C), and write no output over an input: evaluate_jitter.py --ankur and the
options it does not take, the paper's data that is not, motions too short for a spiral walk,
evaluate_silhouettes.py's --json and trial, evaluate_real.py's trial and model,
draw_fitted_body.py's output, contact_sheet.py, count_frames.py, build_dataset.py's numbers,
bench_track.py --frames, and FFmpeg's own log lines kept off stderr."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys

import cv2
import numpy as np
import pytest
import scipy.io

from conftest import ROOT, load_script, refused_in_one_line
from regressor.pose_model import DEFAULT_MODEL_PATH
from sequences.bvh import write_bvh
from sequences.pose2sim import CALIBRATION, REFERENCE_TRC, VIEWS
from sequences.spiral import SpiralError, spiral_walk
from sequences.video import truth_path
from synthetic import cmu_motion

SAMPLE = ROOT / "sequences" / "data" / "sample_spiral_walk.mp4"


def _walk(frames: int, fps: float = 30.0):
    """A CMU-skeleton motion of that many frames (no shared data needed)."""
    euler = np.zeros((frames, 31, 3))
    euler[:, 2, 2] = 20 * np.sin(np.arange(frames) / 2)
    root = np.column_stack([np.arange(frames, dtype=float), np.full(frames, 17.0),
                            np.zeros(frames)])
    return cmu_motion(euler, root, fps=fps, source="walk")


def _short_bvh(path):
    """A valid BVH of 2 frames at 120 fps: 1 frame at 30 fps, too short for a spiral walk."""
    write_bvh(path, _walk(2, fps=120.0))
    return path


def _one_line(err: str) -> str:
    err = err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def _video(path, frames: int = 3) -> None:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (320, 240))
    for _ in range(frames):
        writer.write(np.full((240, 320, 3), 100, np.uint8))
    writer.release()


# ---------------------------------------------------------------- evaluate_jitter --ankur

@pytest.fixture(scope="module")
def evaluate_jitter():
    return load_script("evaluate_jitter")


@pytest.mark.parametrize("option", [["--model", "none.npz"], ["--per-frame-model", "none.npz"],
                                    ["--spiral", "30"], ["--size", "320x240"],
                                    ["--heading-factor", "2"], ["--joint-factor", "2"],
                                    ["--ambiguity-threshold", "0.5"]])
def test_ankur_refuses_the_options_of_a_rendered_motion(evaluate_jitter, tmp_path, capsys,
                                                        option):
    data = tmp_path / "ankur.mat"
    data.write_text("stand-in")
    err = refused_in_one_line(evaluate_jitter, ["--ankur", str(data), *option], capsys)
    assert f"{option[0]} is for a rendered --bvh motion" in err


def test_ankur_takes_frames_and_r_scale(evaluate_jitter, tmp_path, monkeypatch):
    data = tmp_path / "ankur.mat"
    data.write_text("stand-in")
    taken = {}

    def sequence(path, options, frames):
        taken.update(r_scale=options.r_scale, frames=frames)
        raise KeyboardInterrupt
    monkeypatch.setattr(evaluate_jitter, "ankur_sequence", sequence)
    assert evaluate_jitter.main(["--ankur", str(data), "--frames", "5", "--r-scale", "3"]) == 130
    assert taken == {"r_scale": 3.0, "frames": 5}


def test_ankur_data_that_is_not_the_papers_is_one_line_naming_the_file(evaluate_jitter,
                                                                       tmp_path, capsys):
    text = tmp_path / "text.mat"
    text.write_text("hello\n")
    assert evaluate_jitter.main(["--ankur", str(text)]) == 1
    err = _one_line(capsys.readouterr().err)
    assert err.startswith(f"evaluate_jitter: error: {text}: cannot read it as a MATLAB file")
    wrong = tmp_path / "wrong.mat"
    scipy.io.savemat(wrong, {"Y": np.zeros((5, 100)), "Z": np.zeros((5, 63)),
                             "Y_test": np.zeros((3, 100)), "Z_test": np.zeros((3, 63))})
    assert evaluate_jitter.main(["--ankur", str(wrong)]) == 1
    assert _one_line(capsys.readouterr().err) == (
        f"evaluate_jitter: error: {wrong}: not the paper's data (Y is 5x100, expected 1927x100)")


# ---------------------------------------------------------------- too short for a spiral

def test_a_motion_too_short_for_a_spiral_walk_is_named():
    with pytest.raises(SpiralError, match="walk: too short to loop"):
        spiral_walk(_walk(1), 30.0)


def test_render_video_names_a_bvh_too_short_for_its_spiral(tmp_path, capsys):
    bvh = _short_bvh(tmp_path / "short.bvh")
    out = tmp_path / "v.mp4"
    assert load_script("render_video").main(["--bvh", str(bvh), "--out", str(out),
                                             "--spiral", "30"]) == 1
    err = _one_line(capsys.readouterr().err)
    assert str(bvh) in err and "too short" in err and not out.exists()


def test_evaluate_jitter_names_a_bvh_too_short_for_its_spiral(evaluate_jitter, tmp_path,
                                                              capsys):
    bvh = _short_bvh(tmp_path / "short.bvh")
    assert evaluate_jitter.main(["--bvh", str(bvh), "--spiral", "30"]) == 1
    err = _one_line(capsys.readouterr().err)
    assert "short.bvh" in err and "too short" in err


def test_evaluate_accuracy_names_a_trial_too_short_for_its_spiral(tmp_path, capsys):
    _short_bvh(tmp_path / "short.bvh")
    assert load_script("evaluate_accuracy").main(
        ["--model", f"a={DEFAULT_MODEL_PATH}", "--trials", "short", "--bvh-dir", str(tmp_path),
         "--video-dir", str(tmp_path / "videos")]) == 1
    err = _one_line(capsys.readouterr().err)
    assert err.startswith(f"evaluate_accuracy: error: trial short: {tmp_path / 'short.bvh'}: ")
    assert "too short" in err


# ---------------------------------------------------------------- FFmpeg's log lines

def test_evaluate_accuracy_keeps_ffmpegs_log_line_off_a_truncated_videos_error(tmp_path):
    video = tmp_path / "tt_spiral30.mp4"
    video.write_bytes(SAMPLE.read_bytes()[:100_000])
    np.savez(truth_path(video), format_version=np.int64(1), pose=np.zeros((60, 1, 55)))
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENCV_FFMPEG_LOGLEVEL", "OPENCV_LOG_LEVEL", "TRACK_DEBUG")}
    run = subprocess.run([sys.executable, str(ROOT / "scripts" / "evaluate_accuracy.py"),
                          "--model", f"a={DEFAULT_MODEL_PATH}", "--trials", "tt",
                          "--video-dir", str(tmp_path), "--bvh-dir", str(tmp_path)],
                         capture_output=True, text=True, env=env, timeout=300)
    assert run.returncode == 1
    assert _one_line(run.stderr).startswith("evaluate_accuracy: error: trial tt, model a: ")
    assert "moov" in run.stderr and "truncated" in run.stderr


# ---------------------------------------------------------------- evaluate_silhouettes

@pytest.fixture(scope="module")
def evaluate_silhouettes():
    return load_script("evaluate_silhouettes")


def _stand_in_trial(root):
    """A trial folder's files as stand-ins (refused before they are read)."""
    for name in (REFERENCE_TRC, CALIBRATION, *(f"videos/{view}.mp4" for view in VIEWS)):
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(f"stand-in {name}")
    return root


def test_evaluate_silhouettes_refuses_a_json_it_could_not_write_or_that_is_an_input(
        evaluate_silhouettes, tmp_path, capsys):
    trial = _stand_in_trial(tmp_path / "trial")
    reference = trial / REFERENCE_TRC
    base = ["--trial", str(trial)]

    def refused(argv):
        return refused_in_one_line(evaluate_silhouettes, base + argv, capsys)
    assert "is the same file as the reference" in refused(["--json", str(reference)])
    assert reference.read_text() == f"stand-in {REFERENCE_TRC}"
    assert "no folder" in refused(["--json", str(tmp_path / "none" / "r.json")])
    assert "is a folder" in refused(["--json", str(tmp_path)])
    err = refused_in_one_line(evaluate_silhouettes, ["--trial", str(tmp_path / "none")],
                              capsys)
    assert f"--trial {tmp_path / 'none'}: no such folder" in err


def test_evaluate_silhouettes_names_a_reference_that_is_not_text(evaluate_silhouettes,
                                                                 tmp_path, capsys):
    trial = _stand_in_trial(tmp_path / "trial")
    (trial / REFERENCE_TRC).write_bytes(bytes(range(256)) * 8)
    assert evaluate_silhouettes.main(["--trial", str(trial)]) == 1
    err = _one_line(capsys.readouterr().err)
    assert err.startswith(f"evaluate_silhouettes: error: {trial / REFERENCE_TRC}: not a text")


def test_evaluate_silhouettes_says_what_it_does_writes_its_json_whole_and_stops_on_ctrl_c(
        evaluate_silhouettes, tmp_path, capsys, monkeypatch):
    trial = _stand_in_trial(tmp_path / "trial")
    out = tmp_path / "r.json"
    monkeypatch.setattr(evaluate_silhouettes, "checked_trial", lambda root, views: "trial")
    monkeypatch.setattr(evaluate_silhouettes, "evaluate_pose2sim_view",
                        lambda trial, view, *args, **kwargs: {"view": view})
    monkeypatch.setattr(evaluate_silhouettes, "format_table", lambda results: "table")
    assert evaluate_silhouettes.main(["--trial", str(trial), "--extractor", "before", "after",
                                      "--views", "cam01", "cam02", "--json", str(out)]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err == ["[1/4] extractor before, view cam01", "[2/4] extractor before, view cam02",
                   "[3/4] extractor after, view cam01", "[4/4] extractor after, view cam02"]
    assert '"cam02": {' in out.read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json", "trial"]

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(evaluate_silhouettes, "evaluate_pose2sim_view", interrupted)
    assert evaluate_silhouettes.main(["--trial", str(trial)]) == 130
    assert capsys.readouterr().err.splitlines()[-1] == "evaluate_silhouettes: interrupted"


# ---------------------------------------------------------------- evaluate_real

@pytest.fixture(scope="module")
def evaluate_real():
    return load_script("evaluate_real")


def test_evaluate_real_refuses_a_missing_trial_or_model_naming_it(evaluate_real, tmp_path,
                                                                  capsys):
    err = refused_in_one_line(evaluate_real, ["--trial", str(tmp_path / "none")], capsys)
    assert f"--trial {tmp_path / 'none'}: no such folder" in err and "shared" not in err
    err = refused_in_one_line(evaluate_real, ["--trial", str(tmp_path), "--model",
                                              str(tmp_path / "none.npz")], capsys)
    assert f"--model {tmp_path / 'none.npz'}: no such file" in err


def test_evaluate_real_finds_a_missing_video_before_any_work(evaluate_real, pose2sim_trial,
                                                             tmp_path, capsys, monkeypatch):
    trial = tmp_path / "balancing"
    for name in (REFERENCE_TRC, CALIBRATION):
        (trial / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(pose2sim_trial / name, trial / name)
    (trial / "videos").mkdir()
    for view in ("cam01", "cam02", "cam04"):
        _video(trial / "videos" / f"{view}.mp4")

    def work(*args, **kwargs):
        raise AssertionError("the work started before the trial's videos were checked")
    monkeypatch.setattr(evaluate_real, "evaluate", work)
    assert evaluate_real.main(["--trial", str(trial)]) == 1
    assert _one_line(capsys.readouterr().err) == (
        f"evaluate_real: error: {trial / 'videos' / 'cam03.mp4'}: no such file")


# ---------------------------------------------------------------- draw_fitted_body

@pytest.fixture(scope="module")
def draw_fitted_body():
    return load_script("draw_fitted_body")


def test_draw_fitted_body_refuses_an_output_it_could_not_write_before_any_work(
        draw_fitted_body, tmp_path, capsys, monkeypatch):
    trial = _stand_in_trial(tmp_path / "trial")

    def work(*args, **kwargs):
        raise AssertionError("the work started before the output was checked")
    monkeypatch.setattr(draw_fitted_body, "draw", work)

    def refused(out):
        return refused_in_one_line(draw_fitted_body, [str(out), "--trial", str(trial)], capsys)
    assert "no folder" in refused(tmp_path / "none" / "fit.png")
    link = tmp_path / "fit.png"                         # the calibration, by a hard link
    link.hardlink_to(trial / CALIBRATION)
    assert "is the same file as the calibration" in refused(link)
    assert (trial / CALIBRATION).read_text() == f"stand-in {CALIBRATION}"
    assert not (tmp_path / "none").exists()


def test_draw_fitted_body_names_a_reference_that_is_not_text(draw_fitted_body, tmp_path,
                                                             capsys):
    trial = _stand_in_trial(tmp_path / "trial")
    (trial / REFERENCE_TRC).write_bytes(bytes(range(256)) * 8)
    assert draw_fitted_body.main([str(tmp_path / "fit.png"), "--trial", str(trial)]) == 1
    err = _one_line(capsys.readouterr().err)
    assert err.startswith(f"draw_fitted_body: error: {trial / REFERENCE_TRC}: not a text file")


def test_draw_fitted_body_passes_the_jpeg_quality_for_a_jpeg_only(draw_fitted_body, tmp_path,
                                                                  monkeypatch):
    flags = {}
    monkeypatch.setattr(draw_fitted_body.cv2, "imwrite",
                        lambda path, image, params=(): flags.update({path[-4:]: list(params)})
                        or True)
    image = np.zeros((4, 4, 3), np.uint8)
    for name in ("a.png", "a.jpg"):
        draw_fitted_body._write_image(tmp_path / name, image, tmp_path / name)
    assert flags == {".png": [], ".jpg": [cv2.IMWRITE_JPEG_QUALITY, 80]}


def test_draw_fitted_body_keeps_ffmpegs_log_lines_off_stderr(draw_fitted_body, tmp_path,
                                                             capsys, monkeypatch):
    monkeypatch.delenv("OPENCV_FFMPEG_LOGLEVEL", raising=False)
    monkeypatch.delenv("TRACK_DEBUG", raising=False)
    trial = _stand_in_trial(tmp_path / "trial")
    draw_fitted_body.main([str(tmp_path / "fit.png"), "--trial", str(trial)])
    capsys.readouterr()
    assert os.environ.get("OPENCV_FFMPEG_LOGLEVEL") == "-8"


# ---------------------------------------------------------------- contact_sheet

@pytest.fixture(scope="module")
def contact_sheet():
    return load_script("contact_sheet")


@pytest.fixture
def walk_bvh(tmp_path):
    path = tmp_path / "walk.bvh"
    write_bvh(path, _walk(6))
    return path


def test_contact_sheet_refuses_bad_options_in_one_line(contact_sheet, walk_bvh, tmp_path,
                                                       capsys):
    def refused(*argv):
        return refused_in_one_line(contact_sheet, ["--bvh", str(walk_bvh), *argv], capsys)
    png = str(tmp_path / "s.png")
    assert "--frame must be 0 or more" in refused("--frame", "-1", "--out", png)
    # (read_bvh drops the first frame, a T-pose)
    assert "walk.bvh has 5 frames (0..4)" in refused("--frame", "6", "--out", png)
    assert "give an image name" in refused("--out", str(tmp_path / "s.txt"))
    assert "is a folder" in refused("--out", str(tmp_path))
    assert "no folder" in refused("--out", str(tmp_path / "new" / "s.png"))
    assert not (tmp_path / "new").exists()
    err = refused_in_one_line(contact_sheet, ["--bvh", str(tmp_path / "none.bvh")], capsys)
    assert "no such file" in err
    motion = tmp_path / "motion.png"                     # a BVH named like an image
    motion.write_bytes(walk_bvh.read_bytes())
    err = refused_in_one_line(contact_sheet, ["--bvh", str(motion), "--out", str(motion)],
                              capsys)
    assert "is the same file as --bvh" in err
    assert motion.read_bytes() == walk_bvh.read_bytes()


def test_contact_sheet_names_a_malformed_bvh_in_one_line(contact_sheet, tmp_path, capsys):
    bvh = tmp_path / "bad.bvh"
    bvh.write_text("hello\n")
    assert contact_sheet.main(["--bvh", str(bvh), "--out", str(tmp_path / "s.png")]) == 1
    assert "bad.bvh line 1" in _one_line(capsys.readouterr().err)


def test_contact_sheets_help_is_whole_and_says_what_each_option_is(contact_sheet, capsys):
    with pytest.raises(SystemExit):
        contact_sheet.main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "shaded render above its binary silhouette." in text
    for option in ("--bvh BVH the motion", "--frame FRAME the frame", "--out OUT the image"):
        assert option in text


def test_contact_sheet_draws_the_sheet(contact_sheet, walk_bvh, tmp_path, capsys):
    out = tmp_path / "sheet.png"
    assert contact_sheet.main(["--bvh", str(walk_bvh), "--frame", "3", "--out", str(out)]) == 0
    assert cv2.imread(str(out)).shape == (6 * 170, 12 * 115, 3)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sheet.png", "walk.bvh"]


# ---------------------------------------------------------------- count_frames

@pytest.mark.parametrize("fps", ["0", "-30", "nan", "1e300"])
def test_count_frames_refuses_absurd_rates(tmp_path, capsys, fps):
    err = refused_in_one_line(load_script("count_frames"), [str(tmp_path), "--fps", fps],
                              capsys)
    assert "--fps must be within" in err


def test_count_frames_names_what_is_wrong_with_the_folder(tmp_path, capsys):
    script = load_script("count_frames")
    assert "no such folder" in refused_in_one_line(script, [str(tmp_path / "none")], capsys)
    (tmp_path / "a.txt").write_text("a file")
    assert "is a file, not a folder" in refused_in_one_line(script, [str(tmp_path / "a.txt")],
                                                           capsys)
    (tmp_path / "y.bvh").mkdir()
    write_bvh(tmp_path / "walk.bvh", _walk(6))
    assert script.main([str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert "y.bvh        ERROR Is a directory" in out and "2 files, 5 frames" in out


def test_count_frames_and_build_dataset_end_ctrl_c_in_one_line(tmp_path, capsys, monkeypatch):
    write_bvh(tmp_path / "walk.bvh", _walk(6))

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    for name, function, argv in (("count_frames", "read_bvh", [str(tmp_path)]),
                                 ("build_dataset", "build_dataset",
                                  ["--bvh-dir", str(tmp_path), "--cache", str(tmp_path / "c")])):
        script = load_script(name)
        monkeypatch.setattr(script, function, interrupted)
        assert script.main(argv) == 130
        assert capsys.readouterr().err.splitlines()[-1] == f"{name}: interrupted"   # after progress


# ---------------------------------------------------------------- build_dataset

@pytest.mark.parametrize("option, value", [("--workers", "0"), ("--workers", "-3"),
                                           ("--rows-per-trial", "-5"), ("--seed", "-1"),
                                           ("--max-views", "0"), ("--views", "0")])
def test_build_dataset_refuses_absurd_numbers_naming_the_option(tmp_path, capsys, option,
                                                                value):
    err = refused_in_one_line(load_script("build_dataset"),
                              ["--bvh-dir", str(tmp_path), option, value], capsys)
    assert f"{option} must be in" in err


# ---------------------------------------------------------------- bench_track --frames

def test_bench_track_renders_the_frames_asked_for_though_another_length_is_cached(
        tmp_path, monkeypatch):
    script = load_script("bench_track")
    monkeypatch.setattr(script, "ROOT", tmp_path)
    cached = script.default_video(script.DEFAULT_FRAMES)
    cached.parent.mkdir(parents=True)
    cached.write_bytes(b"the default video, 1200 frames")
    rendered = []

    def render(path, frames):
        rendered.append((path, frames))
        raise KeyboardInterrupt
    monkeypatch.setattr(script, "_make_video", render)
    assert script.main(["--frames", "10"]) == 130
    assert rendered == [(tmp_path / "out" / "bench" / "walk640-turn60-10f.mp4", 10)]


def test_bench_track_refuses_frames_with_a_video_of_its_own(tmp_path, capsys):
    video = tmp_path / "v.mp4"
    _video(video)
    err = refused_in_one_line(load_script("bench_track"), ["--video", str(video), "--frames",
                                                           "10"], capsys)
    assert "--frames sets the length of the default video" in err


# ---------------------------------------------------------------- render_video --help

def test_render_videos_help_gives_the_elevations_it_takes(capsys):
    with pytest.raises(SystemExit):
        load_script("render_video").main(["--help"])
    assert "strictly between -89 and 89" in " ".join(capsys.readouterr().out.split())


def test_a_skeleton_without_the_cmu_joints_is_named_by_its_file(contact_sheet, evaluate_jitter,
                                                                walk_bvh, tmp_path, capsys):
    """"skeleton lacks the CMU joints" had not said which file."""
    odd = tmp_path / "odd.bvh"
    odd.write_text(walk_bvh.read_text().replace("LeftUpLeg", "LeftThigh"))
    assert contact_sheet.main(["--bvh", str(odd), "--out", str(tmp_path / "s.png"),
                               "--frame", "0"]) == 1
    assert _one_line(capsys.readouterr().err) == (
        f"contact_sheet: error: --bvh {odd}: skeleton lacks the CMU joints ['LeftUpLeg']")
    assert evaluate_jitter.main(["--bvh", str(odd)]) == 1
    assert _one_line(capsys.readouterr().err) == (
        f"evaluate_jitter: error: --bvh {odd}: skeleton lacks the CMU joints ['LeftUpLeg']")
