"""Issue 50, item 1: a run that ends before its first pose leaves every existing file as it was.

The outputs are opened in turn (the MCAP, then the JSON, then the BVH folder's lock), so a
refusal after the first left those already opened to be finished: their empty files were
renamed onto the user's. Every way such a run ends is checked against every output kind:
a later output that cannot be opened, a lock another run holds, a video error or a Ctrl-C
before the first pose.
"""
from __future__ import annotations

import gc
import json
from pathlib import Path

import pytest
from mcap.reader import make_reader

from sequences.video import Actor, write_video
from tests.test_track_cli import _assert_one_line_error, _track, _walker
from tests.test_track_safety import cut_off_avi
from tracker.outputs import open_sinks
from tracker.outputs.bvh import BVHSink
from tracker.outputs.files import OutputBusyError
from tracker.outputs.json_summary import JsonSummarySink
from tracker.outputs.mcap import McapSink

EARLIER = {"keep.mcap": b"an earlier recording", "ok.json": b'{"tracks": ["an earlier run"]}',
           "b/cut_0.bvh": b"HIERARCHY an earlier run's track"}


def _earlier_outputs(folder: Path) -> None:
    """An earlier run's MCAP, JSON and BVH file, as the refused run's outputs will name them."""
    (folder / "b").mkdir()
    for name, data in EARLIER.items():
        (folder / name).write_bytes(data)


def _left_as_they_were(folder: Path, *allowed: str) -> None:
    """The earlier outputs hold what they held and nothing new is left (no NAME.partial, no
    lock file, no empty summary), but for ``allowed`` (names in folder, or in folder/b)."""
    gc.collect()                    # an MCAP sink left open would be finished by its finalizer
    assert {name: (folder / name).read_bytes() for name in EARLIER} == EARLIER
    names = {p.relative_to(folder).as_posix() for p in folder.rglob("*")}
    assert names == {"b", "cut.avi", "a.avi", *EARLIER, *allowed}


def _refused(folder: Path, *options: str):
    return _track("cut.avi", "--out", "keep.mcap", "--json", "ok.json", "--bvh", "b",
                  *options, cwd=folder)


def test_a_later_output_that_cannot_be_opened_leaves_the_opened_ones_unwritten(tmp_path):
    """The BVH folder's lock cannot be made (here its name is a folder): the MCAP and the JSON,
    opened before it, had become a 0-message recording and a 0-frame summary."""
    cut_off_avi(tmp_path)
    _earlier_outputs(tmp_path)
    (tmp_path / "b" / ".cut.bvh.lock").mkdir()
    result = _refused(tmp_path)
    _assert_one_line_error(result, "--bvh b/.cut.bvh.lock: cannot create (Is a directory)")
    _left_as_they_were(tmp_path, "b/.cut.bvh.lock")


@pytest.mark.parametrize("held", ["json", "bvh"])
def test_a_lock_another_run_holds_leaves_the_opened_outputs_unwritten(tmp_path, held):
    """A second run sharing the --json (or --bvh folder) of a running one: its --out (and
    --json) had lost what they held."""
    cut_off_avi(tmp_path)
    _earlier_outputs(tmp_path)
    running = (JsonSummarySink(tmp_path / "ok.json", 30.0) if held == "json"
               else BVHSink(tmp_path / "b", 30.0, prefix="cut"))
    try:
        result = _refused(tmp_path)
        _assert_one_line_error(result, f"--{held} ", "another track run is writing this "
                                                   "output")
        assert "kept in" not in result.stderr
        _left_as_they_were(tmp_path, "ok.json.partial" if held == "json"
                           else "b/.cut.bvh.lock")
    finally:
        running.abandon()


def test_a_video_error_before_the_first_pose_leaves_every_output_unwritten(tmp_path):
    """All three outputs are open when the video fails (nothing decodes from --start on)."""
    cut_off_avi(tmp_path)
    _earlier_outputs(tmp_path)
    result = _refused(tmp_path, "--start", "1.2")
    _assert_one_line_error(result, "cut.avi: no decodable frames from 1.2 s on")
    _left_as_they_were(tmp_path)


@pytest.mark.parametrize("where", ["tracker_settings", "_prime"])
def test_a_ctrl_c_before_the_first_pose_leaves_every_output_unwritten(tmp_path, monkeypatch,
                                                                       where):
    """A Ctrl-C once the outputs are open: before the tracking loop starts (the sinks had been
    left open, the MCAP's finalizer finishing an empty recording over the earlier one, the
    JSON's partial file and the BVH lock left behind) or while it learns the background."""
    cut_off_avi(tmp_path)
    _earlier_outputs(tmp_path)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(("tracker.cli." if where == "tracker_settings" else "tracker.run.")
                        + where, interrupted)
    result = _refused(tmp_path)
    assert result.returncode == 130 and "Traceback" not in result.stderr
    _left_as_they_were(tmp_path)


def test_a_refused_run_leaves_no_bvh_folder_it_made(tmp_path, monkeypatch):
    """--bvh names a new folder, which the sink makes; a run stopped before the tracking loop
    had left it (and its lock file) behind."""
    cut_off_avi(tmp_path)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr("tracker.cli.tracker_settings", interrupted)
    result = _track("cut.avi", "--bvh", "new", cwd=tmp_path)
    assert result.returncode == 130
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.avi", "cut.avi"]


@pytest.mark.parametrize("order", [("mcap", "json", "bvh"), ("bvh", "json", "mcap"),
                                   ("json", "bvh", "mcap")])
def test_open_sinks_abandons_every_kind_opened_before_a_refusal(tmp_path, order):
    """The library's rule, for each output kind opened before the one refused."""
    _earlier_outputs(tmp_path)
    (tmp_path / "a.avi").touch()
    (tmp_path / "cut.avi").touch()
    makers = {"mcap": lambda: McapSink(tmp_path / "keep.mcap"),
              "json": lambda: JsonSummarySink(tmp_path / "ok.json", 30.0),
              "bvh": lambda: BVHSink(tmp_path / "b", 30.0, prefix="cut")}

    def refused():
        raise OutputBusyError("another track run is writing this output")
    with pytest.raises(OutputBusyError):
        open_sinks([makers[kind] for kind in order] + [refused])
    _left_as_they_were(tmp_path)


def test_a_video_name_too_long_for_the_bvh_lock_name_is_tracked(tmp_path):
    """A legal 251-byte video name makes the lock ".STEM.bvh.lock" 257 bytes: the run had been
    refused after its MCAP and JSON were opened, replacing them with empty ones. The lock and
    the BVH's partial file take shorter names (tracker.outputs.files.beside_name)."""
    video = tmp_path / ("w" * 247 + ".mp4")
    write_video(tmp_path / "w.mp4", [Actor(_walker(30))], size=(240, 320), noise_sigma=2.0,
                seed=3)
    (tmp_path / "w.mp4").rename(video)
    result = _track(video.name, "--bvh", "b", "--json", "ok.json", "--out", "keep.mcap",
                    "--quiet", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert json.loads((tmp_path / "ok.json").read_text())["frames"] == 30
    with open(tmp_path / "keep.mcap", "rb") as f:
        assert len(list(make_reader(f, validate_crcs=True).iter_messages())) > 30
    assert [p.name for p in (tmp_path / "b").iterdir()] == ["w" * 247 + "_0.bvh"]
