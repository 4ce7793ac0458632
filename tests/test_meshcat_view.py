"""meshcat server (loopback only, never orphaned), live view scene contents, skeleton geometry."""
from __future__ import annotations

import base64
import os
import re
import signal
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import umsgpack
import zmq

from tracker.outputs.meshcat_server import ViewerServer
from tracker.video.decode import focal_length_px
from tracker.outputs.body_mesh import body_mesh, joint_spheres
from tracker.outputs.framing import Framing
from tracker.outputs.meshcat_view import MeshcatView, ViewLostWarning, smooth_path, trail_ribbon
from sequences.skeleton import POSE_JOINTS
from tracker import TrackedPose
from tracker.outputs.geometry import (
    SinkInputError,
    ground_position_from_image,
    pose_joints_m,
    y_up_to_z_up,
)

ROOT = Path(__file__).resolve().parents[1]
POSE_JOINT_INDEX = {name: i for i, name in enumerate(POSE_JOINTS)}
POSE = np.r_[1.0, np.zeros(54)]
JOINTS = pose_joints_m(POSE[None])[0] + [0.0, 0.95, 0.0]
LOOPBACK_HEX = "0100007F"  # 127.0.0.1 as /proc/net/tcp writes it


def _listening_addresses(pid: int) -> list[str]:
    """Local addresses ("HEXIP:HEXPORT") of the TCP sockets process ``pid`` listens on."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        match = re.fullmatch(r"socket:\[(\d+)\]", os.readlink(fd))
        if match:
            inodes.add(match.group(1))
    addresses = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            fields = line.split()
            if fields[3] == "0A" and fields[9] in inodes:  # 0A = LISTEN
                addresses.append(fields[1])
    return addresses


def _gone(pid: int, timeout_s: float = 10.0) -> bool:
    """True once process ``pid`` no longer runs (absent, or a zombie nobody reaped yet)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except (FileNotFoundError, ProcessLookupError):
            return True
        if state in ("Z", "X"):
            return True
        time.sleep(0.05)
    return False


def _non_loopback_address() -> str | None:
    """An IPv4 address of this machine other than 127.x, if it has one (UDP connect sends
    nothing; it only picks the outgoing interface)."""
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        probe.connect(("10.254.254.254", 9))
        address = probe.getsockname()[0]
    except OSError:
        return None
    finally:
        probe.close()
    return None if address.startswith("127.") or address == "0.0.0.0" else address


@pytest.mark.skipif(not Path("/proc/net/tcp").exists(), reason="needs Linux /proc/net/tcp")
def test_server_listens_on_loopback_only():
    with ViewerServer() as server:
        addresses = _listening_addresses(server.pid)
        web_port = int(server.web_url.rsplit(":", 1)[1].split("/")[0])
        zmq_port = int(server.zmq_url.rsplit(":", 1)[1])
        assert sorted(int(a.split(":")[1], 16) for a in addresses) == sorted([web_port, zmq_port])
        assert all(a.split(":")[0] == LOOPBACK_HEX for a in addresses), addresses
        assert server.web_url.startswith("http://127.0.0.1:")
        other = _non_loopback_address()
        if other is not None:
            with pytest.raises(OSError):
                socket.create_connection((other, web_port), timeout=2).close()
        socket.create_connection(("127.0.0.1", web_port), timeout=2).close()


def test_server_is_gone_after_close():
    server = ViewerServer()
    assert server.running
    pid, web_port = server.pid, int(server.web_url.rsplit(":", 1)[1].split("/")[0])
    server.close()
    server.close()  # idempotent
    assert _gone(pid)
    with pytest.raises(OSError):
        socket.create_connection(("127.0.0.1", web_port), timeout=2).close()


_PARENT = textwrap.dedent("""
    import sys, time
    import numpy as np
    from tracker import TrackedPose
    from tracker.outputs.meshcat_view import MeshcatView
    with MeshcatView(print_url=False) as view:
        print(view.server.pid, flush=True)
        frame = 0
        while True:
            view.write(TrackedPose(frame, frame / 25.0, 1, np.zeros(55), np.zeros(55), False,
                       np.zeros((18, 3))))
            frame += 1
            time.sleep(0.02)
""")


def _start_parent(**popen_kwargs) -> tuple[subprocess.Popen, int]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    parent = subprocess.Popen([sys.executable, "-c", _PARENT], stdout=subprocess.PIPE,
                              text=True, env=env, cwd=ROOT, **popen_kwargs)
    line = parent.stdout.readline()
    if not line.strip().isdigit():
        parent.kill()
        parent.wait()
        raise AssertionError(f"parent printed {line!r} instead of the server's pid")
    return parent, int(line)


def test_server_dies_with_its_killed_parent():
    parent, child = _start_parent()
    try:
        assert not _gone(child, timeout_s=0.5)
    finally:
        parent.kill()  # SIGKILL: no Python clean-up runs in the parent
        parent.wait()
    assert _gone(child)


@pytest.mark.parametrize("to_group, signum", [(True, signal.SIGINT), (False, signal.SIGINT),
                                               (False, signal.SIGTERM)],
                         ids=["ctrl-c-in-terminal", "sigint-to-parent", "sigterm-to-parent"])
@pytest.mark.slow
def test_interrupting_the_parent_stops_the_server(to_group, signum):
    # A terminal's Ctrl-C sends SIGINT to the whole foreground process group; a SIGINT to the
    # parent alone leaves the stopping to its KeyboardInterrupt clean-up; SIGTERM kills the
    # parent without clean-up, leaving it to the child's stdin watch.
    parent, child = _start_parent(start_new_session=True)
    try:
        time.sleep(0.3)
        (os.killpg if to_group else os.kill)(parent.pid, signum)
        assert parent.wait(timeout=20) != 0
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait()
    assert _gone(child)


def test_a_ctrl_c_leaves_the_server_to_its_parent():
    # The terminal's signals go to its foreground process group: not to the child, in a
    # session of its own; the parent's clean-up stops it after closing the view (a server
    # gone at once made the view warn that it had stopped).
    with ViewerServer() as server:
        assert os.getsid(server.pid) != os.getsid(0)
        os.kill(server.pid, signal.SIGINT)
        assert not _gone(server.pid, timeout_s=0.5)
        assert server.running
    assert _gone(server.pid)


def _scene_paths(zmq_url: str) -> list[str]:
    """Paths of the objects the server holds, from its 'get_scene' HTML (msgpack commands)."""
    context = zmq.Context.instance()
    request = context.socket(zmq.REQ)
    request.setsockopt(zmq.RCVTIMEO, 10_000)
    request.connect(zmq_url)
    try:
        request.send(b"get_scene")
        html = request.recv().decode("utf-8")
    finally:
        request.close(linger=0)
    commands = [umsgpack.unpackb(base64.b64decode(b)) for b in
                re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)]
    return [c["path"] for c in commands if c["type"] == "set_object"]


def _track_paths(zmq_url: str) -> set[str]:
    return {p.split("/people/")[1] for p in _scene_paths(zmq_url)
            if "/people/tracks/" in p or "/people/trails/" in p}


def test_view_draws_each_track_and_removes_tracks_that_left():
    with MeshcatView(print_url=False, trail_every=1) as view:
        view.write(TrackedPose(0, 0.0, 1, POSE, POSE, False, JOINTS))
        view.write(TrackedPose(0, 0.0, 2, POSE, POSE, True, JOINTS + [1.0, 0.0, 0.0]))
        view.end_frame(0)
        view.write(TrackedPose(1, 0.04, 1, POSE, POSE, False, JOINTS + [0.05, 0.0, 0.0]))
        view.write(TrackedPose(1, 0.04, 2, POSE, POSE, True, JOINTS + [1.05, 0.0, 0.0]))
        view.end_frame(1)
        assert _track_paths(view.server.zmq_url) == {
            f"{kind}/track-{t}{part}" for t in (1, 2) for kind, part in
            (("tracks", "/body"), ("tracks", "/label"), ("trails", ""))}
        view.write(TrackedPose(2, 0.08, 1, POSE, POSE, False, JOINTS))
        view.write(TrackedPose(3, 0.12, 1, POSE, POSE, False, JOINTS))  # frame 2 ended without track 2
        assert _track_paths(view.server.zmq_url) == {
            "tracks/track-1/body", "tracks/track-1/label", "trails/track-1"}
        with pytest.raises(SinkInputError, match="joints3d"):
            view.write(TrackedPose(4, 0.16, 1, POSE, POSE, False, np.zeros((18, 2))))
    assert view.closed and _gone(view.server.pid)
    with pytest.raises(SinkInputError, match="closed"):
        view.write(TrackedPose(5, 0.2, 1, POSE, POSE, False, JOINTS))


def test_a_close_runner_up_hypothesis_is_drawn_as_a_ghost_and_removed_when_not():
    flipped = POSE.copy()
    flipped[0] = -flipped[0]
    with MeshcatView(print_url=False) as view:
        view.write(TrackedPose(0, 0.0, 1, POSE, POSE, True, JOINTS, runner_up=flipped,
                               runner_up_probability=0.4))
        view.end_frame(0)
        assert "tracks/track-1/ghost" in _track_paths(view.server.zmq_url)
        view.write(TrackedPose(1, 0.04, 1, POSE, POSE, False, JOINTS))
        view.end_frame(1)
        paths = _track_paths(view.server.zmq_url)
        assert "tracks/track-1/body" in paths and "tracks/track-1/ghost" not in paths


def test_body_mesh_colours_each_side_and_closes_every_bone():
    colours = np.array([[0.5, 0.5, 0.5], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    joints = y_up_to_z_up(JOINTS)
    vertices, faces, vertex_colours = body_mesh(joints, colours)
    assert len(vertices) == len(vertex_colours) and faces.max() == len(vertices) - 1
    left = vertices[np.all(vertex_colours == colours[1], axis=1)]
    right = vertices[np.all(vertex_colours == colours[2], axis=1)]
    # Each side's colour lies on that side's hand, not on the other one.
    left_hand, right_hand = joints[POSE_JOINT_INDEX["LeftHand"]], joints[POSE_JOINT_INDEX["RightHand"]]
    assert np.linalg.norm(left - left_hand, axis=1).min() < 0.06
    assert np.linalg.norm(right - right_hand, axis=1).min() < 0.06
    assert np.linalg.norm(left - right_hand, axis=1).min() > 0.1
    assert vertices[:, 2].max() > joints[:, 2].max() + 0.15      # the head ball on top


def test_framing_keeps_every_person_and_the_screen_in_view():
    framing = Framing()
    people = np.array([[-2.0, 6.0, 0.95], [2.5, 8.0, 0.95]])
    for step in range(60):                                       # 2 s at 30 fps
        framing.update(people + [0.02 * step, 0.0, 0.0], step / 30)
    camera = framing.look_at + framing.camera_offset
    half_h = np.radians(framing.vertical_fov_deg) / 2
    half_w = np.arctan(np.tan(half_h) * framing.aspect)
    forward = -framing.view_direction
    right = np.array([1.0, 0.0, 0.0])
    up = np.cross(right, forward)
    screen = framing.look_at + framing.screen_centre
    width, height = framing.screen_size_m
    points = [p + [0.02 * 59, 0, dz] for p in people for dz in (-0.95, 1.0)]
    points += [screen + [sx * width / 2, 0, sz * height / 2] for sx in (-1, 1) for sz in (-1, 1)]
    for point in points:
        ray = point - camera
        depth = ray @ forward
        assert abs(np.arctan2(ray @ right, depth)) < half_w, point
        assert abs(np.arctan2(ray @ up, depth)) < half_h, point
    assert framing.vertical_fov_deg == pytest.approx(2 * np.degrees(np.arctan(
        np.tan(np.radians(30)) * 0.75)))                         # the video's, 60 deg wide, 4:3


def test_trail_ribbon_fades_from_the_track_colour_into_the_ground():
    path = np.column_stack([np.linspace(0, 2, 20), np.zeros(20)])
    vertices, faces, colours = trail_ribbon(path, np.linspace(1, 0, 20), (1.0, 0.0, 0.0))
    assert vertices.shape == (40, 3) and faces.shape == (38, 3)
    np.testing.assert_allclose(colours[-1], [1.0, 0.0, 0.0])
    assert colours[0, 1] > 0.8                                  # the oldest end: ground grey
    noisy = path + np.random.default_rng(0).normal(0, 0.05, path.shape)
    assert np.abs(smooth_path(noisy, 9)[3:-3, 1]).mean() < np.abs(noisy[3:-3, 1]).mean() / 2


def test_a_killed_server_gives_one_warning_and_tracking_goes_on():
    with MeshcatView(print_url=False) as view:
        view.write(TrackedPose(0, 0.0, 1, POSE, POSE, False, JOINTS))
        os.kill(view.server.pid, signal.SIGKILL)
        started = time.monotonic()
        with pytest.warns(ViewLostWarning, match="meshcat viewer stopped") as caught:
            for frame in range(1, 6):
                view.write(TrackedPose(frame, frame / 25, 1, POSE, POSE, False, JOINTS))
        assert len(caught) == 1
        assert time.monotonic() - started < 2.0         # not a 10 s hang per frame


def test_a_stalled_server_drops_frames_within_a_second():
    with MeshcatView(print_url=False) as view:
        os.kill(view.server.pid, signal.SIGSTOP)
        try:
            started = time.monotonic()
            view.write(TrackedPose(0, 0.0, 1, POSE, POSE, False, JOINTS))   # no exception
            assert time.monotonic() - started < 2.0
        finally:
            os.kill(view.server.pid, signal.SIGCONT)
        view.write(TrackedPose(1, 0.04, 1, POSE, POSE, False, JOINTS))      # still drawing
        assert any("/people/tracks/track-1" in p for p in _scene_paths(view.server.zmq_url))


def test_joint_spheres_are_closed_meshes_of_the_right_radius():
    centres = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]])
    vertices, faces = joint_spheres(centres, 0.05)
    assert vertices.shape == (84, 3) and faces.shape == (160, 3)
    distances = np.linalg.norm(vertices.reshape(2, 42, 3) - centres[:, None], axis=2)
    np.testing.assert_allclose(distances, 0.05, atol=1e-6)  # float32 vertices
    assert faces.min() == 0 and faces.max() == 83
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), 1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 2)  # every edge shared by two triangles: watertight


def test_y_up_to_z_up_is_a_rotation_that_puts_the_head_on_top():
    points = np.random.default_rng(0).normal(size=(5, 3))
    rotated = y_up_to_z_up(points)
    np.testing.assert_allclose(np.linalg.norm(rotated, axis=1), np.linalg.norm(points, axis=1))
    joints = y_up_to_z_up(JOINTS)
    assert joints[3, 2] > joints[0, 2] > joints[14, 2]  # head above hips above left foot


def test_ground_position_from_image_follows_the_pinhole_model():
    # A 170-px silhouette in a 640-px-wide frame with a 90-degree field of view: f = 320 px,
    # so a 1.7-m person is 3.2 m away; 160 px right of the centre is 1.6 m to the right.
    position = ground_position_from_image(np.array([[480.0, 240.0]]), np.array([170.0]),
                                          640, 480, focal_px=focal_length_px(640, 90.0))
    np.testing.assert_allclose(position, [[1.6, 0.95, -3.2]])
    with pytest.raises(SinkInputError, match="bbox_height_px"):
        ground_position_from_image(np.array([[1.0, 1.0]]), np.array([0.0]), 640, 480)


def test_labels_say_when_a_silhouette_is_unfamiliar():
    with MeshcatView(print_url=False) as view:
        for frame, (ambiguous, novelty) in enumerate(((False, 2.0), (True, 1.5), (False, 0.5),
                                                      (False, None))):
            view.write(TrackedPose(frame, 0.04 * frame, 1, POSE, POSE, ambiguous, JOINTS,
                                   novelty=novelty))
            view.end_frame(frame)
            assert view._labels[1] == ["track 1 (unfamiliar)", "track 1 (ambiguous, unfamiliar)",
                                       "track 1", "track 1"][frame]
