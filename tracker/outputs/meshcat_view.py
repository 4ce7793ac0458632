"""Live 3-D view of the tracked people in a browser, through meshcat (Z-up metres).

The page shows each track's body (bone cylinders, joint spheres, head) in its side colours
(geometry.body_colours, so a left/right swap shows), labelled "track N", translucent when
ambiguous, with a faint ghost of a close runner-up hypothesis; each pelvis path as a ribbon
fading over TRAIL_S seconds; the video beside the people, each silhouette outlined
(video_panel.py); and a camera placed as the video camera is, following the people
(framing.py: the scene is shifted so the people stay in the middle and the orbit controls
stay the user's).

Scene paths: ``/people`` (shifted by the follow) holds ``ground``, ``tracks/track-<id>/body``,
``.../label``, ``.../ghost`` and ``trails/track-<id>``; ``/video`` holds the screen. Tracks not
written in the previous frame are removed. The view talks to a
:class:`tracker.outputs.meshcat_server.ViewerServer` (127.0.0.1 only), by default its own.
"""
from __future__ import annotations

import base64
import contextlib
import functools
import io
import warnings
from collections import deque
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
import zmq

from tracker.outputs.body_mesh import body_mesh
from tracker.outputs.framing import Framing
from tracker.outputs.meshcat_server import ViewerServer
from tracker.outputs.playout import Player
from tracker.outputs.geometry import (
    SinkInputError,
    body_colours,
    check_joints,
    is_unfamiliar,
    known_novelty,
    pose_joints_m,
    pose_label,
    track_colour,
    y_up_to_z_up,
)
from tracker.outputs.video_panel import encode_jpeg, encode_png, label_image, panel_image

if TYPE_CHECKING:
    from tracker.pipeline import TrackedPose
    from tracker.video.silhouettes import PersonMask

# A dead server must not hang the tracker: after this long without an answer the frame is
# dropped (the server is slow) or the view is given up (the server process is gone).
_REPLY_TIMEOUT_MS = 1_000
_STARTUP_TIMEOUT_MS = 10_000
#: Colours of the scene (0xRRGGBB): ground, grid lines, the video screen's bezel.
GROUND_COLOUR, GRID_COLOUR, BEZEL_COLOUR = 0xE4E6EA, 0xB4B8C0, 0x1F2938
_GROUND_RGB = np.array([0xE4, 0xE6, 0xEA]) / 255.0
_LABEL_SIZE_M = (0.8, 0.2)
_TRAIL_WIDTH_M = 0.07
#: Seconds of pelvis path drawn; screen updates a second and the width (pixels) of the frame's
#: copy sent for it.
TRAIL_S, SCREEN_FPS, SCREEN_WIDTH_PX = 8.0, 5.0, 256


class ViewLostWarning(UserWarning):
    """The meshcat server stopped; tracking goes on without the live view (one line)."""


def _transform(rotation: np.ndarray | None = None, translation=(0.0, 0.0, 0.0)) -> np.ndarray:
    matrix = np.eye(4)
    if rotation is not None:
        matrix[:3, :3] = rotation
    matrix[:3, 3] = translation
    return matrix


def trail_ribbon(points: np.ndarray, ages: np.ndarray, colour, width_m: float = _TRAIL_WIDTH_M
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A flat ribbon along a ground path, fading into the ground colour with age.

    points: (N, 2) ground positions, metres, N >= 2; ages: (N,) in [0, 1], 0 = newest (full
    colour), 1 = oldest (ground colour); colour: RGB in [0, 1]. Returns vertices (2N, 3)
    float32 at z = 5 mm, faces (2(N-1), 3) uint32, vertex colours (2N, 3) float32.
    """
    tangent = np.gradient(points, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-9)
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0]]) * (width_m / 2)
    ground = np.column_stack([points, np.full(len(points), 0.005)])
    side = np.column_stack([normal, np.zeros(len(points))])
    vertices = np.stack([ground - side, ground + side], axis=1).reshape(-1, 3)
    i = 2 * np.arange(len(points) - 1)
    faces = np.concatenate([np.stack([i, i + 2, i + 1], 1), np.stack([i + 1, i + 2, i + 3], 1)])
    fade = np.clip(ages, 0.0, 1.0)[:, None]
    colours = (1 - fade) * np.asarray(colour) + fade * _GROUND_RGB
    return (vertices.astype(np.float32), faces.astype(np.uint32),
            np.repeat(colours, 2, axis=0).astype(np.float32))


@functools.cache
def _meshcat_extras():
    """meshcat element types that meshcat 0.3.2 lacks: (PlaneGeometry, JpegImage). Built on
    first use: importing meshcat is deferred (it pulls in IPython)."""
    import meshcat.geometry as g

    class PlaneGeometry(g.Geometry):
        """three.js PlaneGeometry: width along X, height along Y, facing +Z."""

        def __init__(self, width: float, height: float):
            super().__init__()
            self.width, self.height = float(width), float(height)

        def lower(self, object_data):
            return {"uuid": self.uuid, "type": "PlaneGeometry", "width": self.width,
                    "height": self.height, "widthSegments": 1, "heightSegments": 1}

    class JpegImage(g.Image):
        """A JPEG for an ImageTexture (meshcat's PngImage only sends PNGs)."""

        def __init__(self, data: bytes):
            super().__init__()
            self.data = data

        def lower(self, object_data):
            return {"uuid": self.uuid, "url": "data:image/jpeg;base64," +
                    base64.b64encode(self.data).decode("ascii")}

    return PlaneGeometry, JpegImage


def _plane(width: float, height: float):
    return _meshcat_extras()[0](width, height)


def smooth_path(points: np.ndarray, window: int) -> np.ndarray:
    """Moving average of a path (N, 2) over ``window`` samples (shorter at the ends, where
    the end points are kept): the root's ground position jitters with the silhouette's box."""
    n = len(points)
    half = min(window // 2, (n - 1) // 2)
    if half < 1:
        return points
    cumulative = np.vstack([np.zeros((1, points.shape[1])), np.cumsum(points, axis=0)])
    index = np.arange(n)
    reach = np.minimum(np.minimum(index, n - 1 - index), half)   # symmetric, shrinking at ends
    return (cumulative[index + reach + 1] - cumulative[index - reach]) / (2 * reach + 1)[:, None]


class MeshcatView:
    """Live view of the tracked people (see the module docstring).

    server: a running ViewerServer to draw into; None starts one (owned: stopped by close()).
    print_url: print the page's address on start. realtime: draw each frame no sooner than its
    video time after the first (play at the video's own speed), from a thread of its own up to
    a second of video behind the writes (tracker.outputs.playout: a pause of the tracking loop
    does not pause the view; close() plays out what is left, discard() drops it).
    trail_every: redraw each trail every this many frames. Attributes: web_url (open it in a
    browser); frames_drawn; framing (framing.Framing: the tracker's assumed field of view, 4:3).
    """

    def __init__(self, server: ViewerServer | None = None, print_url: bool = True,
                 realtime: bool = False, trail_every: int = 5):
        import meshcat  # deferred: it pulls in IPython and PIL, needed only for the live view
        import meshcat.geometry

        self._g = meshcat.geometry
        self._owns_server = server is None
        self.server = ViewerServer() if server is None else server
        self.web_url = self.server.web_url
        self.framing = Framing()
        self._frame: int | None = None
        self._last_frame: dict[int, int] = {}  # track id -> last frame it was drawn in
        self._labels: dict[int, str] = {}      # track id -> label text on screen
        self._trails: dict[int, deque] = {}    # track id -> (time s, x, y) of its pelvis
        self._ghosts: set[int] = set()         # tracks whose runner-up hypothesis is drawn
        self._roots: list[np.ndarray] = []     # roots drawn in the current frame (Z-up)
        self._frame_time_s, self._frame_done = 0.0, False
        self._closed = False
        self._lost = False          # the server stopped: writes do nothing
        self._player: Player | None = None   # realtime: makes the drawing calls
        self._last_time_s = 0.0              # video time of the last call handed over
        # A server found gone is warned of once, from the writer's thread (the command's
        # warnings go through it; the player only sets _lost), and not after a stop
        # (discard()), which the command is ending anyway.
        self._warned = self._discarded = False
        self._last_screen_s = -float("inf")
        self._trail_every = max(1, int(trail_every))
        self.frames_drawn = 0
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
            self._set_stage()
            socket.setsockopt(zmq.RCVTIMEO, _REPLY_TIMEOUT_MS)
            socket.setsockopt(zmq.SNDTIMEO, _REPLY_TIMEOUT_MS)
        except BaseException:
            self.close()
            raise
        if realtime:
            self._player = Player(name="meshcat-view")
        if print_url:
            print(f"meshcat viewer: {self.web_url}")

    def _set_stage(self) -> None:
        """Light background, our own ground (it moves with the people group), the camera."""
        g, vis = self._g, self._vis
        vis["people"].delete()
        vis["video"].delete()
        for path in ("/Grid", "/Axes"):
            vis[path].set_property("visible", False)
        vis["/Background"].set_property("top_color", [0.97, 0.98, 1.0])
        vis["/Background"].set_property("bottom_color", [0.78, 0.83, 0.9])
        vis["people/ground/plane"].set_object(_plane(200.0, 200.0),
                                              g.MeshBasicMaterial(color=GROUND_COLOUR))
        ticks = np.arange(-30.0, 30.5, 1.0)
        lines = np.concatenate([[[t, -30, 0.01], [t, 30, 0.01]] for t in ticks] +
                               [[[-30, t, 0.01], [30, t, 0.01]] for t in ticks])
        vis["people/ground/grid"].set_object(g.LineSegments(
            g.PointsGeometry(lines.T.astype(np.float32)), g.LineBasicMaterial(color=GRID_COLOUR)))
        fov = self.framing.vertical_fov_deg
        vis["/Cameras/default"].set_transform(np.eye(4))
        vis["/Cameras/default/rotated"].set_object(
            g.PerspectiveCamera(fov=fov, aspect=self.framing.aspect, near=0.05, far=200.0))
        self._place_camera()
        self._follow()

    def _place_camera(self) -> None:
        # meshcat's camera lives in a frame rotated to three.js's Y-up convention:
        # Z-up (x, y, z) is (x, z, -y) there. It orbits the origin, where the people are kept.
        x, y, z = (float(c) for c in self.framing.camera_offset)
        self._vis["/Cameras/default/rotated/<object>"].set_property("position", [x, z, -y])
        self._place_screen()

    def _place_screen(self) -> None:
        rotation = self.framing.facing_rotation()
        centre = self.framing.screen_centre
        width, height = self.framing.screen_size_m
        g = self._g
        self._vis["video"].set_transform(_transform(rotation, centre))
        self._vis["video/bezel"].set_object(_plane(width + 0.08, height + 0.08),
                                            g.MeshBasicMaterial(color=BEZEL_COLOUR))
        self._vis["video/bezel"].set_transform(_transform(translation=(0, 0, -0.005)))

    def _follow(self) -> None:
        self._vis["people"].set_transform(_transform(translation=-self.framing.look_at))

    @property
    def closed(self) -> bool:
        """True after close()."""
        return self._closed

    def write(self, pose: TrackedPose) -> None:
        """Draw track ``pose.track_id`` at pose.joints_m (18, 3) metres (Y up); with
        ``realtime``, not before the pose's video time has passed since the first frame.
        Raises SinkInputError on bad joints or novelty, or when closed. If the server process
        has stopped, warns once (ViewLostWarning) and draws nothing from then on; a frame the
        server does not answer within 1 s is dropped."""
        if self._closed:
            raise SinkInputError("meshcat view is closed")
        joints = y_up_to_z_up(check_joints(pose.joints_m))
        unfamiliar = is_unfamiliar(known_novelty(getattr(pose, "novelty", None)))
        self._play(pose.time_s, self._draw, pose, joints, unfamiliar)

    def _play(self, time_s: float, draw, *args) -> None:
        """_send(draw, *args) now, or with ``realtime`` by the player at video time time_s
        (seconds); raises what an earlier call raised there."""
        if self._player is None:
            self._send(draw, *args)
            return
        if self._player.error is not None:
            raise self._player.error
        self._warn_if_lost()
        if self._lost:
            return                          # nothing to draw into: not even the waiting
        self._last_time_s = float(time_s)
        self._player.put(time_s, self._send, draw, *args)

    def _send(self, draw, *args) -> None:
        """draw(*args) unless the server is gone; a zmq timeout drops this frame's drawing."""
        if self._lost or not self._server_alive():
            return
        try:
            draw(*args)
        except zmq.Again:
            self._server_alive()        # dead: warned; alive but slow: this frame is dropped

    def _server_alive(self) -> bool:
        """False (after one ViewLostWarning) once the server process has exited."""
        if not self._lost and not self.server.running:
            self._lost = True
            if self._player is None:
                self._warn_if_lost()
        return not self._lost

    def _warn_if_lost(self) -> None:
        """Warn once that the server is gone (the writer's thread only)."""
        if self._lost and not self._warned and not self._discarded:
            self._warned = True
            warnings.warn(f"the meshcat viewer stopped (server process {self.server.pid} "
                          f"exited); tracking goes on without the live view", ViewLostWarning,
                          stacklevel=5)

    def _draw(self, pose: TrackedPose, joints: np.ndarray, unfamiliar: bool) -> None:
        frame_index, track_id = int(pose.frame_index), int(pose.track_id)
        if frame_index != self._frame:
            self._finish_frame()
            self._frame, self._frame_time_s, self._frame_done = frame_index, pose.time_s, False
        node = self._vis["people/tracks"][f"track-{track_id}"]
        self._set_body(node["body"], joints, track_id, 0.5 if pose.ambiguous else 1.0)
        self._draw_label(node["label"], track_id, joints,
                         pose_label(track_id, bool(pose.ambiguous), unfamiliar))
        self._draw_ghost(node["ghost"], track_id, pose)
        trail = self._trails.setdefault(track_id, deque())
        trail.append((float(pose.time_s), joints[0, 0], joints[0, 1]))
        while trail and trail[0][0] < pose.time_s - TRAIL_S:
            trail.popleft()
        if frame_index % self._trail_every == 0:
            self._draw_trail(track_id, trail)
        self._roots.append(joints[0])
        self._last_frame[track_id] = frame_index

    def _draw_label(self, node, track_id: int, joints: np.ndarray, text: str) -> None:
        if self._labels.get(track_id) != text:
            g = self._g
            png = encode_png(label_image(text, track_colour(track_id)))
            node.set_object(_plane(*_LABEL_SIZE_M), g.MeshBasicMaterial(
                map=g.ImageTexture(g.PngImage(png)), transparent=True))
            self._labels[track_id] = text
        top = joints[:, 2].max() + 0.3
        head = joints[3]
        node.set_transform(_transform(self.framing.facing_rotation(), (head[0], head[1], top)))

    def _draw_ghost(self, node, track_id: int, pose: TrackedPose) -> None:
        """The runner-up front/back hypothesis, when the tracker says it is close, as a faint
        body at the same root (opacity grows with its probability); removed when not close."""
        if pose.runner_up is None:
            if track_id in self._ghosts:
                node.delete()
                self._ghosts.discard(track_id)
            return
        root = np.asarray(pose.joints_m, np.float64)[:1]
        ghost = y_up_to_z_up(pose_joints_m(np.asarray(pose.runner_up)[None],
                                           root_position_m=root)[0])
        self._set_body(node, ghost, track_id,
                       0.1 + 0.3 * float(pose.runner_up_probability or 0.0))
        self._ghosts.add(track_id)

    def _set_body(self, node, joints: np.ndarray, track_id: int, opacity: float) -> None:
        """Draw a solid body at joints (18, 3) metres, Z up, in the track's side colours."""
        g = self._g
        vertices, faces, colours = body_mesh(joints, body_colours(track_id))
        node.set_object(g.TriangularMeshGeometry(vertices, faces, colours),
                        g.MeshLambertMaterial(vertexColors=True, opacity=opacity))

    def _draw_trail(self, track_id: int, trail: deque) -> None:
        node = self._vis["people/trails"][f"track-{track_id}"]
        if len(trail) < 2:
            return
        samples = np.array(trail)
        ages = (samples[-1, 0] - samples[:, 0]) / TRAIL_S
        vertices, faces, colours = trail_ribbon(smooth_path(samples[:, 1:], 9), ages,
                                                track_colour(track_id))
        g = self._g
        node.set_object(g.TriangularMeshGeometry(vertices, faces, colours),
                        g.MeshBasicMaterial(vertexColors=True))

    def _finish_frame(self) -> None:
        """Follow the people drawn in the frame just finished and remove the tracks that were
        not drawn in it."""
        if self._frame is None or self._frame_done:
            return
        self._frame_done = True
        if self._roots:
            if self.framing.update(np.array(self._roots), self._frame_time_s):
                self._place_camera()
            self._follow()
            self.frames_drawn += 1
        self._roots = []
        gone = [t for t, f in self._last_frame.items() if f != self._frame]
        for track_id in gone:
            self._vis["people/tracks"][f"track-{track_id}"].delete()
            self._vis["people/trails"][f"track-{track_id}"].delete()
            self._ghosts.discard(track_id)
            for kept in (self._last_frame, self._labels, self._trails):
                kept.pop(track_id, None)

    def write_frame(self, frame_index: int, time_s: float, frame: np.ndarray,
                    people: Mapping[int, PersonMask]) -> None:
        """Show the video frame (BGR uint8 (H, W, 3)) with its people's outlines, if
        1 / SCREEN_FPS seconds of video have passed since the last one shown; with
        ``realtime``, not before its video time."""
        if self._closed:
            raise SinkInputError("meshcat view is closed")
        if time_s - self._last_screen_s < 1.0 / SCREEN_FPS:
            return
        self._last_screen_s = time_s
        # The small copy is made here: the player holds it, not the frame (which the caller
        # may reuse).
        self._play(time_s, self._draw_screen, panel_image(frame, people, SCREEN_WIDTH_PX))

    def _draw_screen(self, panel: np.ndarray) -> None:
        g = self._g
        jpeg = encode_jpeg(panel)
        self._vis["video/frame"].set_object(
            _plane(*self.framing.screen_size_m),
            g.MeshBasicMaterial(map=g.ImageTexture(_meshcat_extras()[1](jpeg))))

    def end_frame(self, frame_index: int) -> None:
        """Follow the frame's people with the camera; remove the tracks absent from it (also
        done when a pose of a later frame is written without end_frame)."""
        if self._closed:
            raise SinkInputError("meshcat view is closed")
        self._play(self._last_time_s, self._finish_frame)

    def discard(self) -> None:
        """Drop the frames handed over and not shown yet (``realtime``; after a stop, the
        command does not wait for them to play)."""
        if self._player is not None:
            self._discarded = True
            self._player.discard()

    def close(self) -> None:
        """Disconnect, and stop the server if this view started it; idempotent."""
        if self._closed:
            return
        self._closed = True
        player = getattr(self, "_player", None)
        if player is not None:
            # What was handed over plays out at its times; a stalled server (each call waits
            # for its reply timeout) must not hold the command much longer than the lead.
            player.close(timeout_s=player.lead_s + 2 * _REPLY_TIMEOUT_MS / 1000)
            self._warn_if_lost()
        vis = getattr(self, "_vis", None)
        if vis is not None:
            # meshcat's Visualizer.close() raises (its window has no close); close the socket.
            vis.window.zmq_socket.close(linger=0)
        if self._owns_server:
            self.server.close()
        if player is not None and player.error is not None:
            raise player.error               # a drawing call's failure at the end, not lost

    def __enter__(self) -> "MeshcatView":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()
