"""Issue 50, item 5: what a user meets first at the ``track`` command.

--version; ``track`` alone; messages in the options' terms (--start, --json, --out); cameras
and URLs; a full disk's message saying where the recording so far is kept; output names at
the file system's 255-byte limit; --bvh in a folder that does not exist.
"""
from __future__ import annotations

import json
import os
from importlib import metadata
from pathlib import Path

import pytest
from mcap.reader import make_reader

from sequences.video import Actor, write_video
from tests.test_track_cli import _assert_one_line_error, _noise_video, _track, _walker
from tracker.outputs.aside import set_aside
from tracker.outputs.files import (NAME_MAX, OutputBusyError, OutputFile, beside_name,
                                 partial_path)
from tracker.outputs.mcap_repair import recover_mcap


@pytest.fixture(scope="module")
def walk(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("walk") / "walk.mp4"
    write_video(path, [Actor(_walker(30))], size=(240, 320), noise_sigma=2.0, seed=3)
    return path


@pytest.fixture()
def video(tmp_path) -> Path:
    """A short video in tmp_path, refused before it is tracked."""
    return _noise_video(tmp_path / "v.mp4", frames=5)


def test_version_prints_the_packages_version():
    """It had said "the following arguments are required: video"."""
    result = _track("--version")
    assert result.returncode == 0
    assert result.stdout == f"track {metadata.version('silhouette-pose')}\n"


def test_track_alone_prints_the_usage_and_where_the_options_are():
    result = _track()
    assert result.returncode == 2 and result.stdout == ""
    usage, hint = result.stderr.splitlines()
    assert usage.startswith("usage: track VIDEO [--out FILE.mcap]")
    assert "track --help" in hint


@pytest.mark.parametrize("given", ["0", "rtsp://host/x", "http://host/clip.mp4"])
def test_a_camera_or_a_url_is_refused_as_such(tmp_path, given):
    """A camera index or a stream had got "no such file" (rtsp://host/x shown as rtsp:/host/x)."""
    result = _track(given, cwd=tmp_path)
    _assert_one_line_error(result, f"{given}: cameras and streams are not supported; give a "
                                   f"video file")
    assert list(tmp_path.iterdir()) == []


def test_a_file_named_like_a_camera_index_is_read_as_a_file(tmp_path):
    (tmp_path / "0").write_text("not a video")
    result = _track("0", cwd=tmp_path)
    _assert_one_line_error(result, "0:")
    assert "cameras" not in result.stderr


def test_a_start_past_the_end_names_the_option_and_the_videos_length(tmp_path, video):
    """It said "start_s=1.0 is past the end", the library's parameter."""
    result = _track(video, "--start", "1", "--json", "s.json", cwd=tmp_path)
    _assert_one_line_error(result, f"--start 1 s is past the end of {video} (0.17 s, 5 frames")
    assert "start_s" not in result.stderr
    result = _track(video, "--start", "0.1", "--end", "0.1000000000001", cwd=tmp_path)
    _assert_one_line_error(result, "no frames in the chosen time range", "--start 0.1 s")
    assert "start_s" not in result.stderr


def test_a_json_on_a_full_disk_names_the_option(tmp_path, walk):
    """It said "JsonSummarySink: /dev/full: ..."; nothing is kept of a JSON, so nothing said."""
    result = _track(walk, "--json", "/dev/full", "--end", "0.5", "--quiet", cwd=tmp_path)
    _assert_one_line_error(result, "--json /dev/full: No space left on device")
    assert "JsonSummarySink" not in result.stderr and "kept" not in result.stderr


def test_a_disk_filling_mid_recording_says_where_the_recording_so_far_is(tmp_path, walk,
                                                                        monkeypatch):
    """The MCAP keeps its partial file on a full disk: the message names the option and that
    file, which recover_mcap turns into a readable recording; the earlier file stays."""
    (tmp_path / "o.mcap").write_bytes(b"an earlier recording")
    write = OutputFile.write

    def filling(self, data):
        if self.tell() > 20_000:                # from here on the disk is full
            full = os.open("/dev/full", os.O_WRONLY)
            os.dup2(full, self._fd)
            os.close(full)
        return write(self, data)
    monkeypatch.setattr(OutputFile, "write", filling)
    result = _track(walk, "--out", "o.mcap", "--quiet", "--workers", "1", cwd=tmp_path)
    _assert_one_line_error(result, "--out o.mcap: No space left on device",
                           "the recording so far is kept in o.mcap.partial")
    assert (tmp_path / "o.mcap").read_bytes() == b"an earlier recording"
    report = recover_mcap(tmp_path / "o.mcap.partial", tmp_path / "repaired.mcap")
    assert report.messages > 0


def test_output_names_at_the_file_systems_limit_are_written(tmp_path, walk):
    """254-byte names are legal; NAME.partial is not: the run had been refused."""
    stem = "n" * 249
    result = _track(walk, "--json", f"{stem}.json", "--out", f"{stem}.mcap", "--end", "0.5",
                    "--quiet", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert json.loads((tmp_path / f"{stem}.json").read_text())["frames"] == 15
    with open(tmp_path / f"{stem}.mcap", "rb") as f:
        assert make_reader(f, validate_crcs=True).get_summary() is not None
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"{stem}.json", f"{stem}.mcap"]


def test_a_long_names_partial_file_is_locked_and_kept_aside_like_any_other(tmp_path):
    """The shortened name is the same for the same NAME (a second run finds the first's lock,
    the next run its unfinished data), and different for names that differ past the cut."""
    name = "é" * 124 + ".json"                  # 253 bytes
    partial = partial_path(tmp_path / name)
    assert len(os.fsencode(partial.name)) <= NAME_MAX and partial.name.endswith(".partial")
    assert partial == partial_path(tmp_path / name)
    assert partial != partial_path(tmp_path / ("é" * 124 + ".jsox"))
    first = OutputFile(tmp_path / name)
    with pytest.raises(OutputBusyError):
        OutputFile(tmp_path / name)
    first.write(b"an unfinished run")
    first.discard(keep=True)
    with pytest.warns(UserWarning, match="kept as"):
        aside = set_aside(partial)
    assert aside.read_bytes() == b"an unfinished run" and len(os.fsencode(aside.name)) <= 255
    assert beside_name(tmp_path / "short.json", ".partial").name == "short.json.partial"


def test_bvh_in_a_folder_that_does_not_exist_is_refused_as_json_and_out_are(tmp_path, video):
    """--bvh DIR is made if missing, but in a folder that exists: a/b had been made, a too."""
    for option, name in (("--json", "nope/s.json"), ("--out", "nope/s.mcap"),
                         ("--bvh", "nope/b")):
        result = _track(video, option, name, cwd=tmp_path)
        _assert_one_line_error(result, f"{option} {name}: folder nope does not exist")
        assert result.returncode == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.mp4"]


def test_a_video_name_too_long_for_its_bvh_files_is_refused_before_tracking(tmp_path):
    """A 250-byte stem makes STEM_0.bvh 256 bytes: refused up front, not after the tracking."""
    video = _noise_video(tmp_path / "v.mp4", frames=5).rename(tmp_path / ("v" * 250 + ".mp4"))
    result = _track(video.name, "--bvh", "b", cwd=tmp_path)
    _assert_one_line_error(result, "--bvh b: the video's name is too long", "256 bytes")
    assert sorted(p.name for p in tmp_path.iterdir()) == [video.name]
