"""Synthetic test videos: shaded people walking over a textured, static scene, with ground truth.

A video is what the ``track`` command sees in real use (a fixed camera, a static background,
sensor noise), made from real motion capture so every frame's pose is known. Each frame:
people are skinned, drawn Lambert-shaded far to near (so they occlude each other correctly),
composited over a procedurally textured background, and given Gaussian sensor noise.

Ground truth goes to a sidecar ``<video>.truth.npz`` (no pickle): per frame and person the pose
vector relative to the camera's line of sight, heading, hips position, silhouette bounding box
and centroid in pixels.
"""
from __future__ import annotations

import contextlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import cv2
import numpy as np

from regressor.errors import SilhouettePoseError

from .body import BodyShape, Skinner, ground_sequence, load_body
from .bvh import Motion
from .pose_conversions import motion_to_pose_vectors
from .pose_vector import POSE_DIM
from .render import Camera, look_at_camera, shaded_render
from .spiral import line_of_sight_azimuth

TRUTH_FORMAT_VERSION = 1
_MARGIN = 0.08                 # fraction of the image kept free around the people's paths
_COLOURS = ((205, 170, 150), (120, 150, 200), (170, 200, 140), (210, 190, 110))


class VideoWriteError(SilhouettePoseError, ValueError):
    """Bad video options or an output that cannot be written."""


@dataclass
class Actor:
    """One person in a video. motion: its BVH motion (already at the video's fps; shorter
    motions hold their last frame); shape: body shape; offset_m: (x, z) metres added to its
    ground path; colour: RGB 0-255 of its clothes-less skin (None: a palette colour)."""

    motion: Motion
    shape: BodyShape = BodyShape()
    offset_m: tuple[float, float] = (0.0, 0.0)
    colour: tuple[int, int, int] | None = None


def textured_background(size: tuple[int, int], seed: int) -> np.ndarray:
    """A static scene (H, W, 3) uint8 RGB: a wall with blotchy plaster texture above a tiled
    floor, with mild vignetting. Deterministic in seed. Texture matters: background subtraction
    must cope with a scene that is not flat colour."""
    h, w = size
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    noise = np.zeros((h, w), np.float32)
    for scale, amp in ((64, 28.0), (16, 12.0), (4, 6.0)):
        coarse = rng.normal(0, 1, (h // scale + 2, w // scale + 2)).astype(np.float32)
        noise += amp * cv2.resize(coarse, (w, h), interpolation=cv2.INTER_CUBIC)
    horizon = int(0.45 * h)
    wall = np.array(rng.uniform(150, 200, 3), np.float32)
    floor = np.array(rng.uniform(90, 140, 3), np.float32)
    image = np.where((yy < horizon)[..., None], wall, floor) + noise[..., None]
    # Floor tiles in perspective: lines converging to a vanishing point above the image.
    depth = np.maximum(yy - horizon + 1, 1)
    tile_u = (xx - w / 2) / depth * 12
    tile_v = 400.0 / depth
    grout = (np.abs(tile_u - np.round(tile_u)) < 0.04) | (np.abs(tile_v - np.round(tile_v)) < 0.05)
    image[(yy >= horizon) & grout] *= 0.7
    vignette = 1.0 - 0.25 * (((xx - w / 2) / w) ** 2 + ((yy - h / 2) / h) ** 2)
    return np.clip(image * vignette[..., None], 0, 255).astype(np.uint8)


def posed_sequences(actors: Sequence[Actor], n_frames: int):
    """The body model and, per actor, its posed vertices (T, V, 3) metres grounded on y = 0 and
    its hips positions (T, 3) metres, T = n_frames (shorter motions hold their last frame)."""
    body = load_body()
    out = []
    for actor in actors:
        m = actor.motion
        idx = np.minimum(np.arange(n_frames), m.n_frames - 1)
        skinner = Skinner(body, offsets=m.offsets, names=m.names, end_sites=m.end_sites,
                          shape=actor.shape)
        root = skinner.root_from_bvh(m.root_position[idx])
        root[:, [0, 2]] += np.asarray(actor.offset_m, dtype=np.float64)
        verts = skinner.pose(m.local_rotations()[idx], root)
        grounded = ground_sequence(verts)
        root = root + (grounded[0, 0] - verts[0, 0])
        out.append((grounded, root))
    return body, out


def scene_camera(posed, size: tuple[int, int], azimuth_deg: float, elevation_deg: float,
                 distance_m: float) -> Camera:
    """The fixed camera of a video of posed people (posed_sequences' list): fitted_camera on
    every 7th vertex of every frame (plenty to bound the scene, 7x cheaper)."""
    every = np.concatenate([v[:, ::7].reshape(-1, 3) for v, _ in posed])
    return fitted_camera(every, size, azimuth_deg, elevation_deg, distance_m)


def fitted_camera(points_m: np.ndarray, size: tuple[int, int], azimuth_deg: float,
                  elevation_deg: float, distance_m: float) -> Camera:
    """A fixed camera at azimuth/elevation (degrees) and distance_m metres from the centre of
    points_m (N, 3) metres (all vertices of all frames, or a subsample), with the focal length
    that keeps every point inside the image with a small margin."""
    pts = np.asarray(points_m, dtype=np.float64)
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    probe = look_at_camera(centre, azimuth_deg, elevation_deg, distance_m, 1.0, size)
    uv, z = probe.project(pts)
    if z.min() <= 0.1:
        raise VideoWriteError(f"camera distance {distance_m} m puts people behind the camera; "
                              "use a larger distance")
    cx, cy = probe.principal_point
    half = np.array([cx, cy]) * (1 - 2 * _MARGIN)
    focal = float(np.min(half / np.maximum(np.abs(uv - [cx, cy]).max(axis=0), 1e-9)))
    return look_at_camera(centre, azimuth_deg, elevation_deg, distance_m, focal, size)


def write_video(path: str | Path, actors: Sequence[Actor], size: tuple[int, int] = (480, 640),
                fps: float = 30.0, azimuth_deg: float = 0.0, elevation_deg: float = 8.0,
                distance_m: float = 9.0, noise_sigma: float = 3.0, seed: int = 0,
                n_frames: int | None = None,
                progress: Callable[[int, int], None] | None = None) -> Path:
    """Render actors as an mp4 (mp4v) video and write its ground-truth sidecar.

    path: output .mp4; size: (height, width) pixels; fps: video rate (the motions must already
    be at it); azimuth_deg/elevation_deg/distance_m: the fixed camera, seen from the middle of
    the people's paths; noise_sigma: sensor noise, grey levels; n_frames: default the longest
    motion. progress(done, total) after each frame. Returns the sidecar's path.
    """
    path = Path(path)
    if not actors:
        raise VideoWriteError("a video needs at least one actor")
    if not (16 <= size[0] <= 4096 and 16 <= size[1] <= 4096):
        raise VideoWriteError(f"video size {size} must be within 16..4096 pixels")
    if not (0 <= noise_sigma <= 50):
        raise VideoWriteError(f"noise_sigma {noise_sigma} must be within 0..50 grey levels")
    for a in actors:
        if abs(a.motion.fps - fps) > 1e-6:
            raise VideoWriteError(f"motion {a.motion.source!r} is at {a.motion.fps} fps, the "
                                  f"video at {fps}: resample it (read_bvh(..., fps={fps:g}))")
    T = n_frames or max(a.motion.n_frames for a in actors)
    body, posed = posed_sequences(actors, T)
    camera = scene_camera(posed, size, azimuth_deg, elevation_deg, distance_m)
    background = textured_background(size, seed)
    rng = np.random.default_rng(seed + 1)

    path.parent.mkdir(parents=True, exist_ok=True)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (size[1], size[0]))
    if not writer.isOpened():
        raise VideoWriteError(f"cannot write video {path}")
    P = len(actors)
    bbox = np.zeros((T, P, 4), np.int64)
    centroid = np.full((T, P, 2), np.nan)
    colours = [a.colour or _COLOURS[i % len(_COLOURS)] for i, a in enumerate(actors)]
    try:
        for t in range(T):
            image, masks = _shaded_people([v[t] for v, _ in posed], body.faces, camera, colours)
            for i, mask_i in enumerate(masks):
                ys, xs = np.nonzero(mask_i)
                if len(xs):
                    bbox[t, i] = [xs.min(), ys.min(), np.ptp(xs) + 1, np.ptp(ys) + 1]
                    centroid[t, i] = [xs.mean(), ys.mean()]
            frame = background.astype(np.float32)
            union = np.any(masks, axis=0)
            frame[union] = image[union]
            frame += rng.normal(0, noise_sigma, frame.shape).astype(np.float32)
            writer.write(cv2.cvtColor(np.clip(frame, 0, 255).astype(np.uint8), cv2.COLOR_RGB2BGR))
            if progress:
                progress(t + 1, T)
    finally:
        writer.release()

    pose = np.empty((T, P, POSE_DIM))
    hips = np.stack([root for _, root in posed], axis=1)          # (T, P, 3) metres
    for i, a in enumerate(actors):
        idx = np.minimum(np.arange(T), a.motion.n_frames - 1)
        az = line_of_sight_azimuth(hips[:, i], camera.position)
        clipped = Motion(**{**a.motion.__dict__, "euler_deg": a.motion.euler_deg[idx],
                            "root_position": a.motion.root_position[idx]})
        pose[:, i] = motion_to_pose_vectors(clipped, az)
    sidecar = truth_path(path)
    np.savez_compressed(
        sidecar, format_version=np.int64(TRUTH_FORMAT_VERSION), pose=pose, hips_m=hips,
        bbox_px=bbox, centroid_px=centroid, fps=np.float64(fps),
        camera_rotation=camera.rotation, camera_position=camera.position,
        camera_focal_px=np.float64(camera.focal_px), size=np.array(size),
        description=np.str_(json.dumps({"actors": [a.motion.source for a in actors],
                                        "noise_sigma": noise_sigma, "seed": seed})))
    return sidecar


def _shaded_people(verts: list[np.ndarray], faces: np.ndarray, camera: Camera, colours):
    """Shaded image (H, W, 3) uint8 of several posed bodies (each (V, 3) metres) and each
    one's own silhouette (P, H, W) bool. Where people overlap, the one whose hips are nearer
    the camera is drawn: people rarely interpenetrate, so this orders them correctly."""
    out = np.zeros((*camera.size, 3), np.uint8)
    depth = np.full(camera.size, np.inf)
    masks = np.zeros((len(verts), *camera.size), bool)
    for i, (v, colour) in enumerate(zip(verts, colours)):
        image, masks[i] = shaded_render(v, faces, camera, colour=colour)
        _, z = camera.project(v.mean(axis=0))
        nearer = masks[i] & (float(z) < depth)
        out[nearer] = image[nearer]
        depth[nearer] = float(z)
    return out, masks


def truth_path(video_path: str | Path) -> Path:
    """The ground-truth sidecar path of a video: 'walk.mp4' -> 'walk.truth.npz'."""
    p = Path(video_path)
    return p.with_name(p.stem + ".truth.npz")


#: Names OpenCV's writer takes write_video's mp4v codec in (checked with OpenCV 5.1); any other
#: name (.txt, no suffix) fails only once the frames are drawn, with OpenCV's own warnings.
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".m4v")


def partial_video(video_path: str | Path) -> Path:
    """Where :func:`replace_video` writes a video until it and its sidecar are complete:
    NAME.partial with the suffix kept last (OpenCV picks the container from it):
    'walk.mp4' -> 'walk.partial.mp4', whose sidecar is 'walk.partial.truth.npz'."""
    p = Path(video_path)
    return p.with_name(f"{p.stem}.partial{p.suffix}")


def replace_video(video_path: str | Path, render: Callable[[Path], object]) -> None:
    """Write a video and its ground-truth sidecar whole or not at all: render(partial) writes
    them (e.g. with :func:`write_video`) at :func:`partial_video`'s name, then both are renamed
    onto video_path and its sidecar. The old video goes first and the new one comes last, so
    a kill between the renames leaves no video (a cache renders it again), never a video
    beside another one's ground truth or without its own; if render fails or is interrupted,
    the old pair is as it was and the temporary files are removed."""
    path = Path(video_path)
    partial = partial_video(path)
    try:
        render(partial)
        path.unlink(missing_ok=True)
        os.replace(truth_path(partial), truth_path(path))
        os.replace(partial, path)
    finally:
        for leftover in (partial, truth_path(partial)):
            with contextlib.suppress(OSError):
                leftover.unlink(missing_ok=True)


def load_truth(video_path: str | Path) -> dict[str, np.ndarray]:
    """Read a video's ground-truth sidecar: pose (T, P, 55), hips_m (T, P, 3), bbox_px
    (T, P, 4) x y w h, centroid_px (T, P, 2), fps, camera_* fields."""
    sidecar = truth_path(video_path)
    try:
        with np.load(sidecar, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:
        raise VideoWriteError(f"{sidecar}: cannot read ground truth ({exc})") from exc
    if int(data.get("format_version", -1)) != TRUTH_FORMAT_VERSION:
        raise VideoWriteError(f"{sidecar}: unsupported ground-truth format")
    return data
