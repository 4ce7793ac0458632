"""Video to tracked 3-D poses: silhouettes, filtering, outputs and the ``track`` command. The
public names (_PUBLIC) load on first use: a submodule run alone does not pay for their imports."""
import signal
from importlib import import_module

#: What stops a run as Ctrl-C does (the command's handlers, the loop's held outputs, the worker).
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

_PUBLIC = {"PoseTracker": "pipeline", "TrackedPose": "pipeline", "TrackerSettings": "pipeline",
           "track_video": "run", "TrackRun": "run", "Sink": "outputs", "PoseRecorder": "outputs"}
__all__ = sorted(_PUBLIC)


def __getattr__(name: str):
    if name in _PUBLIC:
        return getattr(import_module(f".{_PUBLIC[name]}", __name__), name)
    raise AttributeError(f"module 'tracker' has no attribute {name!r}")
