"""Video to tracked 3-D poses: silhouettes, filtering, outputs and the ``track`` command.

Public API: :func:`track_video` (the one tracking loop), :class:`PoseTracker` (per-frame
tracking, with injectable extractor, associator and filter factory), :class:`TrackerSettings`,
:class:`TrackedPose` (what sinks receive), :class:`Sink` (the output protocol) and
:class:`PoseRecorder` (a sink keeping poses in memory). ``lab`` (training,
evaluation, reports) is not imported by anything online.

Names are loaded on first use, so ``python -m tracker.outputs.meshcat_server`` and other
submodules do not pay for the filter's imports.
"""
from importlib import import_module

_PUBLIC = {"PoseTracker": "pipeline", "TrackedPose": "pipeline", "TrackerSettings": "pipeline",
           "track_video": "run", "TrackRun": "run", "Sink": "outputs", "PoseRecorder": "outputs"}
__all__ = sorted(_PUBLIC)


def __getattr__(name: str):
    if name in _PUBLIC:
        return getattr(import_module(f".{_PUBLIC[name]}", __name__), name)
    raise AttributeError(f"module 'tracker' has no attribute {name!r}")
