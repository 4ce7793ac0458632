"""The background model's noise floor (tracker.video.noise_floor) and sharp priming at working size."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from tracker.video.noise_floor import _ratio, choose_var_min, foreground_counts
from tracker.video.silhouettes import BackgroundSubtractor, ExtractionError, SilhouetteExtractor


def textured(width: int, height: int, seed: int = 0, blur: float = 1.0) -> np.ndarray:
    """A static, finely textured scene, BGR uint8 (height, width, 3)."""
    rng = np.random.default_rng(seed)
    return cv2.GaussianBlur(rng.integers(0, 256, (height, width, 3), dtype=np.uint8), (0, 0), blur)


def frames_with_person(bg: np.ndarray, noise_sigma: float, n: int, seed: int = 1) -> list:
    """n frames of bg with a solid block moving across and Gaussian noise of noise_sigma
    grey levels (a stand-in for sensor and compression noise)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        frame = bg.astype(np.float32)
        x = 20 + 8 * i
        frame[40:110, x:x + 20] = (40, 190, 70)
        frame += rng.normal(0.0, noise_sigma, frame.shape)
        out.append(np.clip(frame, 0, 255).astype(np.uint8))
    return out


def speck_ratio(model, frames) -> float:
    """Specks per solid foreground px (0.0: no foreground, inf: only specks)."""
    return _ratio(*foreground_counts(model, frames))


def primed_on(bg: np.ndarray) -> BackgroundSubtractor:
    """A subtractor primed with bg (its reference for primed_model)."""
    sub = BackgroundSubtractor()
    sub.prime(bg)
    return sub


def test_speck_ratio_counts_isolated_pixels_against_solid_foreground():
    bg = textured(160, 120)
    sub = primed_on(bg)
    clean = frames_with_person(bg, 0.0, 4)
    assert speck_ratio(sub.primed_model(4.0), clean) < 0.02
    noisy = frames_with_person(bg, 6.0, 4)
    assert speck_ratio(sub.primed_model(4.0), noisy) > 0.2
    assert speck_ratio(sub.primed_model(4.0), [bg, bg]) == 0.0


def test_noisier_clips_get_a_higher_floor():
    bg = textured(160, 120)
    sub = primed_on(bg)
    quiet = choose_var_min(sub.primed_model, frames_with_person(bg, 1.0, 6))
    loud = choose_var_min(sub.primed_model, frames_with_person(bg, 6.0, 6))
    assert quiet == 4.0
    assert loud > 4.0
    # the chosen floor leaves the noisy clip's foreground solid
    assert speck_ratio(sub.primed_model(loud), frames_with_person(bg, 6.0, 6)) <= 0.15


def test_extractor_adapts_its_floor_to_the_clip_unless_told():
    bg = textured(160, 120)
    frames = frames_with_person(bg, 6.0, 12)
    adapted = SilhouetteExtractor()
    adapted.prime(frames)
    assert adapted.subtractor.var_min > 4.0
    fixed = SilhouetteExtractor(var_min=4.0)
    fixed.prime(frames)
    assert fixed.subtractor.var_min == 4.0
    # and the floor pays: the adapted extractor's person is not inflated by the noise halo
    people = adapted(frames[5])
    assert len(people) == 1 and abs(people[0].area - 70 * 20) < 0.15 * 70 * 20


@pytest.mark.parametrize("var_min", [0.0, -1.0, 80.0, float("nan")])
def test_absurd_floors_are_refused(var_min):
    with pytest.raises(ExtractionError, match="var_min"):
        BackgroundSubtractor(var_min=var_min)


def test_priming_at_working_size_keeps_the_background_sharp():
    """A 640 px video works at 320 px: the median of shrunk frames given as is, not scaled up
    and back down, so texture does not read as foreground."""
    full = textured(640, 480, blur=0.7)
    small = cv2.resize(full, (320, 240), interpolation=cv2.INTER_AREA)
    round_trip = cv2.resize(cv2.resize(small, (640, 480), interpolation=cv2.INTER_CUBIC),
                            (320, 240), interpolation=cv2.INTER_AREA)
    sharp, blurred = BackgroundSubtractor(), BackgroundSubtractor()
    sharp.prime(small, frame_size=(640, 480))
    blurred.prime(cv2.resize(small, (640, 480), interpolation=cv2.INTER_CUBIC))
    assert np.array_equal(sharp.reference, small)
    assert not np.array_equal(blurred.reference, small)
    assert np.abs(blurred.reference.astype(int) - round_trip).max() <= 1
    assert sharp.ready
    spill_sharp = np.count_nonzero(sharp.subtract(full)[1] > 200)
    spill_blurred = np.count_nonzero(blurred.subtract(full)[1] > 200)
    assert spill_sharp < 0.01 * small.shape[0] * small.shape[1] < spill_blurred


def test_priming_at_working_size_checks_the_size():
    sub = BackgroundSubtractor()
    with pytest.raises(ExtractionError, match="must be .* at working size"):
        sub.prime(np.zeros((100, 100, 3), np.uint8), frame_size=(640, 480))
    sub.prime(np.zeros((240, 320, 3), np.uint8), frame_size=(640, 480))
    sub.subtract(np.zeros((480, 640, 3), np.uint8))           # the frames' size is accepted
    with pytest.raises(ExtractionError, match="frame size changed"):
        sub.subtract(np.zeros((240, 320, 3), np.uint8))


def test_retune_needs_a_primed_background():
    with pytest.raises(ExtractionError, match="prime"):
        BackgroundSubtractor().retune(9.0)
    with pytest.raises(ExtractionError, match="prime"):
        BackgroundSubtractor().primed_model(9.0)


@pytest.mark.parametrize("sigma", [6.0, 12.0])
def test_an_empty_scene_of_pure_noise_gets_a_floor_that_quiets_it(sigma):
    """No body, only noise. At sigma 6 grey levels the low floors give nothing but specks; at
    12 the lowest makes nearly the whole frame solid foreground, with few specks left to count
    (the growth bound catches it)."""
    bg = np.full((120, 160, 3), 128, np.uint8)
    rng = np.random.default_rng(2)
    frames = [np.clip(bg + rng.normal(0, sigma, bg.shape), 0, 255).astype(np.uint8)
              for _ in range(4)]
    sub = primed_on(bg)
    chosen = choose_var_min(sub.primed_model, frames)
    assert chosen > 9.0
    model = sub.primed_model(chosen)
    foreground = np.mean([(model.apply(f, learningRate=0.0) > 200).mean() for f in frames])
    lowest = sub.primed_model(4.0)
    assert foreground < 0.5 * np.mean([(lowest.apply(f, learningRate=0.0) > 200).mean()
                                       for f in frames])


def _eager_choice(make_primed_model, frames) -> float:
    """choose_var_min's rule with every rung of the ladder measured first."""
    from tracker.video.noise_floor import (MAX_EXCESS_SPECKS, MAX_FOREGROUND_GROWTH,
                                           VAR_MIN_LADDER)
    counts = [foreground_counts(make_primed_model(v), frames) for v in VAR_MIN_LADDER]
    top_ratio, top_total = _ratio(*counts[-1]), sum(counts[-1])
    if not np.isfinite(top_ratio):
        return VAR_MIN_LADDER[-1]
    for var_min, (specks, solid) in zip(VAR_MIN_LADDER, counts):
        if (_ratio(specks, solid) - top_ratio <= MAX_EXCESS_SPECKS
                and specks + solid <= MAX_FOREGROUND_GROWTH * max(top_total, 1)):
            return var_min
    return VAR_MIN_LADDER[-1]


@pytest.mark.parametrize("threads", [1, 2])
def test_floor_choice_builds_only_the_rungs_it_needs_and_chooses_as_the_whole_ladder(threads):
    """One thread: the top rung, then rungs from the bottom up to the chosen one; two threads
    measure two rungs at a time: at most one rung more. Either way the whole ladder's choice."""
    bg = textured(160, 120)
    sub = primed_on(bg)
    for sigma in (0.0, 3.0, 6.0, 12.0):
        frames = frames_with_person(bg, sigma, 6)
        built: list[float] = []

        def counting(var_min: float):
            built.append(var_min)
            return sub.primed_model(var_min)
        chosen = choose_var_min(counting, frames, threads=threads)
        assert chosen == _eager_choice(sub.primed_model, frames)
        needed = 1 + sum(v <= chosen for v in (4.0, 9.0, 16.0, 25.0))
        if threads == 1:
            lower = [v for v in built[1:] if v < chosen]
            assert built[0] == 36.0 and built[1:] == lower + ([chosen] if chosen < 36.0 else [])
        assert needed <= len(built) <= needed + threads - 1


def test_foreground_counts_are_the_mask_sums():
    bg = textured(160, 120)
    sub = primed_on(bg)
    frames = frames_with_person(bg, 6.0, 4)
    specks = solid = 0
    model = sub.primed_model(4.0)
    for frame in frames:
        foreground = (model.apply(frame, learningRate=0.0) > 200).astype(np.uint8)
        kept = int(cv2.morphologyEx(foreground, cv2.MORPH_OPEN,
                                    cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))).sum())
        specks, solid = specks + int(foreground.sum()) - kept, solid + kept
    assert foreground_counts(sub.primed_model(4.0), frames) == (specks, solid)


class _CountedModel:
    """A MOG2 counting its apply() calls."""

    def __init__(self, model):
        self.model, self.applied = model, 0

    def apply(self, image, learningRate):
        self.applied += 1
        return self.model.apply(image, learningRate=learningRate)


class _CountingSubtractor(BackgroundSubtractor):
    def new_model(self, var_min):
        return _CountedModel(super().new_model(var_min))


def test_prime_teaches_the_model_on_its_first_use_and_not_the_model_retune_replaces():
    bg = textured(160, 120)
    frames = frames_with_person(bg, 3.0, 5)
    sub = _CountingSubtractor()
    first = sub._model
    sub.prime(bg)
    assert first.applied == 0 and sub.ready
    eager = BackgroundSubtractor().new_model(4.0)      # prime's lessons given at once
    for _ in range(15):
        eager.apply(bg, learningRate=-1.0)
    for frame in frames:
        _, raw = sub.subtract(frame)
        np.testing.assert_array_equal(raw, eager.apply(frame, learningRate=1 / 500))
    assert first.applied == 15 + len(frames)
    retuned = _CountingSubtractor()
    replaced = retuned._model
    retuned.prime(bg)
    retuned.retune(9.0)
    assert replaced.applied == 0 and retuned._model.applied == 15
