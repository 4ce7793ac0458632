"""Direction of travel from the image, and its fusion with a heading."""
from __future__ import annotations

import numpy as np
import pytest

from tracker.filtering import PoseKalmanFilter
from tracker.travel import TravelDirection, fuse_heading, travel_heading

FPS, WIDTH = 30.0, 640
CENTRE = (WIDTH - 1) / 2


def _heading_of(u, h):
    return travel_heading(np.asarray(u, float), np.asarray(h, float), FPS, WIDTH)


def test_sideways_and_depth_motions_give_the_pose_vector_headings():
    n = np.arange(15) - 14                            # ends on the optical axis
    assert _heading_of(CENTRE + 3 * n, np.full(15, 200.0))[0] == pytest.approx(90.0, abs=1e-6)
    assert _heading_of(CENTRE - 3 * n, np.full(15, 200.0))[0] == pytest.approx(-90.0, abs=1e-6)
    # Off the axis, the heading is relative to the line of sight: sideways travel 42 px right
    # of the centre is turned by the ray's angle atan(42 / f).
    f = 0.5 * WIDTH / np.tan(np.radians(30.0))
    assert _heading_of(CENTRE + 42 + 3 * n, np.full(15, 200.0))[0] == \
        pytest.approx(90.0 + np.degrees(np.arctan(42 / f)), abs=1e-6)
    growing = 200.0 * np.exp(0.01 * n)               # coming closer: towards the camera
    assert _heading_of(np.full(15, CENTRE), growing)[0] == pytest.approx(0.0, abs=1e-6)
    shrinking = 200.0 * np.exp(-0.01 * n)
    assert abs(_heading_of(np.full(15, CENTRE), shrinking)[0]) == pytest.approx(180.0, abs=1e-6)


def test_walking_straight_at_the_camera_off_axis_is_heading_zero():
    """A person right of the optical axis walking along the line of sight towards the camera:
    image x drifts outwards as they approach, but the heading is still 0."""
    f = 0.5 * WIDTH / np.tan(np.radians(30.0))
    X0, Z = 1.0, 10.0 - 0.05 * np.arange(15)          # metres; walking along the ray to (0, 0)
    X = X0 * Z / Z[0]
    u = CENTRE + f * X / Z
    h = f * 1.7 / Z
    assert _heading_of(u, h)[0] == pytest.approx(0.0, abs=1e-6)


def test_speed_is_in_body_heights_per_second():
    n = np.arange(15)
    _, speed = _heading_of(CENTRE + 4 * n, np.full(15, 200.0))    # 120 px/s, 200 px tall
    assert speed == pytest.approx(0.6)


def test_rolling_estimate_waits_for_its_window_and_for_motion():
    travel = TravelDirection(FPS, WIDTH, window=5, min_speed=0.15)
    out = [travel.push(CENTRE + 4 * (i - 4), 200.0) for i in range(5)]
    assert out[:4] == [None] * 4 and out[4] == pytest.approx(90.0)
    still = TravelDirection(FPS, WIDTH, window=5, min_speed=0.15)
    assert [still.push(CENTRE + 0.1 * i, 200.0) for i in range(8)][-1] is None


def _raw(heading_deg: float, norm: float) -> np.ndarray:
    raw = np.zeros(55)
    raw[0], raw[1] = norm * np.cos(np.radians(heading_deg)), norm * np.sin(np.radians(heading_deg))
    raw[2:] = 7.0
    return raw


def test_fused_heading_lies_between_by_inverse_variance():
    fused, variance = fuse_heading(_raw(170.0, 0.3), travel_deg=-170.0, raw_variance=100.0,
                                   travel_std_deg=10.0)
    # Equal variances: halfway across the +-180 seam, not through 0.
    assert abs(np.degrees(np.arctan2(fused[1], fused[0]))) == pytest.approx(180.0)
    assert variance == pytest.approx(50.0)
    assert np.hypot(fused[0], fused[1]) == pytest.approx(0.3)
    fused, _ = fuse_heading(_raw(0.0, 0.9), travel_deg=40.0, raw_variance=300.0,
                            travel_std_deg=10.0)
    assert np.degrees(np.arctan2(fused[1], fused[0])) == pytest.approx(30.0)


def test_heading_variance_overrides_the_ambiguity_inflation():
    """After a run at heading 0, one ambiguous frame reads 60. With its own heading variance
    (as after fusing the direction of travel) the filter follows it as far as a clear frame of
    that variance; with the model's inflated R it stays near 0."""
    def last_heading(norm: float, variance=None) -> float:
        kf = PoseKalmanFilter(FPS, R=np.full(54, 100.0), q=1e4, ambiguity_threshold=0.5)
        for _ in range(10):
            kf.step(_raw(0.0, 0.9))
        out, _ = kf.step(_raw(60.0, norm), heading_variance=variance)
        return float(np.degrees(np.arctan2(out[1], out[0])))
    clear, given, inflated = last_heading(0.9), last_heading(0.3, 100.0), last_heading(0.3)
    assert given == pytest.approx(clear)
    assert inflated < 0.3 * given
    assert last_heading(0.9, 25.0) > clear            # a smaller variance pulls harder
