"""The background sample's pass shared with a forked helper (tracker.video.split_sample): the
same frames as one process's pass whether the helper's half joins or not, and a Ctrl-C or an
error during it leaves no process behind."""
from __future__ import annotations

import os
import signal

import numpy as np
import pytest

import tracker.video.split_sample as split_sample
from tracker.video.decode import open_video
from tracker.video.split_sample import SampleHelper

from test_video import flat_frames, write_video


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    """200 frames (mp4v, a key frame every 12), each telling its index, with noise."""
    rng = np.random.default_rng(0)
    frames = [np.clip(f.astype(np.int16) + rng.integers(-20, 21, f.shape), 0, 255)
              .astype(np.uint8) for f in flat_frames(200, width=128, height=96)]
    return write_video(tmp_path_factory.mktemp("split") / "clip.mp4", frames)


@pytest.fixture
def joins(monkeypatch):
    """The frame index at which each shared pass took the helper's samples; the caller waits
    for the helper's message at the middle frame (a loaded machine may slow the helper)."""
    seen: list[int] = []
    rest = SampleHelper.rest

    def recording(self, index, image, capture):
        if index == self.middle:
            self._reader.poll(60.0)
        samples = rest(self, index, image, capture)
        if samples is not None:
            seen.append(index)
        return samples
    monkeypatch.setattr(SampleHelper, "rest", recording)
    return seen


def _same(a: list[np.ndarray], b: list[np.ndarray]) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))


def _alone(source, count=25, size=(64, 48)):
    return source.sample_frames(count, size=size)


def test_the_helpers_half_joins_and_the_samples_are_one_pass_s(clip, joins):
    source = open_video(clip)
    for size in ((64, 48), None):
        shared = source.sample_frames(25, size=size, two_processes=True)
        assert _same(shared, _alone(source, size=size)) and len(shared) == 25
    assert joins == [100, 100]


def test_a_short_range_is_read_alone(clip, monkeypatch):
    source = open_video(clip, end_s=100 / 25.0)          # 100 frames: under MIN_SPLIT_FRAMES
    monkeypatch.setattr(split_sample, "SampleHelper", None)     # would fail if made
    assert _same(source.sample_frames(9, two_processes=True), source.sample_frames(9))


def _shifted(read):
    """_read_from_seek landing one frame late (as an inexact seek would), but for the last."""
    def late(source, wanted, size):
        first, samples = read(source, [i + 1 for i in wanted[:-1]] + wanted[-1:], size)
        return first, [(i, image) for i, (_, image) in zip(wanted, samples, strict=True)]
    return late


@pytest.mark.parametrize("helper", ["late", "nothing", "dies"])
def test_a_helper_whose_frames_are_not_the_passes_is_not_joined(clip, joins, monkeypatch,
                                                                   helper):
    read = split_sample._read_from_seek
    broken = {"late": _shifted(read), "nothing": lambda *args: None,
              "dies": lambda *args: os._exit(3)}[helper]
    monkeypatch.setattr(split_sample, "_read_from_seek", broken)
    source = open_video(clip)
    assert _same(source.sample_frames(25, size=(64, 48), two_processes=True), _alone(source))
    assert joins == []


def test_a_ctrl_c_during_the_shared_pass_ends_the_helper_and_is_raised(clip, monkeypatch):
    helpers = []
    rest = SampleHelper.rest

    def interrupted(self, index, image, capture):
        helpers.append(self)
        if index == 50:
            raise KeyboardInterrupt
        return rest(self, index, image, capture)
    monkeypatch.setattr(SampleHelper, "rest", interrupted)
    with pytest.raises(KeyboardInterrupt):
        open_video(clip).sample_frames(25, two_processes=True)
    assert helpers and not helpers[0]._process.is_alive()


def test_the_helper_ignores_a_ctrl_c_sent_to_it(clip, joins, monkeypatch, capfd):
    """A Ctrl-C reaches every process of the terminal's group: the helper's is the caller's."""
    rest = SampleHelper.rest

    def ctrl_c_to_helper(self, index, image, capture):
        if index == 1:
            os.kill(self._process.pid, signal.SIGINT)
        return rest(self, index, image, capture)
    monkeypatch.setattr(SampleHelper, "rest", ctrl_c_to_helper)
    source = open_video(clip)
    assert _same(source.sample_frames(25, size=(64, 48), two_processes=True), _alone(source))
    assert joins == [100]
    assert "Traceback" not in capfd.readouterr().err


def test_samples_too_large_for_a_pipe_are_read_alone(clip, monkeypatch):
    monkeypatch.setattr(split_sample, "MAX_SPLIT_BYTES", 25 * 64 * 48 * 3 - 1)
    monkeypatch.setattr(split_sample, "SampleHelper", None)     # would fail if made
    source = open_video(clip)
    assert _same(source.sample_frames(25, size=(64, 48), two_processes=True), _alone(source))


def test_a_ctrl_c_as_the_helper_starts_prints_nothing(clip, joins, monkeypatch, capfd,
                                                      tmp_path):
    """Before the helper has set its own handlers (here a long start) a Ctrl-C waits for them."""
    import time
    real, started = split_sample._help, tmp_path / "started"

    def slow_start(*args):
        started.touch()
        time.sleep(0.5)
        real(*args)
    monkeypatch.setattr(split_sample, "_help", slow_start)
    made = SampleHelper.__init__

    def ctrl_c_once_started(self, *args):
        made(self, *args)
        while not started.exists():
            time.sleep(0.001)
        os.kill(self._process.pid, signal.SIGINT)
    monkeypatch.setattr(SampleHelper, "__init__", ctrl_c_once_started)
    source = open_video(clip)
    assert _same(source.sample_frames(25, size=(64, 48), two_processes=True), _alone(source))
    assert joins == [100]
    assert "Traceback" not in capfd.readouterr().err
