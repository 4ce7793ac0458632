"""Live 3-D view of the tracked skeletons in a browser, through meshcat.

One skeleton per track under ``/skeletons/track-<id>``: bones as line segments and joints as
small spheres (one merged triangle mesh), in the track's colour, updated on every ``write``.
Tracks that were not written in the previous frame are removed. Positions are drawn as given
(metres, Y up in, converted to meshcat's Z-up world).

The view talks to a :class:`tracker.sinks.meshcat_server.ViewerServer` (127.0.0.1 only) through
meshcat's ``Visualizer``; by default it starts its own server and stops it on ``close()``.
"""
from __future__ import annotations

import contextlib
import io
import time
import warnings
from typing import TYPE_CHECKING

import numpy as np
import zmq

from tracker.sinks.meshcat_server import ViewerServer
from tracker.sinks.geometry import (
    SinkInputError,
    bone_segments,
    check_joints,
    track_colour,
    y_up_to_z_up,
)

if TYPE_CHECKING:
    from ..pipeline import TrackedPose

# A dead server must not hang the tracker: after this long without an answer the frame is
# dropped (the server is slow) or the view is given up (the server process is gone).
_REPLY_TIMEOUT_MS = 1_000
_STARTUP_TIMEOUT_MS = 10_000


class ViewLostWarning(UserWarning):
    """The meshcat server stopped; tracking goes on without the live view (one line)."""


def _icosphere() -> tuple[np.ndarray, np.ndarray]:
    """Unit icosahedron subdivided once: vertices (42, 3) on the unit sphere, faces (80, 3)."""
    t = (1.0 + 5.0 ** 0.5) / 2.0
    vertices = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                         [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]],
                        dtype=np.float64)
    faces = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9],
                      [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2],
                      [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
                      [8, 6, 7], [9, 8, 1]])
    # Split each triangle into four through its edge midpoints (shared midpoints merged).
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), 1)
    unique, inverse = np.unique(edges, axis=0, return_inverse=True)
    mid = len(vertices) + inverse.reshape(3, -1).T  # (20, 3): midpoints of edges 01, 12, 20
    vertices = np.concatenate([vertices, vertices[unique].mean(axis=1)])
    a, b, c = faces.T
    ab, bc, ca = mid.T
    faces = np.concatenate([np.stack(f, axis=1) for f in
                            ((a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca))])
    return vertices / np.linalg.norm(vertices, axis=1, keepdims=True), faces


_SPHERE_VERTICES, _SPHERE_FACES = _icosphere()


def joint_spheres(joints: np.ndarray, radius_m: float) -> tuple[np.ndarray, np.ndarray]:
    """One triangle mesh of a sphere around every joint.

    joints: (N, 3) metres. Returns vertices (N * 42, 3) float32 and faces (N * 80, 3) uint32.
    """
    n = len(joints)
    vertices = joints[:, None, :] + radius_m * _SPHERE_VERTICES[None]
    faces = _SPHERE_FACES[None] + len(_SPHERE_VERTICES) * np.arange(n)[:, None, None]
    return vertices.reshape(-1, 3).astype(np.float32), faces.reshape(-1, 3).astype(np.uint32)


def _hex(track_id: int) -> int:
    r, g, b = (int(round(255 * c)) for c in track_colour(track_id))
    return (r << 16) | (g << 8) | b


class MeshcatView:
    """Live skeleton view (see the module docstring).

    server: a running ViewerServer to draw into; None starts one (owned: stopped by close()).
    joint_radius_m: sphere radius at each joint. camera_position_m: where the browser's camera
    starts, metres in the Z-up world (default: in front of a subject at heading 0, seen from
    the video camera's side, a little to the right and above); it orbits the origin. None keeps
    meshcat's default. print_url: print the page's address on start. realtime: draw each pose
    no sooner than its video time after the first (play at the video's own speed).
    Attributes: web_url (open it in a browser).
    """

    def __init__(self, server: ViewerServer | None = None, joint_radius_m: float = 0.04,
                 camera_position_m: tuple[float, float, float] | None = (0.8, -3.5, 1.4),
                 print_url: bool = True, realtime: bool = False):
        import meshcat  # deferred: it pulls in IPython and PIL, needed only for the live view
        import meshcat.geometry

        self._g = meshcat.geometry
        self._owns_server = server is None
        self.server = ViewerServer() if server is None else server
        self.web_url = self.server.web_url
        self._radius = float(joint_radius_m)
        self._frame: int | None = None
        self._last_frame: dict[int, int] = {}  # track id -> last frame it was drawn in
        # Ground point (x, 0, z) metres under the first person's first root: subtracted from
        # every skeleton, so people appear near the viewer's origin, where its camera looks,
        # rather than metres away at their camera-relative positions.
        self._anchor: np.ndarray | None = None
        self._closed = False
        self._lost = False          # the server stopped: writes do nothing
        self._realtime = realtime
        self._clock_start: tuple[float, float] | None = None   # (video s, wall s) of pose 1
        try:
            with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints the URL itself
                self._vis = meshcat.Visualizer(zmq_url=self.server.zmq_url)
            socket = self._vis.window.zmq_socket
            socket.setsockopt(zmq.RCVTIMEO, _STARTUP_TIMEOUT_MS)   # a just-started server
            socket.setsockopt(zmq.SNDTIMEO, _STARTUP_TIMEOUT_MS)
            socket.setsockopt(zmq.LINGER, 0)
            # After a timeout, send the next request anyway and ignore a late answer.
            socket.setsockopt(zmq.REQ_RELAXED, 1)
            socket.setsockopt(zmq.REQ_CORRELATE, 1)
            self._vis["skeletons"].delete()
            if camera_position_m is not None:
                self._place_camera(camera_position_m)
            socket.setsockopt(zmq.RCVTIMEO, _REPLY_TIMEOUT_MS)
            socket.setsockopt(zmq.SNDTIMEO, _REPLY_TIMEOUT_MS)
        except BaseException:
            self.close()
            raise
        if print_url:
            print(f"meshcat viewer: {self.web_url}")

    def _place_camera(self, position: tuple[float, float, float]) -> None:
        # meshcat's camera lives in a frame rotated to three.js's Y-up convention:
        # Z-up (x, y, z) is (x, z, -y) there.
        x, y, z = (float(c) for c in position)
        self._vis["/Cameras/default"].set_transform(np.eye(4))
        self._vis["/Cameras/default/rotated/<object>"].set_property("position", [x, z, -y])

    @property
    def closed(self) -> bool:
        """True after close()."""
        return self._closed

    def write(self, pose: TrackedPose) -> None:
        """Draw track ``pose.track_id`` at pose.joints_m (18, 3) metres (Y up), shifted so the
        first person drawn starts above the viewer's origin; with ``realtime``, not before the
        pose's video time has passed since the first pose. Raises SinkInputError on bad joints
        or when closed. If the server process has stopped, warns once (ViewLostWarning) and
        draws nothing from then on; a frame the server does not answer within 1 s is dropped."""
        if self._closed:
            raise SinkInputError("meshcat view is closed")
        joints = check_joints(pose.joints_m)
        if self._lost or not self._server_alive():
            return
        try:
            self._draw(pose, joints)
        except zmq.Again:
            self._server_alive()        # dead: warned; alive but slow: this frame is dropped

    def _server_alive(self) -> bool:
        """False (after one ViewLostWarning) once the server process has exited."""
        if not self._lost and not self.server.running:
            self._lost = True
            warnings.warn(f"the meshcat viewer stopped (server process {self.server.pid} "
                          f"exited); tracking goes on without the live view", ViewLostWarning,
                          stacklevel=3)
        return not self._lost

    def _draw(self, pose: TrackedPose, joints: np.ndarray) -> None:
        frame_index, track_id = pose.frame_index, pose.track_id
        if self._realtime:
            self._wait_until(pose.time_s)
        if self._anchor is None:
            self._anchor = np.array([joints[0, 0], 0.0, joints[0, 2]])
        joints = y_up_to_z_up(joints - self._anchor)
        frame_index, track_id = int(frame_index), int(track_id)
        if frame_index != self._frame:
            self._remove_absent_tracks()
            self._frame = frame_index
        node = self._vis["skeletons"][f"track-{track_id}"]
        g, colour = self._g, _hex(track_id)
        segments = bone_segments(joints).reshape(-1, 3).T.astype(np.float32)  # (3, 2B)
        node["bones"].set_object(g.LineSegments(g.PointsGeometry(segments),
                                                g.LineBasicMaterial(color=colour, linewidth=3)))
        vertices, faces = joint_spheres(joints, self._radius)
        node["joints"].set_object(g.TriangularMeshGeometry(vertices, faces),
                                  g.MeshLambertMaterial(color=colour))
        self._last_frame[track_id] = frame_index

    def _wait_until(self, time_s: float) -> None:
        """Sleep until time_s of video has passed (wall clock) since the first pose drawn:
        tracking outruns the video, and the view is played at its own speed."""
        now = time.perf_counter()
        if self._clock_start is None:
            self._clock_start = (time_s, now)
        ahead = (time_s - self._clock_start[0]) - (now - self._clock_start[1])
        if ahead > 0:
            time.sleep(ahead)

    def end_frame(self, frame_index: int) -> None:
        """Nothing per frame: tracks absent from a frame are removed when the next one starts."""

    def _remove_absent_tracks(self) -> None:
        """Delete skeletons of tracks not drawn in the frame that just ended."""
        gone = [t for t, f in self._last_frame.items() if f != self._frame]
        for track_id in gone:
            self._vis["skeletons"][f"track-{track_id}"].delete()
            del self._last_frame[track_id]

    def close(self) -> None:
        """Disconnect, and stop the server if this view started it; idempotent."""
        if self._closed:
            return
        self._closed = True
        vis = getattr(self, "_vis", None)
        if vis is not None:
            # meshcat's Visualizer.close() raises (its window has no close); close the socket.
            vis.window.zmq_socket.close(linger=0)
        if self._owns_server:
            self.server.close()

    def __enter__(self) -> "MeshcatView":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()
