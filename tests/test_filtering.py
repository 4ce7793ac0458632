"""Pose Kalman filter: less jitter, no jump at +-180, ambiguous frames trusted less, RTS."""
from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from regressor.angles import angles_to_pose, heading_norm, pose_angles, wrap_deg
from tracker.tracks.filtering import FilterError, PoseKalmanFilter

FPS = 30.0


@pytest.fixture(autouse=True, scope="module")
def one_blas_thread():
    """108x108 products are too small to share: with OpenBLAS threads on a busy 2-core machine
    these tests ran 8x slower (25 s instead of 3 s). The track command should do the same."""
    with threadpool_limits(limits=1, user_api="blas"):
        yield


def true_angles(frames: int, seed: int = 0) -> np.ndarray:
    """Smooth angle trajectories (frames, 54) deg: sinusoids of 0.2-0.8 Hz, amplitude 10-40 deg
    (accelerations up to 1000 deg/s^2, as in motion capture), heading turning at 45 deg/s."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None] / FPS
    freq, amp, phase = rng.uniform(0.2, 0.8, 54), rng.uniform(10, 40, 54), rng.uniform(0, 6, 54)
    angles = amp * np.sin(2 * np.pi * freq * t + phase)
    angles[:, 0] = 45.0 * t[:, 0]
    return angles


def noisy_poses(angles: np.ndarray, std: float, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return angles_to_pose(angles + rng.normal(0.0, std, angles.shape))


def angle_error(poses: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Wrapped error (T, 54) deg between poses (T, 55) and true angles (T, 54)."""
    return wrap_deg(pose_angles(poses) - angles)


def jitter(poses: np.ndarray) -> float:
    """Mean |second difference| over frames and angles, deg."""
    angles = np.unwrap(np.radians(pose_angles(poses)), axis=0)
    return float(np.mean(np.abs(np.diff(np.degrees(angles), 2, axis=0))))


def run(kf: PoseKalmanFilter, poses: np.ndarray) -> tuple[np.ndarray, list[bool]]:
    outputs = [kf.step(p) for p in poses]
    return np.array([o[0] for o in outputs]), [o[1] for o in outputs]


def test_pose_angle_conversions_round_trip():
    angles = wrap_deg(np.random.default_rng(0).uniform(-400, 400, (5, 54)))
    poses = angles_to_pose(angles)
    back, norm = pose_angles(poses), heading_norm(poses)
    assert np.allclose(wrap_deg(back - angles), 0, atol=1e-9)
    assert np.allclose(norm, 1.0)
    assert wrap_deg(np.array([180.0, -180.0, 540.0, -179.0])).tolist() == [180, 180, 180, -179]


def test_filter_reduces_error_and_jitter_on_noisy_trajectory():
    truth = true_angles(150)
    raw = noisy_poses(truth, std=6.0)
    filtered, flags = run(PoseKalmanFilter(FPS), raw)
    raw_rms = np.sqrt(np.mean(angle_error(raw, truth)[30:] ** 2))
    filtered_rms = np.sqrt(np.mean(angle_error(filtered, truth)[30:] ** 2))
    assert filtered_rms < 0.8 * raw_rms
    assert jitter(filtered) < 0.4 * jitter(raw)
    assert not any(flags)


def test_outputs_keep_the_55_d_layout():
    filtered, _ = run(PoseKalmanFilter(FPS), noisy_poses(true_angles(40) * 6, std=20.0))
    assert filtered.shape == (40, 55)
    assert np.allclose(np.hypot(filtered[:, 0], filtered[:, 1]), 1.0)
    assert (filtered[:, 2:] > -180).all() and (filtered[:, 2:] <= 180).all()


def test_heading_and_joint_crossing_180_do_not_jump():
    frames = 80
    truth = np.zeros((frames, 54))
    truth[:, 0] = 90 + 3.0 * np.arange(frames)       # heading passes +180 -> -180 at frame 30
    truth[:, 7] = -120 - 2.0 * np.arange(frames)     # a joint angle passes -180 -> +180 at 30
    filtered, _ = run(PoseKalmanFilter(FPS), angles_to_pose(wrap_deg(truth)))
    error = angle_error(filtered, truth)
    # The filter starts at rate 0 and needs ~20 frames to lock on to the ramps; after that a
    # wrong unwrap would show as a 360 deg error or a jump.
    assert np.abs(error[20:]).max() < 1.0
    steps = np.abs(wrap_deg(np.diff(pose_angles(filtered), axis=0)))
    assert steps[:, 0].max() < 4.0 and steps[:, 7].max() < 3.0


def test_ambiguous_frame_is_flagged_and_trusted_less():
    steady = angles_to_pose(np.zeros((20, 54)))
    outlier_angles = np.zeros(54)
    outlier_angles[0], outlier_angles[1:] = 90.0, 20.0
    outlier = angles_to_pose(outlier_angles)
    deviation = {}
    for norm in (1.0, 0.3):
        kf = PoseKalmanFilter(FPS, ambiguity_threshold=0.5)
        run(kf, steady)
        raw = outlier.copy()
        raw[:2] *= norm
        filtered, ambiguous = kf.step(raw)
        assert ambiguous == (norm < 0.5)
        deviation[norm] = np.abs(pose_angles(filtered))
    assert deviation[0.3][0] < deviation[1.0][0] / 3      # heading: R x 25
    assert deviation[0.3][1:].max() < deviation[1.0][1:].min() / 1.5   # other angles: R x 4


def test_rts_smoother_beats_forward_filter():
    truth = true_angles(120, seed=3)
    raw = noisy_poses(truth, std=6.0, seed=4)
    forward, _ = run(PoseKalmanFilter(FPS), raw)
    smoothed = PoseKalmanFilter(FPS).rts_smooth(raw)
    assert smoothed.shape == (120, 55)
    forward_rms = np.sqrt(np.mean(angle_error(forward, truth) ** 2))
    smoothed_rms = np.sqrt(np.mean(angle_error(smoothed, truth) ** 2))
    assert smoothed_rms < 0.85 * forward_rms
    assert jitter(smoothed) < jitter(forward)


def test_windowed_smoothing_matches_one_pass():
    raw = noisy_poses(true_angles(90, seed=5), std=6.0, seed=6)
    raw[28:33, :2] *= 0.2  # ambiguous frames near a window boundary
    kf = PoseKalmanFilter(FPS)
    one_pass = kf.rts_smooth(raw, window=1000)
    windowed = kf.rts_smooth(raw, window=30, lag=30)
    assert np.abs(angle_error(windowed, pose_angles(one_pass))).max() < 0.05
    no_lag = kf.rts_smooth(raw, window=30, lag=0)
    assert np.abs(angle_error(no_lag, pose_angles(one_pass))).max() > 0.5


def test_the_smoother_is_filterpys_rts_smoother():
    """The numpy smoother (ConstantVelocityFilter.smooth) gives what filterpy's KalmanFilter
    and rts_smoother give, with per-frame R (ambiguous frames inflated) and angle unwrapping,
    on a pose track with the shipped model's noise models."""
    from regressor.pose_model import load_pose_model
    model = load_pose_model()
    raw = noisy_poses(true_angles(80, seed=7), std=6.0, seed=8)
    raw[20:26, :2] *= 0.2                                   # ambiguous: R inflated there
    kf = PoseKalmanFilter(FPS, R=model.measurement_covariance, q=model.process_noise)
    angles, Rs, ambiguous = kf._measure_all(raw, "test")
    assert ambiguous[20:26].all() and not ambiguous[:20].any()
    ours = kf.cv.smooth(angles, Rs, window=1000)
    from tracker.tracks.filterpy_runs import smooth
    reference = smooth(kf.cv, angles, Rs)
    assert np.abs(ours - reference).max() < 1e-6
    assert np.abs(ours - angles).max() > 1.0                # it did smooth


def test_smoothing_leaves_the_step_state_alone():
    raw = noisy_poses(true_angles(30), std=6.0)
    a, b = PoseKalmanFilter(FPS), PoseKalmanFilter(FPS)
    run(a, raw[:10])
    run(b, raw[:10])
    a.rts_smooth(raw)
    assert np.array_equal(a.step(raw[10])[0], b.step(raw[10])[0])


def test_noise_model_from_arrays_changes_the_filter():
    raw = noisy_poses(true_angles(60), std=6.0)
    default, _ = run(PoseKalmanFilter(FPS), raw)
    trusting, _ = run(PoseKalmanFilter(FPS, R=np.full(54, 0.01), q=np.full(54, 1e10)), raw)
    assert np.abs(angle_error(trusting, pose_angles(raw))).max() < 0.5
    assert np.abs(angle_error(default, pose_angles(raw))).max() > 2.0


@pytest.mark.parametrize("bad, message", [
    (np.zeros(54), r"shape \(55,\)"),
    (np.r_[1.0, 0.0, np.full(52, 0.0), np.nan], "non-finite entries at \\[54\\]"),
])
def test_bad_pose_vectors_are_refused(bad, message):
    with pytest.raises(FilterError, match=message):
        PoseKalmanFilter(FPS).step(bad)


@pytest.mark.parametrize("options", [{"fps": 0.0}, {"R": np.ones(10)}, {"R": -np.eye(54)},
                                     {"q": -1.0}, {"ambiguous_heading_factor": 0.5}])
def test_bad_settings_are_refused(options):
    settings = {"fps": FPS, **options}
    with pytest.raises(FilterError):
        PoseKalmanFilter(**settings)


def test_step_matches_the_batch_filter():
    poses = noisy_poses(true_angles(60), std=5.0)
    poses[::4, :2] *= 0.2                      # ambiguous frames too (R inflated)
    kf = PoseKalmanFilter(FPS)
    stepped = np.array([kf.step(p)[0] for p in poses])
    angles, Rs, _ = kf._measure_all(poses, "test")
    from tracker.tracks.filterpy_runs import forward
    batch = angles_to_pose(forward(PoseKalmanFilter(FPS).cv, angles, Rs))    # filterpy's
    np.testing.assert_allclose(pose_angles(stepped), pose_angles(batch), atol=1e-8)


def test_copy_is_independent_and_scoring_leaves_the_state_alone():
    poses = noisy_poses(true_angles(12), std=5.0)
    a = PoseKalmanFilter(FPS)
    for p in poses[:10]:
        a.step(p)
    before = a.log_likelihoods(poses[10:12])
    b = a.copy()
    b.step(poses[11])
    np.testing.assert_array_equal(a.log_likelihoods(poses[10:12]), before)
    fresh = PoseKalmanFilter(FPS)
    for p in poses[:10]:
        fresh.step(p)
    assert np.array_equal(a.step(poses[10])[0], fresh.step(poses[10])[0])



def test_copies_share_their_covariance_and_still_filter_as_independent_filters():
    """A filter and its copies (a track's front/back hypotheses) compute the covariance's
    prediction, factor and update once; their poses are an independent filter's bit for bit,
    a different ambiguity parts their covariances, and old covariances are not kept."""
    import gc
    import weakref
    poses = noisy_poses(true_angles(30), std=5.0)
    flipped = noisy_poses(true_angles(30, seed=4), std=5.0)
    poses[::5, :2] *= 0.2                       # ambiguous frames: R inflated
    flipped[::5, :2] *= 0.2
    a = PoseKalmanFilter(FPS)
    b = a.copy()                                # before the first step, as FrontBackTracker's
    lone_a, lone_b = PoseKalmanFilter(FPS), PoseKalmanFilter(FPS)
    for p, q in zip(poses[:20], flipped[:20]):
        np.testing.assert_array_equal(a.log_likelihoods([p, q]), lone_a.log_likelihoods([p, q]))
        assert np.array_equal(a.step(p)[0], lone_a.step(p)[0])
        assert np.array_equal(b.step(q)[0], lone_b.step(q)[0])
        assert a._cov is b._cov
    first = weakref.ref(a._cov)
    clear, ambiguous = poses[21].copy(), poses[21].copy()
    ambiguous[:2] *= 0.2
    a.step(clear), b.step(ambiguous)
    assert a._cov is not b._cov
    gc.collect()
    assert first() is None


def test_scoring_rows_at_once_equals_each_row_alone_and_names_a_bad_row():
    """log_likelihoods measures its K rows at once: bit for bit each row's own score (an
    ambiguous row among them), and a non-finite entry refused with its index as step does."""
    poses = noisy_poses(true_angles(8), std=5.0)
    kf = PoseKalmanFilter(FPS)
    for p in poses[:5]:
        kf.step(p)
    rows = poses[5:8].copy()
    rows[1, :2] *= 0.2                                          # ambiguous: inflated R
    together = kf.log_likelihoods(rows)
    alone = [kf.log_likelihoods(row[None])[0] for row in rows]
    np.testing.assert_array_equal(together, alone)
    rows[2, 7] = np.nan
    with pytest.raises(FilterError, match=r"non-finite entries at \[7\]"):
        kf.log_likelihoods(rows)
