"""Pinhole cameras and rendering of a posed body: binary silhouettes and Lambert-shaded images.

World: metres, Y up. A camera at azimuth az, elevation el sits in direction
(cos el sin az, sin el, cos el cos az) from its target, i.e. Ry(az) @ (0, 0, 1) tilted up by
el: az = 0 looks at a CMU body at rest from the front (the body faces +Z). Camera frame is
OpenCV's: x right, y down, z forward; pixel (u, v) = (column, row), pixel centres at integers.

Why a mask is filled one surface patch at a time: cv2.fillPoly fills by the even-odd rule, so
one call on all triangles leaves holes wherever an even number of triangles overlap (an arm in
front of the torso). The body is a closed surface, so the triangles facing the camera alone
cover the silhouette; those of one small surface patch hardly overlap each other, and separate
calls OR together, so ~500 vectorized calls (10 triangles each) give the union at half the cost of drawing all
triangles. tests/test_render.py checks the result against a per-triangle reference.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from regressor.errors import SilhouettePoseError

_SHIFT = 3                 # fillPoly fixed-point fraction bits: 1/8 pixel vertex precision
_NEAR_M = 0.05             # triangles with a vertex nearer than this to the camera are dropped


class RenderError(SilhouettePoseError, ValueError):
    """Bad camera or render input (shapes, non-finite values, impossible settings)."""


@dataclass(frozen=True)
class Camera:
    """A pinhole camera. rotation: (3, 3) world -> camera (rows: right, down, forward axes in
    world coordinates); position: (3,) metres; focal_px: focal length in pixels; size:
    (height, width) in pixels; principal point at the image centre."""

    rotation: np.ndarray
    position: np.ndarray
    focal_px: float
    size: tuple[int, int]

    @property
    def principal_point(self) -> tuple[float, float]:
        """(cx, cy) in pixels."""
        return (self.size[1] - 1) / 2.0, (self.size[0] - 1) / 2.0

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates (..., 2) (u right, v down) and depths (...,) in metres of world
        points (..., 3) in metres."""
        cam = (np.asarray(points, dtype=np.float64) - self.position) @ self.rotation.T
        z = cam[..., 2]
        safe = np.where(z > 1e-9, z, 1e-9)
        cx, cy = self.principal_point
        uv = np.stack([self.focal_px * cam[..., 0] / safe + cx,
                       self.focal_px * cam[..., 1] / safe + cy], axis=-1)
        return uv, z


def _check_size(size) -> tuple[int, int]:
    h, w = (int(s) for s in size)
    if h < 1 or w < 1:
        raise RenderError(f"image size must be positive (height, width), got {size}")
    return h, w


def look_at_camera(target, azimuth_deg: float, elevation_deg: float, distance_m: float,
                   focal_px: float, size: tuple[int, int]) -> Camera:
    """Camera distance_m metres from target (3,) metres, in direction az/el (degrees, see module
    docstring), looking at the target, upright (image up = world +Y). Fixed world cameras for
    videos are made with this too (target = a point of the scene)."""
    if not abs(elevation_deg) < 89.0:
        raise RenderError(f"elevation_deg = {elevation_deg}: must be within (-89, 89) degrees")
    if not (distance_m > 0 and focal_px > 0):
        raise RenderError(f"distance_m ({distance_m}) and focal_px ({focal_px}) must be > 0")
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    direction = np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
    position = np.asarray(target, dtype=np.float64) + distance_m * direction
    forward = -direction
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    return Camera(np.stack([right, down, forward]), position, float(focal_px), _check_size(size))


def centred_camera(vertices: np.ndarray, azimuth_deg: float, elevation_deg: float,
                   size: tuple[int, int], person_px: float = 240.0, distance_m: float = 5.0,
                   reference_height_m: float | None = None) -> Camera:
    """Camera distance_m from the body (vertices (V, 3) metres), az/el in degrees, aimed so
    that the projected vertices' bounding box is centred in the image, with the focal length
    that images reference_height_m metres (default: the vertices' vertical extent) at
    person_px pixels at that distance. Pass the body's standing height as reference_height_m
    to keep crouches smaller than standing poses."""
    v = np.asarray(vertices, dtype=np.float64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    height = hi[1] - lo[1] if reference_height_m is None else reference_height_m
    if not height > 0:
        raise RenderError(f"reference height must be > 0 metres, got {height}")
    focal = person_px * distance_m / height
    target = (lo + hi) / 2
    camera = look_at_camera(target, azimuth_deg, elevation_deg, distance_m, focal, size)
    # The 3-D box centre need not project to the 2-D box centre: move the target sideways.
    uv, _ = camera.project(v)
    offset = (uv.min(axis=0) + uv.max(axis=0)) / 2 - camera.principal_point
    target = target + (distance_m / focal) * (offset[0] * camera.rotation[0]
                                              + offset[1] * camera.rotation[1])
    return look_at_camera(target, azimuth_deg, elevation_deg, distance_m, focal, size)


def _projected_triangles(vertices, faces, camera: Camera):
    """Fixed-point pixel triangles (F, 3, 2) int32, visibility (F,) bool, facing (F,) bool
    (True: outward side towards the camera), vertex depths (F, 3) metres."""
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or not np.isfinite(v).all():
        raise RenderError(f"vertices must be finite (V, 3) metres, got shape {v.shape}")
    uv, z = camera.project(v)
    limit = 4.0 * max(camera.size)                 # keep fixed-point coordinates in int32
    fixed = np.rint(np.clip(uv, -limit, 2 * limit) * (1 << _SHIFT)).astype(np.int32)
    tri = fixed[faces]                             # (F, 3, 2)
    tri_z = z[faces]
    visible = tri_z.min(axis=1) > _NEAR_M
    e = (tri[:, 1:] - tri[:, :1]).astype(np.int64)  # exact integer edge vectors
    # Image y points down, so a counter-clockwise (outward) face seen from outside has a
    # negative signed area in pixel coordinates.
    facing = (e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0]) < 0
    return tri, visible, facing, tri_z


def silhouette_mask(vertices: np.ndarray, faces: np.ndarray, patch_start: np.ndarray,
                    camera: Camera) -> np.ndarray:
    """Binary silhouette (H, W) bool of posed vertices (V, 3) metres of a closed mesh, faces
    (F, 3) (outward normals) sorted by surface patch with patch_start (P + 1,) offsets (as
    BodyModel provides)."""
    tri, visible, facing, _ = _projected_triangles(vertices, faces, camera)
    mask = np.zeros(camera.size, dtype=np.uint8)
    kept = np.flatnonzero(visible & facing)
    bounds = np.searchsorted(kept, patch_start)    # faces are sorted by patch
    tri = tri[kept]
    for lo, hi in zip(bounds[:-1].tolist(), bounds[1:].tolist()):
        if hi > lo:
            cv2.fillPoly(mask, tri[lo:hi], 1, lineType=cv2.LINE_8, shift=_SHIFT)
    return mask.astype(bool)


def shaded_render(vertices: np.ndarray, faces: np.ndarray, camera: Camera,
                  colour=(205, 170, 150), background=(0, 0, 0),
                  ambient: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """Lambert-shaded image of a posed mesh for videos.

    vertices: (V, 3) metres; faces: (F, 3); colour, background: RGB 0-255; ambient: fraction
    of light that does not depend on the surface direction. The light comes from behind the
    camera, above it. Triangles facing the camera are painted far to near (painter's
    algorithm, a Python loop over triangles: a few ms a frame, for offline video writing).
    Returns image (H, W, 3) uint8 RGB and mask (H, W) bool.
    """
    tri, visible, facing, tri_z = _projected_triangles(vertices, faces, camera)
    v = np.asarray(vertices, dtype=np.float64)
    corners = v[faces]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True) + 1e-12
    light = -camera.rotation[2] - 0.6 * camera.rotation[1]      # from the camera, from above
    light /= np.linalg.norm(light)
    lambert = np.clip(normal @ light, 0.0, None)
    shade = ambient + (1.0 - ambient) * lambert
    rgb = np.clip(np.outer(shade, colour), 0, 255).astype(np.uint8)
    image = np.empty((*camera.size, 3), dtype=np.uint8)
    image[:] = np.asarray(background, dtype=np.uint8)
    mask = np.zeros(camera.size, dtype=np.uint8)
    keep = np.flatnonzero(visible & facing)                     # closed mesh: front faces do
    keep = keep[np.argsort(-tri_z[keep].mean(axis=1))]          # far first
    for f in keep:                                              # same fill rule as the masks
        cv2.fillPoly(image, [tri[f]], rgb[f].tolist(), lineType=cv2.LINE_8, shift=_SHIFT)
        cv2.fillPoly(mask, [tri[f]], 1, lineType=cv2.LINE_8, shift=_SHIFT)
    return image, mask.astype(bool)
