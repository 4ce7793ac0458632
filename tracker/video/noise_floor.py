"""The background model's noise floor, chosen per clip from how speckled its foreground is: a
codec smears the background around a moving person beyond MOG2's default floor, and the speckled
halo, cleaned, closes the gaps between the limbs. Specks (pixels a 3 px opening removes) per
solid pixel measure that noise without ground truth (figures: docs/tuning.md)."""
from __future__ import annotations

import contextlib
from collections import deque
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Sequence

import cv2
import numpy as np

#: MOG2 variance floors tried, grey levels squared (MOG2's own default is 4).
VAR_MIN_LADDER: tuple[float, ...] = (4.0, 9.0, 16.0, 25.0, 36.0)
#: Specks per pixel of opened foreground allowed above what the ladder's top rung leaves.
MAX_EXCESS_SPECKS = 0.05
#: Foreground allowed, as a multiple of what the ladder's top rung leaves.
MAX_FOREGROUND_GROWTH = 2.0

#: MOG2 marks foreground 255, shadow 127, background 0: above this is foreground proper.
FOREGROUND_LEVEL = 200
_OPEN_KERNEL = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))


def foreground_counts(model, frames: Sequence[np.ndarray]) -> tuple[int, int]:
    """(specks, solid) foreground px summed over ``frames`` (BGR uint8 (h, w, 3)) by a primed
    MOG2 ``model`` (learning rate 0); specks: removed by a 3 px elliptical opening."""
    specks = solid = 0
    for frame in frames:
        _, foreground = cv2.threshold(model.apply(frame, learningRate=0.0), FOREGROUND_LEVEL, 1,
                                      cv2.THRESH_BINARY)
        kept = cv2.countNonZero(cv2.morphologyEx(foreground, cv2.MORPH_OPEN, _OPEN_KERNEL))
        specks += cv2.countNonZero(foreground) - kept
        solid += kept
    return specks, solid


def _ratio(specks: int, solid: int) -> float:
    if solid == 0:
        return 0.0 if specks == 0 else float("inf")
    return specks / solid


def choose_var_min(make_primed_model: Callable[[float], object], frames: Sequence[np.ndarray],
                   threads: int = 1) -> float:
    """The lowest MOG2 variance floor (grey levels squared) in VAR_MIN_LADDER whose foreground on
    ``frames`` (BGR uint8 at working size, over the clip) has at most MAX_EXCESS_SPECKS more
    specks per solid px than the top rung's (those are not noise) and at most
    MAX_FOREGROUND_GROWTH times its foreground (strong noise can make a low floor's foreground one
    sheet); make_primed_model: BackgroundSubtractor.primed_model. All specks: the top rung.
    threads: rungs measured at once (the same choice; MOG2 lets other threads run)."""
    ladder = VAR_MIN_LADDER

    def counts(var_min: float) -> tuple[int, int]:
        return foreground_counts(make_primed_model(float(var_min)), frames)
    with _in_order(counts, [ladder[-1], *ladder[:-1]], threads) as measured:
        top = next(measured)
        top_ratio, top_total = _ratio(*top), sum(top)
        if not np.isfinite(top_ratio):       # only specks even at the top: all noise, no body
            return float(ladder[-1])
        for var_min in ladder[:-1]:          # the lowest that passes; the top one always does
            specks, solid = next(measured)
            if (_ratio(specks, solid) - top_ratio <= MAX_EXCESS_SPECKS
                    and specks + solid <= MAX_FOREGROUND_GROWTH * max(top_total, 1)):
                return float(var_min)
    return float(ladder[-1])


@contextlib.contextmanager
def _in_order(measure: Callable, rungs: list, threads: int) -> Iterator[Iterator]:
    """An iterator of measure(rung) for ``rungs`` in order, up to ``threads`` computed ahead
    in threads; on leaving, those not started are dropped and running ones awaited."""
    if threads <= 1:
        yield (measure(rung) for rung in rungs)
        return
    pool = ThreadPoolExecutor(threads, thread_name_prefix="noise-floor")
    try:
        ahead = deque(pool.submit(measure, rung) for rung in rungs[:threads])
        later = iter(rungs[threads:])

        def results() -> Iterator:
            while ahead:
                result = ahead.popleft().result()
                rung = next(later, None)
                if rung is not None:
                    ahead.append(pool.submit(measure, rung))
                yield result
        yield results()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
