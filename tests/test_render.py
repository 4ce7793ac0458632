"""Cameras and silhouette / shaded rendering of the posed body."""
from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sequences.body import BodyShape, Skinner, load_body
from sequences.render import (RenderError, _projected_triangles, centred_camera, look_at_camera,
                              shaded_render, silhouette_mask)
from sequences.skeleton import CMU_JOINT_NAMES

J = len(CMU_JOINT_NAMES)
SIZE = (300, 300)
FOCAL = 600.0


@pytest.fixture(scope="module")
def body():
    return load_body()


def _posed(body, shape=BodyShape(), rotations=None):
    """Body in the CMU T-pose (identity rotations, or the given ones), feet on y = 0."""
    sk = Skinner(body, shape=shape)
    R = np.broadcast_to(np.eye(3), (J, 3, 3)).copy() if rotations is None else rotations
    v = sk.pose(R, sk.rest_root_m)
    return v - [0.0, v[:, 1].min(), 0.0], sk


def _mask(body, v, camera):
    return silhouette_mask(v, body.faces, body.patch_start, camera)


def _bbox(mask):
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    return rows[0], rows[-1], cols[0], cols[-1]


def test_mask_area_falls_with_the_square_of_distance(body):
    v, _ = _posed(body)
    areas = [_mask(body, v, look_at_camera([0, 0.85, 0], 20, 0, d, FOCAL, SIZE)).sum()
             for d in (5.0, 10.0)]
    assert areas[0] / areas[1] == pytest.approx(4.0, rel=0.08)


def test_seen_from_above_the_person_looks_shorter(body):
    v, _ = _posed(body)
    level = _bbox(_mask(body, v, look_at_camera([0, 0.85, 0], 0, 0, 6.0, FOCAL, SIZE)))
    above = _bbox(_mask(body, v, look_at_camera([0, 0.85, 0], 0, 60, 6.0, FOCAL, SIZE)))
    assert above[1] - above[0] < 0.8 * (level[1] - level[0])


def test_person_is_upright_with_head_on_top_and_feet_on_the_ground(body):
    v, sk = _posed(body)
    cam = look_at_camera([0, 0.85, 0], 0, 0, 6.0, FOCAL, SIZE)
    top, bottom, left, right = _bbox(_mask(body, v, cam))
    P, _ = sk.joints(np.broadcast_to(np.eye(3), (J, 3, 3)), sk.rest_root_m)
    head = cam.project(P[0, CMU_JOINT_NAMES.index("Head")] - [0, v[:, 1].min(), 0])[0]
    ground = cam.project(np.array([0.0, 0.0, 0.0]))[0]
    assert top <= head[1] <= top + 0.15 * (bottom - top)
    assert abs(bottom - ground[1]) <= 2.0                   # lowest pixels on the floor line
    assert bottom - top > 0.8 * (right - left)              # T-pose: wide but still tall


def test_azimuth_convention_left_hand_on_image_right_seen_from_the_front(body):
    v, sk = _posed(body)
    P, _ = sk.joints(np.broadcast_to(np.eye(3), (J, 3, 3)), sk.rest_root_m)
    front = look_at_camera([0, 0.85, 0], 0, 0, 6.0, FOCAL, SIZE)
    side = look_at_camera([0, 0.85, 0], 90, 0, 6.0, FOCAL, SIZE)
    hand = P[0, CMU_JOINT_NAMES.index("LeftHand")]
    assert front.project(hand)[0][0] > front.principal_point[0] + 50
    assert side.position[0] > 5.0                           # az 90: camera on the +X side
    front_w = np.ptp(np.flatnonzero(_mask(body, v, front).any(axis=0)))
    side_w = np.ptp(np.flatnonzero(_mask(body, v, side).any(axis=0)))
    assert side_w < 0.4 * front_w                           # T-pose arms vanish edge-on


def test_taller_and_broader_bodies_give_taller_and_wider_masks(body):
    cam = look_at_camera([0, 0.85, 0], 0, 0, 6.0, FOCAL, SIZE)
    arms_down = np.broadcast_to(np.eye(3), (J, 3, 3)).copy()
    for name, angle in (("LeftArm", -70), ("RightArm", 70)):
        arms_down[CMU_JOINT_NAMES.index(name)] = Rotation.from_euler(
            "z", angle, degrees=True).as_matrix()

    def box(shape):
        t, b, l, r = _bbox(_mask(body, _posed(body, shape, arms_down)[0], cam))
        return b - t, r - l
    h0, w0 = box(BodyShape())
    h1, _ = box(BodyShape(height_scale=1.1))
    _, w2 = box(BodyShape(girth_scale=1.3))
    assert h1 / h0 == pytest.approx(1.1, abs=0.03)
    assert w2 > w0 + 4


def test_centred_camera_makes_the_person_the_requested_height(body):
    v, _ = _posed(body)
    cam = centred_camera(v, 45, 0, (320, 260), person_px=240)
    top, bottom, left, right = _bbox(_mask(body, v, cam))
    assert bottom - top == pytest.approx(240, abs=8)
    assert abs((top + bottom) / 2 - 159.5) < 2 and abs((left + right) / 2 - 129.5) < 2


def test_mask_equals_per_triangle_rasterization(body):
    rng = np.random.default_rng(0)
    sk = Skinner(body)
    for k in range(6):
        R = Rotation.from_rotvec(rng.normal(0, 0.5, (J, 3))).as_matrix()
        v = sk.pose(R, np.zeros(3))
        cam = centred_camera(v, rng.uniform(0, 360), rng.uniform(-10, 45), (300, 300), 240)
        tri, visible, _, _ = _projected_triangles(v, body.faces, cam)
        reference = np.zeros(cam.size, np.uint8)
        for t in tri[visible]:                  # every triangle, one at a time: the union
            cv2.fillPoly(reference, [t], 1, cv2.LINE_8, 3)
        reference = reference.astype(bool)
        mask = _mask(body, v, cam)
        assert not (mask & ~reference).any()
        assert (reference & ~mask).sum() < 0.01 * reference.sum()
        interior = cv2.erode(reference.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        assert (interior & ~mask).sum() <= 5    # no holes inside the silhouette


def test_shaded_render_colours_the_silhouette_only(body):
    v, _ = _posed(body)
    cam = look_at_camera([0, 0.85, 0], 30, 10, 6.0, FOCAL, SIZE)
    image, mask = shaded_render(v, body.faces, cam, background=(0, 0, 255))
    assert image.shape == (*SIZE, 3) and image.dtype == np.uint8
    silhouette = _mask(body, v, cam)
    assert (mask != silhouette).sum() < 0.02 * silhouette.sum()
    assert np.all(image[~mask] == [0, 0, 255])
    lum = image[mask].astype(float).sum(axis=1)
    assert lum.min() > 0 and lum.std() > 10                 # shaded, not flat


def test_bad_camera_and_vertices_are_refused(body):
    with pytest.raises(RenderError, match="elevation_deg"):
        look_at_camera([0, 1, 0], 0, 90, 5.0, FOCAL, SIZE)
    with pytest.raises(RenderError, match="distance_m"):
        look_at_camera([0, 1, 0], 0, 0, -1.0, FOCAL, SIZE)
    cam = look_at_camera([0, 1, 0], 0, 0, 5.0, FOCAL, SIZE)
    bad = body.vertices.copy()
    bad[0, 0] = np.nan
    with pytest.raises(RenderError, match="finite"):
        silhouette_mask(bad, body.faces, body.patch_start, cam)
