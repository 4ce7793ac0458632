"""The live view's player: calls made in order at their video times, from a thread, behind a
buffer bounded in video time; a stop drops what waits; an error is kept, never a hang."""
from __future__ import annotations

import os
import signal
import threading
import time
import warnings

import numpy as np
import pytest

from tracker import TrackedPose
from tracker.outputs.meshcat_view import MeshcatView, ViewLostWarning
from tracker.outputs.geometry import SinkInputError, pose_joints_m
from tracker.outputs.playout import Player

POSE = np.r_[1.0, np.zeros(54)]
JOINTS = pose_joints_m(POSE[None])[0] + [0.0, 0.95, 0.0]


def _recorder():
    made, lock = [], threading.Lock()

    def call(label):
        with lock:
            made.append((label, time.perf_counter()))
    return made, call


def test_calls_are_made_in_order_and_never_before_their_video_time():
    made, call = _recorder()
    player = Player(lead_s=1.0)
    times = [0.0, 0.05, 0.1, 0.15, 0.2]
    for t in times:
        player.put(t, call, t)
    player.close()
    assert [label for label, _ in made] == times
    stamps = np.array([stamp for _, stamp in made])
    # (the first call is made a moment after the clock starts, hence the 10 ms)
    assert np.all(stamps - stamps[0] >= np.array(times) - 0.01)


def test_the_writer_goes_on_while_the_calls_wait_for_their_time():
    made, call = _recorder()
    player = Player(lead_s=1.0)
    for t in np.arange(10) * 0.05:                  # 0.45 s of video, within the lead
        player.put(t, call, t)
    handed_over = time.perf_counter()
    player.close()
    # A writer that waited for each call's time would hand the last one over after the
    # calls before it were made.
    assert len(made) == 10 and handed_over < made[-2][1]


def test_the_writer_waits_once_the_buffer_spans_the_lead():
    made, call = _recorder()
    player = Player(lead_s=0.1)
    times = np.arange(12) * 0.02
    for t in times:
        player.put(t, call, t)
        # Whatever is older than the lead was made before this put returned.
        waiting = [u for u in times[times <= t] if t - u > 0.1 + 1e-9]
        assert len(made) >= len(waiting) - 1      # the oldest may be being made just now
    player.close()
    assert len(made) == len(times)


@pytest.mark.parametrize("stop", ["discard", "close without draining"])
def test_a_stop_drops_the_calls_waiting_and_does_not_wait_for_them(stop):
    made, call = _recorder()
    player = Player(lead_s=60.0)
    for t in (0.0, 20.0, 40.0):
        player.put(t, call, t)
    started = time.perf_counter()
    if stop == "discard":
        player.discard()
        player.close()
    else:
        player.close(drain=False)
    assert time.perf_counter() - started < 5.0          # not the 40 s of video
    assert [label for label, _ in made] in ([], [0.0])
    with pytest.raises(RuntimeError, match="closed"):
        player.put(50.0, call, 50.0)


def test_an_error_is_kept_and_the_writer_never_blocks_for_good():
    made, call = _recorder()

    def fail(_):
        raise ValueError("drawing failed")
    player = Player(lead_s=0.05)
    player.put(0.0, fail, 0)
    for t in np.arange(1, 20) * 0.01:              # beyond the lead: puts wait on the thread
        player.put(t, call, t)
    player.close()
    assert isinstance(player.error, ValueError) and made == []


def test_a_realtime_view_plays_out_on_close_and_a_discarded_one_does_not():
    with MeshcatView(print_url=False, realtime=True) as view:
        for frame in range(5):
            view.write(TrackedPose(frame, frame / 30, 1, POSE, POSE, False, JOINTS))
            view.end_frame(frame)
    assert view.frames_drawn == 5
    with MeshcatView(print_url=False, realtime=True) as view:
        for frame in range(3):                      # within the view's lead of 1 s
            view.write(TrackedPose(frame, 0.45 * frame, 1, POSE, POSE, False, JOINTS))
            view.end_frame(frame)
        view.discard()
    assert view.frames_drawn <= 1


def _kill(server) -> None:
    os.kill(server.pid, signal.SIGKILL)
    deadline = time.monotonic() + 10
    while server.running and time.monotonic() < deadline:
        time.sleep(0.01)


@pytest.mark.slow
def test_a_realtime_view_warns_once_of_a_lost_server_but_not_after_a_stop():
    with pytest.warns(ViewLostWarning, match="meshcat viewer stopped") as caught:
        with MeshcatView(print_url=False, realtime=True) as view:
            view.write(TrackedPose(0, 0.0, 1, POSE, POSE, False, JOINTS))
            _kill(view.server)
            for frame in range(1, 6):
                view.write(TrackedPose(frame, frame / 50, 1, POSE, POSE, False, JOINTS))
                view.end_frame(frame)
    # (meshcat's Visualizer leaks a socket, whose ResourceWarning may fall in here too)
    assert len([w for w in caught if issubclass(w.category, ViewLostWarning)]) == 1
    # After a stop (Ctrl-C) the command ends anyway: nothing to warn of then.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with MeshcatView(print_url=False, realtime=True) as view:
            for frame in range(3):
                view.write(TrackedPose(frame, 0.3 * frame, 1, POSE, POSE, False, JOINTS))
                view.end_frame(frame)
            _kill(view.server)
            view.discard()
    assert not [w for w in caught if issubclass(w.category, ViewLostWarning)]


def test_a_drain_that_takes_too_long_is_cut_short():
    made, call = _recorder()

    def slow(label):
        time.sleep(0.3)
        call(label)
    player = Player(lead_s=60.0)
    for label in range(10):                      # all due at once, 3 s of work
        player.put(0.0, slow, label)
    started = time.perf_counter()
    player.close(timeout_s=0.4)
    assert time.perf_counter() - started < 2.0
    assert 1 <= len(made) < 10


def test_a_closed_realtime_view_refuses_frames_and_reports_a_late_failure():
    view = MeshcatView(print_url=False, realtime=True)
    view.write(TrackedPose(0, 0.0, 1, POSE, POSE, False, JOINTS))

    def broken():
        raise OSError("drawing failed")
    view._finish_frame = broken                 # fails on the player's thread
    view.end_frame(0)
    with pytest.raises(OSError, match="drawing failed"):
        view.close()
    assert not view.server.running
    with pytest.raises(SinkInputError, match="closed"):
        view.end_frame(1)
