"""Where the live view's camera looks: at every tracked person and the video screen beside them,
following them as they move.

Z-up metres: the video camera sits at the origin looking along +Y (horizontal field of view
``tracker.video.decode.ASSUMED_FOV_DEG``); people stand on z = 0. The view looks the same way
with the same vertical field of view, from higher up (``elevation_deg``: the walked path shows)
and far enough back that the people (left) and the screen (right) fit. The look-at point
follows the people smoothly; the distance and the screen move only when the people spread out
or gather by more than a margin, so a viewer is not nudged every frame.
"""
from __future__ import annotations

import math

import numpy as np

from tracker.video.decode import ASSUMED_FOV_DEG

#: Body half-width plus margin around the outermost root, metres.
_BODY_HALF_WIDTH_M = 0.6
#: Top of a body with its label above the ground, metres.
_TOP_M = 2.3


class Framing:
    """The view's look-at point, camera offset and screen place for the people in view.

    fov_deg: horizontal field of view of the video camera (the tracker's assumption); aspect:
    the video's width / height (vertical field of view = the video's); elevation_deg: the view
    looks down by this much; screen_size_m: (width, height) of the video screen; gap_m: between
    the people and the screen; follow_time_s: time constant of the smooth follow; look_height_m:
    height of the look-at point above the ground.

    Attributes: target (3,) the people's smoothed mean ground position, raised to
    look_height_m; look_at (3,) the point the camera looks at (right of target, between the
    people and the screen); camera_offset (3,) and screen_centre (3,) relative to look_at;
    people_half_width_m; camera_distance_m.
    """

    def __init__(self, fov_deg: float = ASSUMED_FOV_DEG, aspect: float = 4 / 3,
                 elevation_deg: float = 18.0, screen_size_m: tuple[float, float] = (1.6, 1.2),
                 gap_m: float = 0.4, follow_time_s: float = 0.6, look_height_m: float = 0.9):
        self.aspect = max(float(aspect), 4 / 3)   # browser windows are rarely narrower
        self.vertical_fov_deg = math.degrees(
            2 * math.atan(math.tan(math.radians(fov_deg) / 2) / float(aspect)))
        self.elevation = math.radians(elevation_deg)
        self.screen_size_m = screen_size_m
        self.gap_m = gap_m
        self.follow_time_s = follow_time_s
        self.look_height_m = look_height_m
        self.target = np.array([0.0, 0.0, look_height_m])
        self.people_half_width_m = _BODY_HALF_WIDTH_M
        self.camera_distance_m = self._distance(self.people_half_width_m, 0.0)
        self._time_s: float | None = None

    @property
    def view_direction(self) -> np.ndarray:
        """(3,) unit vector from the look-at point towards the camera."""
        return np.array([0.0, -math.cos(self.elevation), math.sin(self.elevation)])

    @property
    def camera_offset(self) -> np.ndarray:
        """(3,) camera position relative to look_at, metres."""
        return self.camera_distance_m * self.view_direction

    @property
    def screen_centre(self) -> np.ndarray:
        """(3,) centre of the video screen relative to look_at: right of the people, at mid
        height of a body."""
        return np.array([self.people_half_width_m + self.gap_m / 2, 0.0,
                         0.95 - self.look_height_m])

    def facing_rotation(self) -> np.ndarray:
        """(3, 3) rotation whose columns are right, up and the normal of a plane facing the
        view camera (a PlaneGeometry's X, Y and Z axes)."""
        normal = self.view_direction
        right = np.array([1.0, 0.0, 0.0])
        return np.column_stack([right, np.cross(normal, right), normal])

    def _distance(self, half_width: float, depth: float) -> float:
        width, height = self.screen_size_m
        half_fov_v = math.radians(self.vertical_fov_deg) / 2
        horizontal = (half_width + (self.gap_m + width) / 2 + 0.2) / (
            math.tan(half_fov_v) * self.aspect)
        vertical = max(_TOP_M - self.look_height_m, self.look_height_m, height / 2) + 0.1
        return max(horizontal, vertical / math.tan(half_fov_v)) + depth

    def update(self, roots: np.ndarray, time_s: float) -> bool:
        """Follow the people whose roots (N, 3) (Z-up metres, N >= 1) are in view at time_s.
        Returns True when the camera distance or the screen's place changed."""
        roots = np.asarray(roots, dtype=np.float64)
        centre = roots[:, :2].mean(axis=0)
        if self._time_s is None:
            self._time_s = time_s
            self.target[:2] = centre
        else:
            step = 1.0 - math.exp(-max(time_s - self._time_s, 0.0) / self.follow_time_s)
            self._time_s = time_s
            self.target[:2] += step * (centre - self.target[:2])
        # The screen is right of the people: shift the look-at point to the middle of both.
        spread = np.abs(roots[:, :2] - centre)
        half_width = float(spread[:, 0].max()) + _BODY_HALF_WIDTH_M
        depth = float(spread[:, 1].max())
        changed = False
        if half_width > self.people_half_width_m or half_width < 0.6 * self.people_half_width_m:
            self.people_half_width_m = max(1.1 * half_width, _BODY_HALF_WIDTH_M)
            changed = True
        needed = self._distance(self.people_half_width_m, depth)
        if needed > self.camera_distance_m or needed < 0.75 * self.camera_distance_m or changed:
            self.camera_distance_m = 1.05 * needed
            changed = True
        return changed

    @property
    def look_at(self) -> np.ndarray:
        """(3,) absolute point the view camera looks at: between the people and the screen."""
        width = self.screen_size_m[0]
        return self.target + [(self.gap_m + width) / 2, 0.0, 0.0]
