"""JSON summary of a tracking run, for scripts: frames, speed, and per track its frames,
centroids, headings, ambiguity, novelty and poses (layout: docs/code_notes/outputs.md), written
to a locked ``PATH.partial`` renamed onto PATH once complete (files.OutputFile)."""
from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from tracker.outputs.files import ClosedOnExit, OutputFile
from tracker.outputs.geometry import (SinkInputError, check_centroid, check_joints, check_pose,
                                      checked_probability, checked_time, heading_deg,
                                      is_unfamiliar, known_novelty)

if TYPE_CHECKING:
    from tracker.pipeline import TrackedPose

FORMAT = "silhouette-pose tracking summary"
VERSION = 1
_DECIMALS = 6
POSES = ("filtered", "smoothed", "fixed-lag smoothed")


class JsonSummarySink(ClosedOnExit):
    """Collect per-track results and write the summary to ``path`` on close. poses: one of POSES
    (``pose_kind``). clock: seconds counter for the speed achieved (tests fix it)."""

    def __init__(self, path: str | Path, video_fps: float, poses: str = "filtered",
                 clock: Callable[[], float] = time.perf_counter):
        if not (math.isfinite(video_fps) and video_fps > 0):
            raise SinkInputError(f"video_fps must be a positive number, got {video_fps}")
        if poses not in POSES:
            raise SinkInputError(f"poses must be one of {POSES}, got {poses!r}")
        self.pose_kind = poses
        self.path = Path(path)
        self.video_fps = float(video_fps)
        self._clock = clock
        self._start: float | None = None
        self._frames: set[int] = set()
        self._tracks: dict[int, dict[str, list]] = {}
        self._unfamiliar: dict[int, int] = {}     # per track: frames is_unfamiliar says so
        self.closed = False
        self._file = OutputFile(self.path)     # PATH.partial, locked until close()

    def end_frame(self, frame_index: int) -> None:
        """Count a processed frame (called for frames without people too; write() calls it)."""
        if self._start is None:
            self._start = self._clock()
        self._frames.add(int(frame_index))

    def write(self, pose: TrackedPose) -> None:
        """Record one track in one frame (centroid_px required); SinkInputError if bad or closed."""
        if self.closed:
            raise SinkInputError(f"JSON summary {self.path.name} is closed")
        frame_index, track_id = int(pose.frame_index), int(pose.track_id)
        raw = check_pose("raw55", pose.raw)
        filtered = check_pose("filtered55", pose.filtered)
        check_joints(pose.joints_m)
        if pose.centroid_px is None:
            raise SinkInputError("the JSON summary needs centroid_px (x, y) in pixels")
        centroid = check_centroid(pose.centroid_px)
        novelty = known_novelty(getattr(pose, "novelty", None))
        time_s = checked_time(pose.time_s)
        runner_up = None
        if getattr(pose, "runner_up", None) is not None:
            alt = check_pose("runner_up55", pose.runner_up)
            probability = checked_probability("runner_up_probability", pose.runner_up_probability)
            runner_up = {"frame": frame_index, "probability": round(probability, _DECIMALS),
                         "heading_deg": heading_deg(alt),
                         "pose": np.round(alt, _DECIMALS).tolist()}
        row = {"frames": frame_index, "time_s": round(time_s, _DECIMALS),
               "centroid_px": np.round(centroid, 3).tolist(), "heading_deg": heading_deg(filtered),
               "heading_norm": round(math.hypot(raw[0], raw[1]), _DECIMALS),
               "ambiguous": bool(pose.ambiguous),
               "novelty": None if novelty is None else round(novelty, 4),
               "pose": np.round(filtered, _DECIMALS).tolist()}
        # Everything is checked: from here on the row is written whole.
        self.end_frame(frame_index)
        track = self._tracks.setdefault(track_id, {key: [] for key in [*row, "runner_up"]})
        for key, value in row.items():
            track[key].append(value)
        if runner_up is not None:
            track["runner_up"].append(runner_up)
        self._unfamiliar[track_id] = self._unfamiliar.get(track_id, 0) + is_unfamiliar(novelty)

    def summary(self) -> dict:
        """The summary document as it stands (see the module docstring)."""
        wall = 0.0 if self._start is None else self._clock() - self._start
        frames = len(self._frames)
        tracks = []
        for track_id in sorted(self._tracks):
            track = self._tracks[track_id]
            heading = np.radians(track["heading_deg"])
            mean = math.degrees(math.atan2(np.sin(heading).mean(), np.cos(heading).mean()))
            tracks.append({"id": track_id, "first_frame": track["frames"][0],
                           "last_frame": track["frames"][-1], "n_frames": len(track["frames"]),
                           **track, "ambiguous_frames": int(sum(track["ambiguous"])),
                           "unfamiliar_frames": self._unfamiliar.get(track_id, 0),
                           "heading_mean_deg": round(mean, _DECIMALS)})
        return {"format": FORMAT, "version": VERSION, "frames": frames,
                "fps": round(frames / wall, 3) if wall > 0 else 0.0,
                "video_fps": self.video_fps, "wall_time_s": round(wall, 3),
                "poses": self.pose_kind, "tracks": tracks}

    def close(self) -> None:
        """Write the summary and put it in place, idempotent; on failure the old one stays."""
        if self.closed:
            return
        self.closed = True
        try:
            text = json.dumps(self.summary(), allow_nan=False, separators=(",", ":"))
            self._file.write(text.encode("utf-8"))
            self._file.commit()
        except BaseException:
            self._file.discard()
            raise

    def abandon(self) -> None:
        """Stop without writing (a run that tracked nobody), the path keeping what it held."""
        if not self.closed:
            self.closed = True
            self._file.discard()
