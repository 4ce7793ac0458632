"""scripts/evaluate_gait.py's leg-sign chain on a hand-made profile gait with a known answer."""
from __future__ import annotations

import importlib.util
import sys

import numpy as np

from sequences.gait_measures import gait_measures, knee_flexion
from sequences.pose_conversions import canonical_member
from sequences.pose_vector import POSE_DIM, front_back_flip, heading_deg, pose_vector_names
from tracker.tracks.hypotheses import members_over_time
from tests.conftest import ROOT


def _load():
    spec = importlib.util.spec_from_file_location("evaluate_gait",
                                                  ROOT / "scripts" / "evaluate_gait.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["evaluate_gait"] = module
    spec.loader.exec_module(module)
    return module


evaluate_gait = _load()
NAMES = pose_vector_names()
T = 90


def _profile_walk() -> np.ndarray:
    """Pose vectors (T, 55) of a walk in profile: 1 Hz gait at 30 fps (a leg crossing every
    15 frames), the heading swaying across the profile line, a little towards the camera on
    average."""
    t = np.arange(T) + 0.3
    phase = 2 * np.pi * t / 30.0
    v = np.zeros((T, POSE_DIM))
    h = np.radians(87.0 + 8.0 * np.sin(phase + 0.9))
    v[:, 0], v[:, 1] = np.cos(h), np.sin(h)
    v[:, NAMES.index("LeftUpLeg_x")] = -25 * np.sin(phase)
    v[:, NAMES.index("RightUpLeg_x")] = 25 * np.sin(phase)
    v[:, NAMES.index("LeftLeg_z")] = 30 + 25 * np.sin(phase - 1.0)
    v[:, NAMES.index("RightLeg_z")] = 30 + 25 * np.sin(phase - 1.0 + np.pi)
    return v


def _rectified(truth: np.ndarray) -> np.ndarray:
    """Of each pose and its front/back flip, the one with the left thigh's x angle above the
    right's: the members the shipped networks give in profile (docs/left_right.md), a gait
    whose configuration changes at every leg crossing."""
    direction = np.zeros(POSE_DIM)
    direction[NAMES.index("LeftUpLeg_x")], direction[NAMES.index("RightUpLeg_x")] = 1.0, -1.0
    return canonical_member(truth, direction)


def test_the_leg_sign_chain_unfolds_members_that_swap_at_every_leg_crossing():
    truth = _profile_walk()
    members = _rectified(truth)
    assert 0.3 < (np.abs(members - truth).max(axis=1) > 1e-9).mean() < 0.7   # they swap
    heading = np.full(T, heading_deg(truth).mean())                     # a smoothed heading
    chosen = evaluate_gait.gait_sign_chain(1.0)(members, heading)
    np.testing.assert_allclose(chosen, truth, atol=1e-9)
    gait = gait_measures(knee_flexion(chosen), knee_flexion(truth))
    assert gait["alternation"] > 0.99 and gait["range"] > 0.99
    # Always the rectified members (no unfolding) would not alternate.
    assert gait_measures(knee_flexion(members), knee_flexion(truth))["alternation"] < 0.5


def test_the_leg_sign_chain_survives_noise():
    truth = _profile_walk()
    heading = np.full(T, heading_deg(truth).mean())
    rng = np.random.default_rng(0)
    members = _rectified(truth)
    members[:, 2:] += rng.normal(0.0, 3.0, (T, POSE_DIM - 2))
    chosen = evaluate_gait.gait_sign_chain(1.0)(members, heading)
    assert gait_measures(knee_flexion(chosen), knee_flexion(truth))["alternation"] > 0.8


def _rectified_legs_walk():
    """(truth, members, heading) of a walk in profile whose members keep the body's arms and
    heading but take the legs of the body or of its flip, whichever has the left thigh ahead
    (the networks' rectified gait, docs/left_right.md). Thighs and knees (bent about x, which
    the flip keeps) meet at each crossing, so the members' legs are continuous through it; the
    left arm is held 20 deg up, so a member's flip is not."""
    phase = 2 * np.pi * (np.arange(T) + 0.3) / 30.0
    truth = np.zeros((T, POSE_DIM))
    h = np.radians(87.0 + 8.0 * np.sin(phase + 0.9))
    truth[:, 0], truth[:, 1] = np.cos(h), np.sin(h)
    for side, s in (("Left", -1.0), ("Right", 1.0)):
        truth[:, NAMES.index(f"{side}UpLeg_x")] = 25 * s * np.sin(phase)
        truth[:, NAMES.index(f"{side}Leg_x")] = 30 + 25 * s * np.sin(phase)
    truth[:, NAMES.index("LeftArm_z")] = 20.0
    legs = np.array(["Leg" in n or "Foot" in n for n in NAMES])
    members = truth.copy()
    behind = truth[:, NAMES.index("LeftUpLeg_x")] < truth[:, NAMES.index("RightUpLeg_x")]
    members[np.ix_(behind, legs)] = front_back_flip(truth[behind])[:, legs]
    return truth, members, np.degrees(h)


def test_the_leg_sign_chain_unfolds_a_rectified_gait_the_shipped_chain_keeps():
    """The shipped chain (legs' continuity) keeps the rectified members; the leg-sign chain
    alternates the legs as the truth's."""
    truth, members, heading = _rectified_legs_walk()
    knees = knee_flexion(truth)
    assert gait_measures(knee_flexion(members), knees)["alternation"] < 0.3
    shipped = members_over_time(members, heading)
    assert gait_measures(knee_flexion(shipped), knees)["alternation"] < 0.3
    chosen = evaluate_gait.gait_sign_chain(1.0)(members, heading)
    assert gait_measures(knee_flexion(chosen), knees)["alternation"] > 0.9


def test_a_video_of_several_tracks_is_scored_without_its_picks():
    """Where the online picks cannot be matched to the longest track (several tracks), the
    `picked` row is NaN and every other output is still scored."""
    truth = _profile_walk()
    out = {name: truth for name in evaluate_gait.OUTPUTS}
    out["member"], out["pairs"] = truth, np.stack([truth, truth], axis=1)
    out["picked"] = np.full_like(truth, np.nan)
    res = evaluate_gait.figures(out, truth)
    assert all(np.isnan(res["picked"][c]) for c in evaluate_gait.FIGURES)
    assert res["smoothed"]["alternation"] > 0.99
