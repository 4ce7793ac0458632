"""Each frame's own time reaches `track`'s outputs: a video at 30 fps for 6 s and then at 10 fps
(tests/data/vfr_walk.mkv, scripts/make_vfr_clip.py) keeps its real timing in the JSON, the
MCAP and the BVH; and a file that states no length, as a recording still being written, is
tracked without a phantom track."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from sequences.bvh import read_bvh
from tests.test_track_cli import _track
from tests.test_video import without_duration

VFR_CLIP = Path(__file__).parent / "data" / "vfr_walk.mkv"
#: The clip's frame times: 180 at 30 fps, then 61 at 10 fps (6.0 to 12.0 s).
TIMES = np.r_[np.arange(180) / 30.0, 6.0 + np.arange(61) / 10.0]


@pytest.mark.slow
def test_a_variable_frame_rate_s_times_reach_the_json_the_mcap_and_the_bvh(tmp_path):
    """Every frame was stamped index / 30 fps: frame 220 at 7.33 s instead of 10.0, the
    12 s walk's outputs ending at 8.0 s."""
    out, js, bvh = tmp_path / "walk.mcap", tmp_path / "walk.json", tmp_path / "bvh"
    result = _track(VFR_CLIP, "--out", out, "--json", js, "--bvh", bvh, "--quiet",
                    cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stderr.strip() == ("track: warning: vfr_walk.mkv: variable frame rate "
                                     "(frames 33 to 100 ms apart, 30 fps announced); each "
                                     "frame keeps its own time")
    (track,) = json.loads(js.read_text())["tracks"]
    frames = np.array(track["frames"])
    assert frames[-1] == 240
    np.testing.assert_allclose(track["time_s"], TIMES[frames], atol=1e-3)   # MKV: ms
    with open(out, "rb") as f:
        messages = [(channel.topic, m.log_time, m.publish_time, json.loads(m.data))
                    for _, channel, m in make_reader(f).iter_messages(log_time_order=True)]
    for topic in ("/pose", "/smoothed/pose"):
        poses = [(log, publish, m) for name, log, publish, m in messages if name == topic]
        assert [m["frame_index"] for _, _, m in poses] == track["frames"]
        np.testing.assert_allclose([m["time_s"] for _, _, m in poses], track["time_s"])
        np.testing.assert_allclose(np.array([log for log, _, _ in poses]) / 1e9,
                                   track["time_s"], atol=1e-6)
        assert all(log == publish for log, publish, _ in poses)
    # One BVH frame every 1/30 s from the track's first frame to its last (12.0 s).
    motion = read_bvh(next(bvh.glob("*.bvh")), fps=None)
    assert motion.fps == pytest.approx(30.0)
    assert motion.n_frames == round((track["time_s"][-1] - track["time_s"][0]) * 30) + 1


@pytest.mark.slow
def test_a_video_of_unknown_length_gives_no_phantom_track(tmp_path):
    """A Matroska file still being written states no length: its background was learned from
    its first 25 frames, the walker standing in them, and a second track of 162 frames
    followed that ghost."""
    path = tmp_path / "recording.mkv"
    path.write_bytes(without_duration(VFR_CLIP.read_bytes()))
    js = tmp_path / "walk.json"
    result = _track(path, "--json", js, "--quiet", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    (track,) = json.loads(js.read_text())["tracks"]
    assert track["n_frames"] == 241
