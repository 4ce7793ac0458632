"""Solid bodies as one triangle mesh: a cylinder per bone, a sphere per joint, a ball of a head.

Pure numpy, for the meshcat view (one mesh per track per frame is one message, where an object
per bone would be 35). Vertex colours carry the body sides (tracker.outputs.geometry.body_colours).
"""
from __future__ import annotations

import numpy as np

from tracker.outputs.geometry import BONE_INDEX, BONE_SIDE, JOINT_SIDE, POSE_JOINTS

_HEAD, _NECK = POSE_JOINTS.index("Head"), POSE_JOINTS.index("Neck")
_CYLINDER_SIDES = 10


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


def joint_spheres(centres: np.ndarray, radius_m) -> tuple[np.ndarray, np.ndarray]:
    """One triangle mesh of a sphere around every centre.

    centres: (N, 3) metres; radius_m: a number or (N,) metres. Returns vertices (N * 42, 3)
    float32 and faces (N * 80, 3) uint32.
    """
    n = len(centres)
    radius = np.broadcast_to(np.asarray(radius_m, dtype=np.float64), (n,))
    vertices = centres[:, None, :] + radius[:, None, None] * _SPHERE_VERTICES[None]
    faces = _SPHERE_FACES[None] + len(_SPHERE_VERTICES) * np.arange(n)[:, None, None]
    return vertices.reshape(-1, 3).astype(np.float32), faces.reshape(-1, 3).astype(np.uint32)


def bone_cylinders(starts: np.ndarray, ends: np.ndarray, radius_m: float
                   ) -> tuple[np.ndarray, np.ndarray]:
    """One triangle mesh of open cylinders (the joint spheres close them), start to end.

    starts, ends: (N, 3) metres, of non-zero length. Returns vertices (N * 2S, 3) float32 and
    faces (N * 2S, 3) uint32, S = 10 sides.
    """
    axis = ends - starts
    axis = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    # Any vector not parallel to the axis gives the first radial direction.
    helper = np.where(np.abs(axis[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    u = np.cross(axis, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(axis, u)
    angles = 2 * np.pi * np.arange(_CYLINDER_SIDES) / _CYLINDER_SIDES
    ring = radius_m * (np.cos(angles)[None, :, None] * u[:, None] +
                       np.sin(angles)[None, :, None] * v[:, None])           # (N, S, 3)
    vertices = np.concatenate([starts[:, None] + ring, ends[:, None] + ring], axis=1)
    s = np.arange(_CYLINDER_SIDES)
    s1 = (s + 1) % _CYLINDER_SIDES
    quad = np.concatenate([np.stack([s, s1, s + _CYLINDER_SIDES], 1),
                           np.stack([s1, s1 + _CYLINDER_SIDES, s + _CYLINDER_SIDES], 1)])
    faces = quad[None] + 2 * _CYLINDER_SIDES * np.arange(len(starts))[:, None, None]
    return vertices.reshape(-1, 3).astype(np.float32), faces.reshape(-1, 3).astype(np.uint32)


def body_mesh(joints: np.ndarray, colours: np.ndarray, bone_radius_m: float = 0.035,
              joint_radius_m: float = 0.05, head_radius_m: float = 0.11
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A body as one mesh: a cylinder per drawn bone, a sphere per joint, a head ball.

    joints: (18, 3) metres (any axes); colours: (3, 3) RGB of the CENTRE, LEFT and RIGHT sides
    (geometry.body_colours). The head ball sits on the neck-to-head line, one radius past the
    head joint. Returns vertices (V, 3) float32, faces (F, 3) uint32, vertex colours (V, 3)
    float32. Zero-length bones (Spine1, Neck and shoulders meet at one point) are left out.
    """
    starts, ends = joints[BONE_INDEX[:, 0]], joints[BONE_INDEX[:, 1]]
    keep = np.linalg.norm(ends - starts, axis=1) > 1e-6
    neck_to_head = joints[_HEAD] - joints[_NECK]
    length = np.linalg.norm(neck_to_head)
    up = neck_to_head / length if length > 1e-6 else np.zeros(3)
    centres = np.concatenate([joints, (joints[_HEAD] + head_radius_m * up)[None]])
    radii = np.r_[np.full(len(joints), joint_radius_m), head_radius_m]
    parts = [bone_cylinders(starts[keep], ends[keep], bone_radius_m), joint_spheres(centres, radii)]
    part_sides = [np.repeat(BONE_SIDE[keep], 2 * _CYLINDER_SIDES),
                  np.repeat(np.r_[JOINT_SIDE, JOINT_SIDE[_HEAD]], len(_SPHERE_VERTICES))]
    offset, vertices, faces = 0, [], []
    for v, f in parts:
        vertices.append(v)
        faces.append(f + offset)
        offset += len(v)
    sides = np.concatenate(part_sides)
    return (np.concatenate(vertices), np.concatenate(faces).astype(np.uint32),
            np.asarray(colours, dtype=np.float32)[sides])
