"""Issue 8: `track` never loses the user's data, fails cleanly, and keeps memory and start-up low.

Each numbered case of the issue has a test here or beside the code it concerns (named in the
docstring). In-process (tracker.cli.main) unless a real process is the point (signals during
start-up).
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import signal
import subprocess
import sys
import time
import tracemalloc
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
from mcap.reader import make_reader

from lab.crossings import read_frames
from regressor.pose_model import load_pose_model
from sequences.video import Actor, write_video
from tests.test_track_cli import (_assert_one_line_error, _noise_video, _track, _track_process,
                                  _walker)
from tracker import PoseTracker, TrackerSettings, track_video
from tracker.run import sampled_background
from tracker.outputs.bvh import BVHSink
from tracker.outputs.files import OutputBusyError, OutputWriteError, partial_path
from tracker.outputs.json_summary import JsonSummarySink
from tracker.outputs.mcap import McapSink
from tracker.video.decode import open_video

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def walk(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("walk") / "walk.mp4"
    write_video(path, [Actor(_walker(40))], size=(240, 320), noise_sigma=2.0, seed=3)
    return path


@pytest.fixture()
def video(tmp_path) -> Path:
    """A short video in tmp_path (the refusals happen before it is decoded)."""
    return _noise_video(tmp_path / "v.mp4", frames=5)


def _refused_and_intact(result, video: Path, before: bytes, *needles) -> None:
    _assert_one_line_error(result, *needles)
    assert video.read_bytes() == before


# ------------------------------------------------------------------ 1-4: outputs that collide


@pytest.mark.parametrize("spelling", ["same", "relative", "symlink", "hardlink"])
@pytest.mark.parametrize("option", ["--out", "--json"])
def test_an_output_that_is_the_input_video_is_refused(tmp_path, video, option, spelling):
    """Cases 1 and 2."""
    before = video.read_bytes()
    (tmp_path / "sub").mkdir()
    target = {"same": "v.mp4", "relative": "sub/../v.mp4", "symlink": "link.mp4",
              "hardlink": "hard.mp4"}[spelling]
    if spelling == "symlink":
        (tmp_path / "link.mp4").symlink_to(video)
    if spelling == "hardlink":
        os.link(video, tmp_path / "hard.mp4")
    result = _track("v.mp4", option, target, cwd=tmp_path)
    _refused_and_intact(result, video, before, option, "input video")


@pytest.mark.parametrize("input_", ["model", "background"])
@pytest.mark.parametrize("option", ["--out", "--json"])
def test_an_output_that_is_the_model_or_the_background_is_refused(tmp_path, video, option,
                                                                   input_):
    """An output may not overwrite any input: the model file (given, or the shipped default
    the run would read) and the clean plate, not only the video."""
    model = ROOT / "regressor/models/default_model.npz"
    if input_ == "model":
        target, given = tmp_path / "m.npz", []
        target.symlink_to(model)             # the shipped model itself, through a link
        before = model.read_bytes()
    else:
        target = tmp_path / "plate.png"
        cv2.imwrite(str(target), np.zeros((48, 64, 3), np.uint8))
        given, before = ["--background", target], target.read_bytes()
    result = _track(video, *given, option, target, cwd=tmp_path)
    _assert_one_line_error(result, option, "the model" if input_ == "model" else "--background")
    assert (model if input_ == "model" else target).read_bytes() == before


@pytest.mark.parametrize("options", [["--json", "x", "--out", "x"],
                                     ["--bvh", "x", "--out", "x"],
                                     ["--bvh", ".", "--json", "v_1.bvh"],
                                     ["--out", "x.mcap", "--json", "x.mcap.partial"]],
                         ids=["json-is-out", "bvh-folder-is-out", "json-in-bvh-names",
                              "json-is-out-partial"])
def test_outputs_that_are_one_another_are_refused_before_writing(tmp_path, video, options):
    """Case 3."""
    result = _track(video, *options, cwd=tmp_path)
    _assert_one_line_error(result, "--")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.mp4"]      # nothing written


def test_the_default_output_of_a_video_named_mcap_is_refused(tmp_path):
    """Case 4: `track clip.mcap` would record into clip.mcap."""
    clip = _noise_video(tmp_path / "clip.mp4", frames=5).rename(tmp_path / "clip.mcap")
    before = clip.read_bytes()
    _refused_and_intact(_track("clip.mcap", cwd=tmp_path), clip, before, "default output",
                        "--out")


# ------------------------------------------------------------------ 5: one writer per output


def test_a_second_run_on_the_same_outputs_fails_at_once(tmp_path, video):
    """Case 5: the first run's sinks hold the locks; the second gets one line, quickly."""
    out, js, bvh = tmp_path / "o.mcap", tmp_path / "o.json", tmp_path / "b"
    first = [McapSink(out), JsonSummarySink(js, 30.0), BVHSink(bvh, 30.0, prefix="v")]
    try:
        for options in (["--out", out], ["--json", js], ["--bvh", bvh]):
            started = time.monotonic()
            result = _track(video, *options, cwd=tmp_path)
            _assert_one_line_error(result, "another track run")
            assert time.monotonic() - started < 5
    finally:
        for sink in first:
            sink.close()
    with open(out, "rb") as f:                     # the first run's file is not corrupted
        assert make_reader(f, validate_crcs=True).get_summary() is not None
    assert json.loads(js.read_text())["frames"] == 0
    with pytest.raises(OutputBusyError):           # the library refuses too
        with McapSink(out):
            McapSink(out)


def test_an_existing_output_is_replaced_only_when_the_new_one_is_complete(tmp_path):
    out = tmp_path / "o.mcap"
    out.write_bytes(b"old recording")
    sink = McapSink(out)
    assert out.read_bytes() == b"old recording" and partial_path(out).exists()
    sink.close()
    assert not partial_path(out).exists()
    with open(out, "rb") as f:
        assert make_reader(f, validate_crcs=True).get_summary() is not None


def test_an_earlier_runs_unfinished_recording_is_kept_aside_not_overwritten(tmp_path):
    """A kill leaves NAME.partial for recover_mcap; the next run on NAME must not truncate it:
    it is moved to NAME.partial.1 (then .2) with a warning, and an empty one is reused."""
    out = tmp_path / "o.mcap"
    partial_path(out).write_bytes(b"killed run 1")
    with pytest.warns(UserWarning,
                      match=r"o\.mcap\.partial held an earlier run.*o\.mcap\.partial\.1"):
        sink = McapSink(out)
    sink.close()
    partial_path(out).write_bytes(b"killed run 2")
    with pytest.warns(UserWarning, match=r"kept as .*o\.mcap\.partial\.2"):
        JsonSummarySink(tmp_path / "o.mcap", 30.0).close()   # any OutputFile: the JSON's too
    assert (tmp_path / "o.mcap.partial.1").read_bytes() == b"killed run 1"
    assert (tmp_path / "o.mcap.partial.2").read_bytes() == b"killed run 2"
    partial_path(out).write_bytes(b"")
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        McapSink(out).close()
    assert not (tmp_path / "o.mcap.partial.3").exists()


@pytest.mark.slow
def test_track_keeps_a_partial_file_it_finds_and_says_so_in_one_line(tmp_path, walk):
    """Through the command: the MCAP's and a BVH's NAME.partial that hold data survive a run."""
    out, bvh = tmp_path / "w.mcap", tmp_path / "bvh"
    bvh.mkdir()
    partial_path(out).write_bytes(b"an earlier recording")
    partial_path(bvh / "walk_0.bvh").write_text("someone's file")
    result = _track(walk, "--out", out, "--bvh", bvh, "--quiet", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    notices = [line for line in result.stderr.splitlines() if "kept as" in line]
    assert len(notices) == 2 and all(n.startswith("track: warning: ") for n in notices)
    assert (tmp_path / "w.mcap.partial.1").read_bytes() == b"an earlier recording"
    assert (bvh / "walk_0.bvh.partial.1").read_text() == "someone's file"
    with open(out, "rb") as f:
        assert make_reader(f, validate_crcs=True).get_summary() is not None
    assert (bvh / "walk_0.bvh").read_text().startswith("HIERARCHY")


@pytest.mark.slow
def test_a_symlinked_output_replaces_its_target_and_keeps_the_link(tmp_path, walk):
    """An output given as a symlink: the file it points to gets the result (not the link
    replaced by a regular file, the target left stale), for the JSON, the MCAP and a BVH."""
    (tmp_path / "real").mkdir()
    for name in ("s.json", "s.mcap"):
        (tmp_path / "real" / name).write_text("old")
        (tmp_path / name).symlink_to(tmp_path / "real" / name)
    result = _track(walk, "--json", "s.json", "--out", "s.mcap", "--end", "0.5", "--quiet",
                    cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "s.json").is_symlink() and (tmp_path / "s.mcap").is_symlink()
    assert json.loads((tmp_path / "real" / "s.json").read_text())["frames"] == 15
    with open(tmp_path / "real" / "s.mcap", "rb") as f:
        assert make_reader(f, validate_crcs=True).get_summary() is not None
    assert sorted(p.name for p in (tmp_path / "real").iterdir()) == ["s.json", "s.mcap"]


@pytest.mark.parametrize("mode", ["w", "a"])
@pytest.mark.slow
def test_json_to_a_stdout_redirected_to_a_file_lands_in_that_file(tmp_path, walk, mode):
    """`track V --json /dev/stdout > o.txt` (or >>; here through a link of our own to
    /proc/self/fd/1, so /dev is never at risk): written through the shell's descriptor, so
    o.txt holds what came before (>>), the JSON and the summary line after it, and the link
    stays a link."""
    (tmp_path / "fd").mkdir()
    (tmp_path / "fd" / "stdout").symlink_to("/proc/self/fd/1")
    (tmp_path / "o.txt").write_text("earlier line\n")
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    with open(tmp_path / "o.txt", mode) as out:
        code = subprocess.run([sys.executable, "-m", "tracker.cli", str(walk), "--json",
                               "fd/stdout", "--end", "0.5"], cwd=tmp_path, env=env,
                              stdout=out, stderr=subprocess.PIPE, text=True, timeout=120)
    assert code.returncode == 0, code.stderr
    text = (tmp_path / "o.txt").read_text()
    if mode == "a":
        assert text.startswith("earlier line\n")
        text = text[len("earlier line\n"):]
    assert json.loads(text)["frames"] == 15         # the summary went to stderr
    assert "tracked 15 frames" in code.stderr
    assert (tmp_path / "fd" / "stdout").is_symlink()


@pytest.mark.slow
def test_a_dash_is_standard_output(tmp_path, walk):
    """`--json -` had written a file named "-"."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    code = subprocess.run([sys.executable, "-m", "tracker.cli", str(walk), "--json", "-",
                           "--end", "0.5"], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=120)
    assert code.returncode == 0, code.stderr
    assert json.loads(code.stdout)["frames"] == 15 and "tracked 15 frames" in code.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_a_bvh_name_that_is_a_symlink_is_replaced_not_followed(tmp_path, walk):
    """BVH files are named by track, not the user: a link of that name (here to the input
    video) is replaced by the file; what it points to is left alone."""
    video = tmp_path / "walk.mp4"
    video.write_bytes(walk.read_bytes())
    (tmp_path / "bvh").mkdir()
    (tmp_path / "bvh" / "walk_0.bvh").symlink_to("../walk.mp4")
    result = _track(video, "--bvh", "bvh", "--end", "1", "--quiet", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert video.read_bytes() == walk.read_bytes()
    written = tmp_path / "bvh" / "walk_0.bvh"
    assert not written.is_symlink() and written.read_text().startswith("HIERARCHY")


@pytest.mark.parametrize("option", ["--json", "--out"])
@pytest.mark.parametrize("name", ["newdir/", "newdir/.", "newdir/.."])
def test_an_output_ending_in_a_slash_is_refused_not_written_as_a_file(tmp_path, video, option,
                                                                      name):
    result = _track(video, option, name, cwd=tmp_path)
    _assert_one_line_error(result, name, "folder")
    assert list(tmp_path.iterdir()) == [video]


def test_a_background_that_is_not_a_regular_file_is_named_as_such(tmp_path, video):
    result = _track(video, "--json", "x.json", "--background", "/dev/null", cwd=tmp_path)
    _assert_one_line_error(result, "/dev/null", "not a regular file")


def test_a_partial_file_another_run_is_writing_is_not_set_aside(tmp_path):
    out = tmp_path / "o.mcap"
    first = McapSink(out)
    first._state["stream"].write(b"x" * 10)       # the live run's partial holds data
    try:
        with pytest.raises(OutputBusyError):
            McapSink(out)
        assert not (tmp_path / "o.mcap.partial.1").exists()
    finally:
        first.close()


# ------------------------------------------------------------------ 6: a full disk


def _fill_disk(sink_file) -> None:
    """From now on, writes through this OutputFile fail with ENOSPC (as on a full disk)."""
    full = os.open("/dev/full", os.O_WRONLY)
    os.dup2(full, sink_file._fd)
    os.close(full)


def test_out_dev_full_gives_one_line_naming_the_file(tmp_path, walk):
    """Case 6: no empty file name, no finalizer traceback at exit (a real process)."""
    result = _track_process(walk, "--out", "/dev/full", "--quiet", cwd=tmp_path)
    assert result.returncode == 1
    _assert_one_line_error(result, "/dev/full", "No space left")
    assert "Exception ignored" not in result.stderr


def test_a_disk_filling_mid_recording_keeps_the_old_file_and_the_partial_one(tmp_path):
    """Case 6: MCAP cut by a full disk: one error naming the file, the old file intact, what
    was recorded left in NAME.partial for recover_mcap."""
    out = tmp_path / "o.mcap"
    out.write_bytes(b"old recording")
    sink = McapSink(out)
    _fill_disk(sink._state["stream"])
    with pytest.raises(OutputWriteError, match="o.mcap: No space left"):
        sink.close()
    assert out.read_bytes() == b"old recording"
    assert partial_path(out).exists()


def test_a_bvh_or_json_cut_by_a_full_disk_is_not_left_looking_valid(tmp_path, monkeypatch):
    """Case 6: the partial file is removed, an existing file is left as it was."""
    bvh = BVHSink(tmp_path, 30.0, prefix="t")
    pose = np.r_[1.0, np.zeros(54)]
    from tracker import TrackedPose
    for frame in range(3):
        bvh.write(TrackedPose(frame, frame / 30, 1, pose, pose, False, np.zeros((18, 3))))
    (tmp_path / "t_1.bvh").write_text("old")

    def half_then_full(path, motion):
        Path(path).write_text("HIERARCHY\nROOT Hips\n")
        raise OSError(28, "No space left on device")
    monkeypatch.setattr("tracker.outputs.bvh.write_bvh", half_then_full)
    with pytest.raises(OutputWriteError, match="t_1.bvh: No space left"):
        bvh.close()
    assert (tmp_path / "t_1.bvh").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t_1.bvh"]     # no partial, no lock
    js = JsonSummarySink(tmp_path / "s.json", 30.0)
    _fill_disk(js._file)
    with pytest.raises(OutputWriteError, match="s.json: No space left"):
        js.close()
    assert not (tmp_path / "s.json").exists() and not partial_path(tmp_path / "s.json").exists()


# ------------------------------------------------------------------ 7-9: signals


def test_the_command_module_imports_only_the_standard_library():
    """What makes the start-up Ctrl-C safe: numpy and OpenCV load inside main(), where the
    interrupt is caught; a module-level import of tracker.video.roll once loaded OpenCV before."""
    code = ("import sys, tracker.cli; "
            "print(sorted(m for m in ('cv2', 'numpy', 'scipy') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(ROOT)}, check=True).stdout
    assert out.strip() == "[]"


def _wait_for_mapped(proc: subprocess.Popen, name: str, timeout: float = 30.0) -> bool:
    """Wait until the child process has a file whose path holds ``name`` mapped (Linux /proc):
    True when it has, False if the process ended or the time ran out first."""
    maps, end = Path(f"/proc/{proc.pid}/maps"), time.monotonic() + timeout
    while proc.poll() is None and time.monotonic() < end:
        with contextlib.suppress(OSError):
            if name in maps.read_text():
                return True
        time.sleep(0.002)
    return False


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="needs Linux's /proc")
def test_ctrl_c_during_start_up_gives_no_traceback(tmp_path, walk):
    """Case 7: while numpy, OpenCV and the model are imported (a real process). The signal is
    sent once numpy's extension is mapped (main() imports it after installing its handler):
    a fixed delay would also land in Python's own start-up on a loaded machine, where CPython's
    default handler prints its traceback, or the default action kills it silently. Exit 130; or
    death by SIGINT (-2, which a shell also reports as 130) when the interrupt passed through an
    extension module's initialisation, which makes CPython re-raise it at exit."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    for delay in (0.0, 0.2):
        proc = subprocess.Popen([sys.executable, "-m", "tracker.cli", str(walk), "--json",
                                 str(tmp_path / "s.json")], env=env, stderr=subprocess.PIPE,
                                text=True, cwd=tmp_path)
        assert _wait_for_mapped(proc, "_multiarray_umath"), "track never imported numpy"
        time.sleep(delay)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
        assert "Traceback" not in err, err
        assert proc.returncode in (130, -signal.SIGINT), err
        assert err.strip() == "track: interrupted", err


class _InterruptedWhileClosing:
    """A sink whose close() is hit by a second Ctrl-C (as a user pressing twice)."""

    def write(self, pose):
        pass

    def end_frame(self, frame_index):
        if frame_index == 5:
            raise KeyboardInterrupt            # the first Ctrl-C, during the loop

    def close(self):
        os.kill(os.getpid(), signal.SIGINT)    # the second one, while outputs close
        time.sleep(0.05)                       # delivered here, between two bytecodes


@pytest.mark.slow
def test_a_second_ctrl_c_while_closing_does_not_lose_the_json_or_bvh(tmp_path, walk):
    """Case 8: the JSON and BVH sinks closed after the interrupted one are still written."""
    js, bvh = JsonSummarySink(tmp_path / "s.json", 30.0), BVHSink(tmp_path / "b", 30.0)
    result = track_video(walk, sinks=[_InterruptedWhileClosing(), js, bvh])
    assert result.interrupted and result.frames == 6          # frames 0-5 were written
    assert json.loads((tmp_path / "s.json").read_text())["frames"] == 6
    assert js.closed and bvh.closed


class _InterruptAt:
    """A sink that takes a Ctrl-C once frame ``frame_index`` has been written."""

    def __init__(self, frame_index: int):
        self.frame_index = frame_index

    def write(self, pose):
        pass

    def end_frame(self, frame_index):
        if frame_index == self.frame_index:
            raise KeyboardInterrupt

    def close(self):
        pass


@pytest.mark.slow
def test_after_a_ctrl_c_the_run_counts_the_poses_the_outputs_hold(tmp_path, walk):
    """The tracker works in batches of frames, so when a Ctrl-C stops the outputs it may have
    gone further; the run's per-track counts (track's summary) are those of the outputs."""
    js = JsonSummarySink(tmp_path / "s.json", 30.0)
    result = track_video(walk, sinks=[js, _InterruptAt(20)])
    assert result.interrupted and result.frames == 21         # frames 0-20 were written
    held = {t["id"]: len(t["frames"]) for t in json.loads((tmp_path / "s.json").read_text())
            ["tracks"]}
    assert held and {t: c.poses for t, c in result.written.items()} == held
    reached = {t: state.frames for t, state in result.tracker.tracks.items()}
    assert sum(reached.values()) > sum(held.values())       # the batch went past frame 20


# ------------------------------------------------------------------ 10, 11: odd input


@pytest.mark.parametrize("options, needle", [
    (["--start", "1e308"], "--start"), (["--end", "1e308"], "--end"),
    (["--end", "1e-12"], "no frames in the chosen time range")],
    ids=["start-1e308", "end-1e308", "end-1e-12"])
def test_absurd_times_are_option_errors(tmp_path, walk, options, needle):
    """Case 10."""
    result = _track(walk, *options, "--json", tmp_path / "s.json", cwd=tmp_path)
    assert result.returncode == 1
    _assert_one_line_error(result, needle)
    assert "OverflowError" not in result.stderr


def cut_off_avi(folder: Path) -> Path:
    """folder/cut.avi: the first half of the bytes of a 40-frame MJPG video (an index-less
    AVI decodes up to the cut, then stops)."""
    avi = folder / "a.avi"
    writer = cv2.VideoWriter(str(avi), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (160, 120))
    scene = np.random.default_rng(0).integers(60, 200, (120, 160, 3), dtype=np.uint8)
    for _ in range(40):
        writer.write(scene)
    writer.release()
    data = avi.read_bytes()
    (folder / "cut.avi").write_bytes(data[: len(data) // 2])
    return folder / "cut.avi"


def test_a_cut_off_avi_gives_a_one_line_warning(tmp_path):
    """Case 11: tracked up to the cut, one "track: warning:" line, no Python source line."""
    cut_off_avi(tmp_path)
    result = _track("cut.avi", "--json", "s.json", "--quiet", cwd=tmp_path)
    assert result.returncode == 0
    assert result.stderr.strip().startswith("track: warning: cut.avi: decoding stopped")
    assert len(result.stderr.strip().splitlines()) == 1


def test_a_start_past_what_decodes_is_one_line_naming_the_file(tmp_path):
    """--start beyond a cut-off file's last decodable frame (within the length the container
    announces) said "median_background needs at least one frame"."""
    cut_off_avi(tmp_path)
    result = _track("cut.avi", "--json", "s.json", "--start", "1.2", cwd=tmp_path)
    assert result.returncode == 1
    _assert_one_line_error(result, "cut.avi: no decodable frames from 1.2 s on")
    assert not (tmp_path / "s.json").exists()


@pytest.mark.slow
def test_black_frames_before_the_scene_are_no_background_and_no_person(tmp_path, walk):
    """80 black frames, then the walk: the background had been learned black, so every
    frame's "person" was the whole image; a black frame inside made one such pose too."""
    frames = list(read_frames(walk))
    black = np.zeros_like(frames[0])
    frames[20] = black                                          # a glitch inside the walk
    path = tmp_path / "fade.mp4"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0,
                             (black.shape[1], black.shape[0]))
    for frame in [black] * 80 + frames:
        writer.write(frame)
    writer.release()
    result = _track(path, "--json", "s.json", "--quiet", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "divide" not in result.stderr
    (track,) = json.loads((tmp_path / "s.json").read_text())["tracks"]
    assert track["first_frame"] >= 80 and 80 + 20 not in track["frames"]
    width = black.shape[1]
    # The walker, not the image: the centroids move along the walk, away from the centre.
    xs = np.array(track["centroid_px"])[:, 0]
    assert xs.max() - xs.min() > width / 4


# ------------------------------------------------------------------ 15-18: resources


@pytest.mark.slow
def test_without_smoothing_the_tracker_keeps_no_per_frame_history(walk):
    """Case 15: memory flat over a long video (`track` keeps histories only to smooth a JSON or
    BVH output)."""
    tracker = PoseTracker(load_pose_model(), 30.0, TrackerSettings(keep_history=False))
    track_video(walk, tracker)
    (state,) = tracker.tracks.values()
    assert state.frames >= 30 and state.hypotheses.history == []
    with pytest.raises(ValueError, match="keep_history"):
        track_video(walk, tracker, smoothed_sinks=[JsonSummarySink(walk.with_suffix(".j"), 30)])


@pytest.mark.slow
def test_a_4k_video_is_tracked_with_its_background_sampled_at_the_working_size(tmp_path):
    """Case 16: no 25 full 4K frames in memory (peak was 2.18 GB), and the video runs."""
    large = tmp_path / "large.mp4"
    writer = cv2.VideoWriter(str(large), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (3840, 2160))
    scene = np.random.default_rng(0).integers(60, 200, (2160, 3840, 3), dtype=np.uint8)
    for shift in range(4):
        writer.write(np.roll(scene, shift, axis=1))
    writer.release()
    source = open_video(large)
    tracker = PoseTracker(load_pose_model(), source.fps)
    tracemalloc.start()
    try:
        background, _ = sampled_background(source, tracker)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    width, height = tracker.extractor.subtractor.working_size(3840, 2160)
    assert background.shape == (height, width, 3) and width < 3840
    assert peak < 120e6                        # a few full frames at most (25 MB each)
    result = _track(large, "--json", tmp_path / "l.json", "--quiet", cwd=tmp_path)
    # It runs through (the scene is empty, so it ends with that one-line error).
    assert result.returncode == 1 and "nobody found in its 4 frames" in result.stderr
    assert "Traceback" not in result.stderr


def test_background_samples_are_read_in_one_pass_not_by_seeking(walk, monkeypatch):
    """Case 17: a seek decodes from a key frame (seconds on long-GOP H.264); a short clip is
    sampled with one sequential pass and gives the frames a seek would."""
    import tracker.video.decode as video_module
    seeks = []
    real = video_module._seek
    monkeypatch.setattr(video_module, "_seek",
                        lambda cap, i, *more: seeks.append(i) or real(cap, i, *more))
    source = open_video(walk)
    frames = source.sample_frames(25)
    assert seeks == [0]
    wanted = np.linspace(0, 39, 25).round().astype(int)
    decoded = [image for index, _, image in source]
    assert all(np.array_equal(f, decoded[i]) for f, i in zip(frames, np.unique(wanted)))


def test_grayscale_video_gives_the_same_single_track_as_colour(tmp_path, walk):
    """Case 18: without colour, MOG2 took the person for a shadow and cut them up."""
    capture, grey = cv2.VideoCapture(str(walk)), tmp_path / "grey.mp4"
    writer = cv2.VideoWriter(str(grey), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (320, 240),
                             False)
    while (frame := capture.read()[1]) is not None:
        writer.write(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY))
    writer.release()
    result = _track(grey, "--json", tmp_path / "g.json", "--quiet", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert len(json.loads((tmp_path / "g.json").read_text())["tracks"]) == 1


@pytest.mark.slow
def test_novelty_is_reported_per_pose_by_default_and_unfamiliar_frames_are_counted(walk, tmp_path):
    """TrackerSettings() gives each pose the model's novelty (TrackerSettings(novelty=False):
    None) and counts a track's frames above UNFAMILIAR_NOVELTY; the JSON summary records both."""
    from tracker import PoseRecorder
    from tracker.cli import _print_summary
    for asked in (False, True):
        recorder = PoseRecorder()
        track_video(walk, PoseTracker(load_pose_model(), 30.0, TrackerSettings(novelty=asked)),
                    sinks=[recorder])
        values = [p.novelty for p in recorder.poses]
        assert len(values) >= 30
        if asked:
            assert all(isinstance(v, float) and np.isfinite(v) and 0 < v < 1 for v in values)
        else:
            assert all(v is None for v in values)
    # A model that finds every other frame unlike its training silhouettes (one row per
    # frame: one person in view).
    model, rows = load_pose_model(), []
    answer = model.hypotheses

    def hypotheses(stacked, *args, **kwargs):
        first = len(rows)
        rows.extend(range(first, first + len(stacked)))
        return replace(answer(stacked, *args, **kwargs), novelty=np.array(
            [2.0 if i % 2 == 0 else 0.5 for i in range(first, len(rows))]))
    model.hypotheses = hypotheses
    tracker = PoseTracker(model, 30.0)
    summary = JsonSummarySink(tmp_path / "n.json", 30.0)
    result = track_video(walk, tracker, sinks=[summary])
    (state,) = result.written.values()          # the poses written, and the unfamiliar
    assert state.poses == len(rows) >= 30 and state.unfamiliar == (len(rows) + 1) // 2
    (track,) = json.loads((tmp_path / "n.json").read_text())["tracks"]
    assert track["novelty"][:4] == [2.0, 0.5, 2.0, 0.5]
    assert track["unfamiliar_frames"] == state.unfamiliar
    args = argparse.Namespace(video=walk, out=None, json=None, bvh=None, lag=None, view=False)
    source = argparse.Namespace(width=320, height=240, fps=30.0)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        _print_summary(args, source, result)
    assert (f"{state.poses} frames; {state.unfamiliar} of them "
            f"({state.unfamiliar / state.poses:.0%}) unlike the training silhouettes") \
        in out.getvalue()



def _swallowing(function):
    """function, except that it first sends this process a SIGINT and swallows the
    KeyboardInterrupt, as a library with a bare except would."""
    def wrapped(*args, **kwargs):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)                      # the handler runs here, inside the try
        except BaseException:
            pass
        return function(*args, **kwargs)
    return wrapped


def test_a_ctrl_c_swallowed_during_start_up_still_stops_the_command(tmp_path, walk, monkeypatch):
    import regressor.pose_model
    from tracker import cli
    signal.signal(signal.SIGINT, signal.default_int_handler)
    monkeypatch.setattr(regressor.pose_model, "load_pose_model",
                        _swallowing(regressor.pose_model.load_pose_model))
    out = tmp_path / "s.json"
    assert cli.main([str(walk), "--json", str(out), "--quiet"]) == cli.EXIT_INTERRUPTED
    assert not out.exists() and not cli._interrupts
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


class _InterruptedInFinalizer:
    """An object whose finalizer takes the Ctrl-C, where Python cannot raise it: as the import
    system's module-lock callback did when a Ctrl-C came during start-up's imports (CPython
    then printed "Exception ignored in ... Traceback ... KeyboardInterrupt")."""

    def __del__(self):
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)                          # the handler runs here, inside __del__


def test_a_ctrl_c_taken_by_a_finalizer_stops_the_command_in_one_line(tmp_path, walk,
                                                                     monkeypatch, capsys):
    import regressor.pose_model
    from tracker import cli
    signal.signal(signal.SIGINT, signal.default_int_handler)
    load = regressor.pose_model.load_pose_model

    def load_while_a_finalizer_takes_a_ctrl_c(*args, **kwargs):
        _InterruptedInFinalizer()                 # dropped at once: its __del__ runs here
        return load(*args, **kwargs)
    monkeypatch.setattr(regressor.pose_model, "load_pose_model",
                        load_while_a_finalizer_takes_a_ctrl_c)
    reported = []                   # what Python's default hook would print as a traceback
    monkeypatch.setattr(sys, "unraisablehook", reported.append)
    out = tmp_path / "s.json"
    assert cli.main([str(walk), "--json", str(out), "--quiet"]) == cli.EXIT_INTERRUPTED
    assert reported == []
    err = capsys.readouterr().err
    assert err == "track: interrupted\n", err
    assert not out.exists() and not cli._interrupts
    assert sys.unraisablehook == reported.append          # restored


def test_other_unraisable_exceptions_still_reach_the_previous_hook(monkeypatch):
    from tracker import cli
    seen = []
    monkeypatch.setattr(cli, "_previous_unraisable_hook", seen.append)
    monkeypatch.setattr(cli, "_interrupts", [])

    class Unraisable:
        def __init__(self, exc_type):
            self.exc_type = exc_type
    cli._unraisable_interrupt_recorded(Unraisable(KeyboardInterrupt))
    assert seen == [] and cli._interrupts == [signal.SIGINT]
    other = Unraisable(ValueError)
    cli._unraisable_interrupt_recorded(other)
    assert seen == [other]


def test_a_ctrl_c_swallowed_while_tracking_stops_at_the_next_frame_written(tmp_path, walk,
                                                                          monkeypatch):
    from tracker import cli
    from tracker.frame_worker import BATCH_FRAMES
    from tracker.pipeline import PoseTracker
    signal.signal(signal.SIGINT, signal.default_int_handler)
    # track_frames: the half of the work done in the main process, a batch of frames at a
    # time, also when a frame worker finds the people (`track`'s default on two cores)
    track_frames, calls = PoseTracker.track_frames, []

    def tracking_swallowing_in_the_second_batch(self, frames):
        calls.append(len(frames))
        if len(calls) == 2:
            return _swallowing(track_frames)(self, frames)
        return track_frames(self, frames)
    monkeypatch.setattr(PoseTracker, "track_frames", tracking_swallowing_in_the_second_batch)
    out = tmp_path / "s.json"
    assert cli.main([str(walk), "--json", str(out), "--quiet"]) == cli.EXIT_INTERRUPTED
    # closed properly, cut after the first frame of the second batch was written
    assert calls == [BATCH_FRAMES, BATCH_FRAMES]
    assert json.loads(out.read_text())["frames"] == BATCH_FRAMES + 1


@pytest.mark.slow
def test_a_ctrl_c_while_tracking_with_a_lag_writes_every_frame_given_to_the_smoother(
        tmp_path, walk, monkeypatch):
    """`track --lag`: a Ctrl-C that lands while tracking (recorded by track's handler, acted on
    at the next frame written) still gets the frames held back written, smoothed over what was
    tracked, into the JSON and BVH, which say so. Before 2026-12-04's fix their tracks came
    out empty: the flush's progress update raised the stop again."""
    from tracker import cli
    from tracker.frame_worker import BATCH_FRAMES
    signal.signal(signal.SIGINT, signal.default_int_handler)
    track_frames, calls = PoseTracker.track_frames, []

    def stopped_in_the_third_batch(self, frames):          # the walk's last (40 frames)
        calls.append(len(frames))
        if len(calls) == 3:
            os.kill(os.getpid(), signal.SIGINT)
        return track_frames(self, frames)
    monkeypatch.setattr(PoseTracker, "track_frames", stopped_in_the_third_batch)
    out, bvh = tmp_path / "s.json", tmp_path / "b"
    assert cli.main([str(walk), "--json", str(out), "--bvh", str(bvh), "--lag", "0.3",
                     "--workers", "1", "--quiet"]) == cli.EXIT_INTERRUPTED
    summary = json.loads(out.read_text())
    # The stop lands while the third batch is tracked: the two batches given to the
    # smoother are all written (a 0.3 s lag holds 17 frames back at 30 fps).
    assert summary["poses"] == "fixed-lag smoothed" and summary["frames"] == 2 * BATCH_FRAMES
    (track,) = summary["tracks"]
    assert track["frames"] == list(range(track["first_frame"], 2 * BATCH_FRAMES))
    assert len(list(bvh.glob("*.bvh"))) == 1


def test_a_signal_the_shell_ignores_stays_ignored(tmp_path):
    from tracker import cli
    previous = signal.signal(signal.SIGHUP, signal.SIG_IGN)      # as under nohup
    try:
        assert cli.main([str(tmp_path / "missing.mp4"), "--quiet"]) == cli.EXIT_ERROR
        assert signal.getsignal(signal.SIGHUP) == signal.SIG_IGN
    finally:
        signal.signal(signal.SIGHUP, previous)


@pytest.mark.slow
def test_a_ctrl_c_just_before_the_outputs_close_does_not_cut_them_short(tmp_path, walk,
                                                                       monkeypatch):
    """A Ctrl-C in the window between the end of the loop and the signals being held (here
    raised on the first attempt to hold them for closing, after the 40 frames' own holds
    while their outputs were written): the run counts as interrupted and every output is
    still closed complete."""
    import tracker.run as run
    held, attempts = run._signals_held, []

    def interrupted_once():
        attempts.append(1)
        if len(attempts) == 41:
            raise KeyboardInterrupt
        return held()
    monkeypatch.setattr(run, "_signals_held", interrupted_once)
    js, bvh = JsonSummarySink(tmp_path / "s.json", 30.0), BVHSink(tmp_path / "b", 30.0)
    result = track_video(walk, sinks=[js, bvh])
    assert result.interrupted and len(attempts) == 42
    assert json.loads((tmp_path / "s.json").read_text())["frames"] == result.frames == 40
    assert js.closed and bvh.closed


class _CtrlCAtFrame5:
    """A sink that raises the user's Ctrl-C at frame 5."""

    def write(self, pose):
        pass

    def end_frame(self, frame_index):
        if frame_index == 5:
            raise KeyboardInterrupt

    def close(self):
        pass


@pytest.mark.slow
def test_a_ctrl_c_leaves_the_smoothed_outputs_the_filtered_poses_so_far(tmp_path, walk):
    """The JSON and BVH are smoothed at the end by default; a Ctrl-C asks for a quick exit,
    so they get the frames tracked so far, filtered (and the JSON says so), not nothing."""
    tracker = PoseTracker(load_pose_model(), 30.0, TrackerSettings(keep_history=True))
    js = JsonSummarySink(tmp_path / "s.json", 30.0, poses="smoothed")
    bvh = BVHSink(tmp_path / "b", 30.0, prefix="walk", min_frames=2)
    result = track_video(walk, tracker, sinks=[_CtrlCAtFrame5()], smoothed_sinks=[js, bvh])
    assert result.interrupted and result.frames == 6          # frames 0-5 were written
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["poses"] == "filtered"
    (track,) = summary["tracks"]
    assert 3 <= track["n_frames"] <= 6
    assert track["n_frames"] == result.written[track["id"]].poses
    assert len(list((tmp_path / "b").glob("*.bvh"))) == 1


class _SignalMidWrite:
    """A sink that gets Ctrl-C half-way through writing frame ``frame_index`` (as the MCAP
    writer can, between a chunk's bytes and its index) and then finishes that write."""

    def __init__(self, frame_index: int):
        self.frame_index, self.frames, self.finished_writes = frame_index, [], 0
        self.signalled = self.closed = False

    def write(self, pose):
        if pose.frame_index == self.frame_index and not self.signalled:
            self.signalled = True
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)                 # delivered here, between two bytecodes
        self.finished_writes += 1

    def end_frame(self, frame_index):
        self.frames.append(frame_index)

    def close(self):
        self.closed = True


@pytest.mark.slow
def test_a_ctrl_c_during_an_outputs_write_waits_for_the_frame_to_be_written(walk):
    """The signal stops the run after the frame whose write it interrupted, not inside it:
    every write begun is finished, the frame is ended in every sink and counted."""
    first, second = _SignalMidWrite(12), _SignalMidWrite(-1)
    result = track_video(walk, sinks=[first, second])
    assert result.interrupted
    assert first.frames == second.frames == list(range(13))       # frames 0-12, all ended
    assert result.frames == 13
    assert first.finished_writes == second.finished_writes == sum(
        c.poses for c in result.written.values())
    assert first.closed and second.closed


# ------------------------------------------------------------------ runs that write nothing


def test_a_stop_before_anyone_is_tracked_keeps_an_earlier_json(tmp_path):
    """A Ctrl-C before the first pose had replaced an earlier run's JSON with an empty one."""
    earlier = tmp_path / "e.json"
    earlier.write_text('{"tracks": ["an earlier run"]}')
    source = open_video(_noise_video(tmp_path / "empty.mp4", frames=20))
    run = track_video(source, sinks=[JsonSummarySink(earlier, 30.0), _InterruptAt(5)],
                      write_empty=False)
    assert run.interrupted and not run.written
    assert earlier.read_text() == '{"tracks": ["an earlier run"]}'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e.json", "empty.mp4"]


def test_a_track_without_a_single_pose_is_nobody_found(tmp_path):
    """A thin bar is matched as a track, but no silhouette of it can be described: the run
    had exited 0 with the earlier run's JSON left in place as if it were this one's."""
    path = tmp_path / "bar.mp4"
    scene = np.random.default_rng(0).integers(60, 200, (240, 320, 3), dtype=np.uint8)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (320, 240))
    for i in range(90):
        frame = scene.copy()
        frame[20 + 2 * i:26 + 2 * i, 50:270] = 255           # a bar 220 x 6 px, sinking
        writer.write(frame)
    writer.release()
    (tmp_path / "out.json").write_text('{"old": true}')
    result = _track(path, "--json", "out.json", cwd=tmp_path)
    _assert_one_line_error(result, "nobody found in its 90 frames")
    assert result.returncode == 1 and (tmp_path / "out.json").read_text() == '{"old": true}'


@pytest.mark.slow
def test_nobody_found_with_the_mcap_on_standard_output_leaves_it_readable(tmp_path):
    """Streamed in place, the recording cannot be taken back: it is finished, empty."""
    video = _noise_video(tmp_path / "empty.mp4", frames=10)
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    run = subprocess.run([sys.executable, "-m", "tracker.cli", str(video), "--out", "-"],
                         cwd=tmp_path, env=env, capture_output=True, timeout=120)
    assert run.returncode == 1 and b"nobody found" in run.stderr
    reader = make_reader(io.BytesIO(run.stdout), validate_crcs=True)
    assert reader.get_summary() is not None and list(reader.iter_messages()) == []


def test_a_plate_check_past_what_decodes_names_the_file(tmp_path):
    cut_off_avi(tmp_path)
    cv2.imwrite(str(tmp_path / "plate.png"), np.full((120, 160, 3), 128, np.uint8))
    result = _track("cut.avi", "--json", "s.json", "--start", "1.2", "--background",
                    "plate.png", cwd=tmp_path)
    _assert_one_line_error(result, "cut.avi: no decodable frames from 1.2 s on")


def test_only_black_or_white_frames_are_left_out_of_the_learned_background():
    """An evenly lit plain backdrop is flat too, but a picture of the scene: leaving it out
    had put the person into the background (a ghost track over the empty frames)."""
    from tracker.run import _blank
    rng = np.random.default_rng(0)
    noisy = lambda level: np.clip(level + rng.normal(0, 0.5, (120, 160, 3)), 0, 255).astype(
        np.uint8)
    assert _blank(noisy(3)) and _blank(noisy(252))
    assert not _blank(noisy(175))                       # a grey studio backdrop
    assert not _blank(rng.integers(0, 40, (120, 160, 3), dtype=np.uint8))   # a dark scene


class _Frames:
    """A stand-in VideoSource giving fixed sample frames."""

    def __init__(self, frames):
        self.frames, self.height, self.width = frames, *frames[0].shape[:2]

    def sample_frames(self, count, size=None):
        return [cv2.resize(f, size, interpolation=cv2.INTER_AREA) for f in self.frames]


def test_a_grey_rooms_plate_is_accepted_though_its_person_wears_colour():
    """The video's colour was judged on one frame, person included: a red top in a grey room
    made a true plate "grey against colour"."""
    from tracker.clean_plate import check_plate
    rng = np.random.default_rng(1)
    grey = cv2.GaussianBlur(rng.integers(40, 220, (240, 320), dtype=np.uint8), (9, 9), 0)
    plate = cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR)
    frames = []
    for i in range(5):
        frame = plate.copy()
        frame[60:200, 40 + 50 * i:80 + 50 * i] = (40, 40, 200)     # a red top, walking
        frames.append(frame)
    check_plate(_Frames(frames), plate)                # no error
