"""scripts/evaluate_accuracy.py on bad data: a malformed BVH, a video without its ground truth
or with a broken one, a video with nobody in it end the run in one line naming the trial and the
file (exit 1), before any rendering; a --video-dir that is a file and a --json that is a folder
or one of the files the run reads or renders are refused by the parser (exit 2, nothing
overwritten); a video is rendered under a temporary name, so an interrupted render leaves none;
Ctrl-C ends the run in one line (exit 130)."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from conftest import load_script, refused_in_one_line
from regressor.pose_model import DEFAULT_MODEL_PATH
from sequences.bvh import write_bvh
from sequences.video import truth_path
from synthetic import cmu_motion

MODEL = ["--model", f"a={DEFAULT_MODEL_PATH}"]

_NOT_CMU = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  End Site
  {
    OFFSET 0 1 0
  }
}
MOTION
Frames: 3
Frame Time: 0.0333
0 0 0 0 0 0
0 0 0 10 0 0
0 0 0 20 0 0
"""


@pytest.fixture(scope="module")
def evaluate_accuracy():
    return load_script("evaluate_accuracy")


@pytest.fixture(scope="module")
def good_bvh(tmp_path_factory) -> str:
    """The text of a well-formed 30-frame BVH on the CMU skeleton (no ../shared needed)."""
    path = tmp_path_factory.mktemp("bvh") / "good.bvh"
    euler = np.random.default_rng(0).uniform(-20, 20, (30, 31, 3))
    write_bvh(path, cmu_motion(euler, np.zeros((30, 3))))
    return path.read_text()


def _malformed(good: str) -> dict[str, bytes]:
    """Malformed BVH files by what is wrong with them."""
    head, motion = good.split("MOTION\n")
    lines = motion.splitlines()
    frames, frame_time, rows = lines[0], lines[1], lines[2:]
    return {
        "truncated": good[:len(head) // 2].encode(),
        "empty": b"",
        "binary": bytes(range(256)) * 4,
        "zero_frames": f"{head}MOTION\nFrames: 0\n{frame_time}\n".encode(),
        "single_frame": f"{head}MOTION\nFrames: 1\n{frame_time}\n{' '.join(['0'] * 96)}\n"
                        .encode(),
        "not_numeric": f"{head}MOTION\n{frames}\n{frame_time}\n"
                       + "\n".join(["x" + r[1:] for r in rows]) + "\n",
        "channels": f"{head}MOTION\n{frames}\n{frame_time}\n"
                    + "\n".join(r + " 1.0" for r in rows) + "\n",
        "not_cmu": _NOT_CMU,
        "frame_time": f"{head}MOTION\n{frames}\nFrame Time: 1e300\n" + "\n".join(rows) + "\n",
    }


@pytest.mark.parametrize("kind", ["truncated", "empty", "binary", "zero_frames", "single_frame",
                                  "not_numeric", "channels", "not_cmu", "frame_time"])
def test_a_malformed_bvh_is_one_line_naming_the_trial_before_any_rendering(
        evaluate_accuracy, good_bvh, tmp_path, capsys, kind):
    bvh_dir, videos = tmp_path / "bvh", tmp_path / "videos"
    bvh_dir.mkdir()
    videos.mkdir()
    data = _malformed(good_bvh)[kind]
    (bvh_dir / "bad.bvh").write_bytes(data if isinstance(data, bytes) else data.encode())
    # The bad trial second: it is found before the first is tracked (its video has nobody in
    # it, which would be the error then) or the bad one rendered.
    _still_video(videos / "first_spiral30.mp4")
    _truth(videos / "first_spiral30.mp4")
    assert evaluate_accuracy.main(MODEL + ["--trials", "first", "bad", "--bvh-dir",
                                           str(bvh_dir), "--video-dir", str(videos)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert err.startswith("evaluate_accuracy: error: trial bad: ") and "bad.bvh" in err
    assert sorted(p.name for p in videos.iterdir()) == ["first_spiral30.mp4",
                                                        "first_spiral30.truth.npz"]


def _still_video(path, frames: int = 60) -> None:
    """A 320x240 video of an empty grey scene: nobody to track."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (320, 240))
    for _ in range(frames):
        writer.write(np.full((240, 320, 3), 100, np.uint8))
    writer.release()


def _truth(video, frames: int = 60) -> None:
    np.savez(truth_path(video), format_version=np.int64(1), pose=np.zeros((frames, 1, 55)))


def test_a_video_without_usable_ground_truth_names_the_files_to_delete(evaluate_accuracy,
                                                                       tmp_path, capsys):
    videos = tmp_path / "videos"
    videos.mkdir()
    video = videos / "zz_spiral30.mp4"
    _still_video(video)
    argv = MODEL + ["--trials", "zz", "--video-dir", str(videos), "--bvh-dir", str(tmp_path)]

    def error():
        assert evaluate_accuracy.main(argv) == 1
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "Traceback" not in err
        return err
    assert f"has no ground truth {truth_path(video)}" in error()         # never written
    assert f"delete {video} to render it again" in error()
    _truth(video)
    truth_path(video).write_bytes(truth_path(video).read_bytes()[:100])     # cut short
    assert f"delete {video} and {truth_path(video)}" in error()
    np.savez(truth_path(video), format_version=np.int64(1), pose=np.zeros((60, 55)))
    assert "unusable ground truth (poses of shape (60, 55)" in error()


def test_a_video_with_nobody_in_it_is_one_line(evaluate_accuracy, tmp_path, capsys):
    video = tmp_path / "zz_spiral30.mp4"
    _still_video(video)
    _truth(video)
    assert evaluate_accuracy.main(MODEL + ["--trials", "zz", "--video-dir", str(tmp_path),
                                           "--bvh-dir", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert err == f"evaluate_accuracy: error: trial zz, model a: {video}: nobody was tracked"


def test_bad_folders_and_outputs_that_would_overwrite_inputs_are_refused(evaluate_accuracy,
                                                                        tmp_path, capsys):
    def refused(argv):
        return refused_in_one_line(evaluate_accuracy, MODEL + argv, capsys)
    videos, bvh_dir = tmp_path / "videos", tmp_path / "bvh"
    videos.mkdir()
    bvh_dir.mkdir()
    video = videos / "tt_spiral30.mp4"
    video.write_bytes(b"a video")
    bvh = bvh_dir / "bb.bvh"
    bvh.write_bytes(b"a motion")
    base = ["--trials", "tt", "--video-dir", str(videos), "--bvh-dir", str(bvh_dir)]
    assert "is a file, not a folder" in refused(["--trials", "tt", "--video-dir", str(video)])
    assert "is a folder" in refused(base + ["--json", str(tmp_path)])
    for output in (video, truth_path(video), videos / "other_spiral30.mp4", bvh):
        assert "choose another file name" in refused(base + ["--json", str(output)])
    sample = evaluate_accuracy.SAMPLE
    before = (sample.read_bytes(), truth_path(sample).read_bytes())
    for output in (sample, truth_path(sample)):            # with the default trials and not
        assert "same file" in refused(["--video-dir", str(videos), "--json", str(output)])
        assert "same file" in refused(base + ["--json", str(output)])
    assert (sample.read_bytes(), truth_path(sample).read_bytes()) == before
    assert video.read_bytes() == b"a video" and bvh.read_bytes() == b"a motion"
    assert sorted(p.name for p in videos.iterdir()) == ["tt_spiral30.mp4"]


def test_ctrl_c_ends_the_run_in_one_line(evaluate_accuracy, tmp_path, capsys, monkeypatch):
    (tmp_path / "good.bvh").write_text("a motion")

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(evaluate_accuracy, "trial_motion", interrupted)
    assert evaluate_accuracy.main(MODEL + ["--trials", "good", "--bvh-dir", str(tmp_path),
                                           "--video-dir", str(tmp_path / "v")]) == 130
    assert capsys.readouterr().err == "evaluate_accuracy: interrupted\n"
