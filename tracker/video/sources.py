"""Where silhouettes come from (``track --silhouettes``): background subtraction, the person
segmenter (tracker.video.segmenter, an optional extra, imported only when used), or auto."""
from __future__ import annotations

import importlib.util
import warnings

import numpy as np

from regressor.errors import SilhouettePoseError
from tracker.video.camera_motion import camera_moves
from tracker.video.decode import colourless
from tracker.video.silhouettes import BackgroundSubtractor, PersonMask, SilhouetteExtractor

#: How to get the segmenter, in the words every message uses.
INSTALL_HINT = "pip install 'silhouette-pose[segment]'"
#: ``track --silhouettes`` choices.
SOURCES = ("background", "segment", "auto")


class SegmenterMissingError(SilhouettePoseError, ImportError):
    """The person segmenter was asked for but its extra is not installed."""


def segmenter_available() -> bool:
    """Whether MediaPipe (the ``segment`` extra) can be imported here."""
    return importlib.util.find_spec("mediapipe") is not None


def require_segmenter(option: str = "--silhouettes segment") -> None:
    """SegmenterMissingError naming ``option`` and how to install it, unless available."""
    if not segmenter_available():
        raise SegmenterMissingError(f"{option} needs the person segmenter, which is not "
                                    f"installed: {INSTALL_HINT}")


class AutoExtractor:
    """``track --silhouettes auto``: background subtraction (``make_background(**options)``
    makes a :class:`SilhouetteExtractor`) until the camera moves (by the clip's samples, and
    with a segmenter each frame), then ``segmenter`` (a PersonSegmenter, no moving blobs; None
    without the extra: one warning). :attr:`source`: "background" or "segment"; :attr:`reason`."""

    def __init__(self, make_background, segmenter):
        self.make_background = make_background
        self.background: SilhouetteExtractor = make_background()
        self.segmenter = segmenter
        self.meter = None                       # the per-frame meter serves the segmenter only
        if segmenter is not None:
            from tracker.video.segmenter import CameraMotionMeter
            self.meter = CameraMotionMeter()
        self.source, self.reason = "background", None

    @property
    def subtractor(self) -> BackgroundSubtractor:
        """The background path's subtractor (its working size decides the samples' size)."""
        return self.background.subtractor

    def prime(self, background, frame_size: tuple[int, int] | None = None) -> None:
        """Prime both paths (:meth:`SilhouetteExtractor.prime`); judge frames of the clip."""
        image = background if isinstance(background, np.ndarray) and background.ndim == 3 \
            else None
        if colourless(image if image is not None else np.asarray(background)[0]):
            self.background = self.make_background(detect_shadows=False)
        self.background.prime(background, frame_size)
        if self.segmenter is not None:
            self.segmenter.prime(background, frame_size)
        if image is None and camera_moves(list(background)):
            self._choose("the camera moves")

    def learn_zone(self, frames, median: np.ndarray | None = None, threads: int = 1) -> None:
        """As :meth:`SilhouetteExtractor.learn_zone`, and judge the frames (:meth:`prime`)."""
        self.background.learn_zone(frames, median, threads)
        if camera_moves(list(frames)):
            self._choose("the camera moves")

    def _choose(self, reason: str) -> None:
        """Turn to the segmenter (without moving blobs) for ``reason``, or warn once."""
        if self.reason is not None:             # set before source turns to "segment"
            return
        self.reason = reason
        if self.segmenter is None:
            warnings.warn(f"{reason}: background subtraction cannot follow it; a person "
                          f"segmenter can ({INSTALL_HINT}; then track --silhouettes auto)")
            return
        self.source = "segment"
        self.segmenter.use_motion = False

    def __call__(self, frame: np.ndarray) -> list[PersonMask]:
        """The people in ``frame`` (BGR uint8 (H, W, 3)) from the path in use."""
        if self.source == "background" and self.segmenter is not None and self.meter(frame):
            self._choose("the camera moves")
        if self.source == "segment":
            return self.segmenter(frame)
        return self.background(frame)


def silhouette_extractor(source: str, settings):
    """The extractor of ``track --silhouettes SOURCE`` (tracker.pipeline.TrackerSettings
    ``settings``): None (PoseTracker's default), a PersonSegmenter or an AutoExtractor."""
    from tracker.pipeline import default_extractor
    if source not in SOURCES:
        raise ValueError(f"silhouette source {source!r} is not one of {', '.join(SOURCES)}")
    if source == "background":
        return None
    if source == "segment":
        require_segmenter()
    segmenter = None
    if segmenter_available():
        from tracker.video.segmenter import PersonSegmenter
        segmenter = PersonSegmenter(min_area_fraction=settings.min_area_fraction)
    if source == "segment":
        return segmenter
    return AutoExtractor(lambda **options: default_extractor(settings, **options), segmenter)
