"""Stacked past-frame descriptors: order, padding at sequence starts, no leakage, streaming."""
import numpy as np
import pytest

from regressor.stacking import FrameStacker, StackingInputError, stack_frames, stack_step


def _frames(n, d=2):
    return np.arange(n * d, dtype=float).reshape(n, d)


def test_k1_is_the_identity():
    X = _frames(5)
    np.testing.assert_array_equal(stack_frames(X, 1), X)


def test_rows_are_current_then_past_frames_with_first_frame_padding():
    X = _frames(4)
    S = stack_frames(X, 3)
    np.testing.assert_array_equal(S[3], np.concatenate([X[3], X[2], X[1]]))
    np.testing.assert_array_equal(S[0], np.concatenate([X[0], X[0], X[0]]))
    np.testing.assert_array_equal(S[1], np.concatenate([X[1], X[0], X[0]]))


def test_no_leakage_across_sequences_ids_and_starts_agree():
    X = _frames(6)
    by_ids = stack_frames(X, 3, sequence_ids=[7, 7, 7, 2, 2, 2])
    by_starts = stack_frames(X, 3, sequence_starts=[0, 3])
    np.testing.assert_array_equal(by_ids, by_starts)
    np.testing.assert_array_equal(by_ids[3], np.concatenate([X[3], X[3], X[3]]))
    np.testing.assert_array_equal(by_ids[4], np.concatenate([X[4], X[3], X[3]]))


def test_streaming_stacker_matches_batch_stacking():
    X = _frames(5, 3)
    stacker = FrameStacker(3)
    streamed = np.array([stacker.push(x) for x in X])
    np.testing.assert_array_equal(streamed, stack_frames(X, 3))
    np.testing.assert_array_equal(FrameStacker(3).push(X[4]), np.tile(X[4], 3))


def test_bad_arguments_are_refused():
    with pytest.raises(StackingInputError, match="k="):
        stack_frames(_frames(3), 0)
    with pytest.raises(StackingInputError, match="sequence_ids"):
        stack_frames(_frames(3), 2, sequence_ids=[0, 1])
    with pytest.raises(StackingInputError, match="sequence_starts"):
        stack_frames(_frames(3), 2, sequence_starts=[1])
    stacker = FrameStacker(2)
    stacker.push(np.zeros(3))
    with pytest.raises(StackingInputError, match="has 4 values; this track.s have 3"):
        stacker.push(np.zeros(4))


def test_a_step_stacks_every_step_th_frame_in_batch_and_streaming():
    """A 60 fps video stacks frames t, t-2, t-4 so that they span the time a 30 fps model's
    t, t-1, t-2 did; frames before the sequence start are its first frame, as with step 1."""
    X = _frames(9, 3)
    S = stack_frames(X, 3, step=2, sequence_starts=[0, 6])
    np.testing.assert_array_equal(S[5], np.concatenate([X[5], X[3], X[1]]))
    np.testing.assert_array_equal(S[3], np.concatenate([X[3], X[1], X[0]]))
    np.testing.assert_array_equal(S[7], np.concatenate([X[7], X[6], X[6]]))   # no leakage
    stacker = FrameStacker(3, step=2)
    streamed = np.array([stacker.push(x) for x in X[:6]])
    np.testing.assert_array_equal(streamed, S[:6])
    with pytest.raises(StackingInputError, match="step=0"):
        stack_frames(X, 3, step=0)
    with pytest.raises(StackingInputError, match="step=1.5"):
        FrameStacker(3, step=1.5)


@pytest.mark.parametrize("video_fps, step", [(30, 1), (29.97, 1), (25, 1), (24, 1), (15, 1),
                                             (50, 2), (59.94, 2), (60, 2), (90, 3), (120, 4),
                                             (240, 8)])
def test_the_step_keeps_stacked_frames_as_far_apart_in_time_as_in_training(video_fps, step):
    assert stack_step(video_fps, 30.0) == step


@pytest.mark.parametrize("video_fps, model_fps", [(0, 30), (-30, 30), (float("nan"), 30),
                                                  (30, 0), (float("inf"), 30)])
def test_absurd_frame_rates_are_refused(video_fps, model_fps):
    with pytest.raises(StackingInputError, match="frame rates must be positive"):
        stack_step(video_fps, model_fps)
