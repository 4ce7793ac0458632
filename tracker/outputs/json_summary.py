"""JSON summary of a tracking run, for scripts: frames, speed, and per track its frames,
centroids, headings, ambiguity flags, novelty (how unlike the training silhouettes each frame
is) and poses (filtered, fixed-lag smoothed or smoothed: the file's "poses" says which).

Layout (format version 1)::

    {"format": "silhouette-pose tracking summary", "version": 1,
     "frames": int,            # frames processed (with or without people)
     "fps": float,             # frames processed per second of wall time from the first frame
                              # on (start-up and background sampling not counted, unlike the
                              # speed track's summary line prints)
     "video_fps": float,        # the frame rate the video's container announces (frames
                              # of a variable frame rate are not 1/video_fps apart: time_s)
     "wall_time_s": float,
     "poses": "filtered" or "smoothed",   # what the tracks' "pose" and "heading_deg" hold:
                                          # frame by frame, or each whole track RTS-smoothed
                                          # ("fixed-lag smoothed" with track --no-smooth --lag:
                                          # tracker.tracks.fixed_lag)
                                          # (track's default for this file; --no-smooth)
     "tracks": [{"id": int, "first_frame": int, "last_frame": int, "n_frames": int,
                 "frames": [int],
                 "time_s": [float],        # each frame's own time in the video, seconds
                                           # (the container's: a variable frame rate's real
                                           # times; tracker.video.decode)
                 "centroid_px": [[x, y]],
                 "heading_deg": [float],   # the poses' heading, degrees in (-180, 180]
                 "heading_norm": [float],  # norm of the RAW (cos, sin): the ambiguity measure
                                           # (the filtered one is 1 by construction)
                 "ambiguous": [bool], "ambiguous_frames": int,
                 "novelty": [float or null],  # how unlike the training silhouettes each
                                              # frame's is (PoseEstimates.novelty; null: unknown)
                 "unfamiliar_frames": int,    # frames with novelty above
                                              # regressor.pose_model.UNFAMILIAR_NOVELTY (1)
                 "heading_mean_deg": float,  # circular mean of heading_deg
                 "pose": [[55 values]],      # as "poses" says; in the order and units of
                                             # sequences.pose_vector.pose_vector_names()
                 "runner_up": [{"frame": int, "probability": float, "heading_deg": float,
                                "pose": [55 values]}]}]}   # the next most probable front/back
                                # hypothesis (filtered, frame by frame, whatever "poses"
                                # says; likewise "ambiguous"), on the frames where it was close

The file is replaced atomically (written to ``PATH.partial``, locked from the sink's creation
so that a second run on the same output fails at once, flushed to disk, then renamed), so a
reader never sees half a summary and an existing summary is replaced only by a complete one.
"""
from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from tracker.outputs.files import OutputFile, write_beside
from tracker.outputs.geometry import (SinkInputError, check_joints, check_pose,
                                    checked_probability, checked_time, is_unfamiliar,
                                    known_novelty)

if TYPE_CHECKING:
    from tracker.pipeline import TrackedPose

FORMAT = "silhouette-pose tracking summary"
VERSION = 1
_DECIMALS = 6
POSES = ("filtered", "smoothed", "fixed-lag smoothed")


def write_json_atomically(path: str | Path, document: dict) -> None:
    """Write ``document`` as JSON to ``path`` beside it and rename when complete.

    Raises ValueError (from json) for NaN or infinite values rather than writing invalid JSON.
    """
    text = json.dumps(document, allow_nan=False, separators=(",", ":"))
    write_beside(path, lambda partial: partial.write_text(text, encoding="utf-8"))


class JsonSummarySink:
    """Collect per-track results and write the summary on close (see the module docstring).

    path: output JSON file. video_fps: the video's frame rate. poses: "filtered", "smoothed"
    or "fixed-lag smoothed", what the poses written to it are (recorded in the summary).
    clock: seconds counter used for the speed achieved (default time.perf_counter; a
    parameter so tests can fix it).
    """

    def __init__(self, path: str | Path, video_fps: float, poses: str = "filtered",
                 clock: Callable[[], float] = time.perf_counter):
        if not (math.isfinite(video_fps) and video_fps > 0):
            raise SinkInputError(f"video_fps must be a positive number, got {video_fps}")
        if poses not in POSES:
            raise SinkInputError(f"poses must be one of {POSES}, got {poses!r}")
        self.pose_kind = poses      # tracker.run.track_video may say "filtered" after Ctrl-C
        self.path = Path(path)
        self.video_fps = float(video_fps)
        self._clock = clock
        self._start: float | None = None
        self._frames: set[int] = set()
        self._tracks: dict[int, dict[str, list]] = {}
        self._unfamiliar: dict[int, int] = {}     # per track: frames is_unfamiliar says so
        self._closed = False
        self._file = OutputFile(self.path)     # PATH.partial, locked until close()

    @property
    def closed(self) -> bool:
        """True after close()."""
        return self._closed

    def end_frame(self, frame_index: int) -> None:
        """Count a processed frame (called for frames without people too; write() calls it)."""
        if self._start is None:
            self._start = self._clock()
        self._frames.add(int(frame_index))

    def write(self, pose: TrackedPose) -> None:
        """Record one track in one frame. pose.centroid_px (x, y) pixels is required here.
        Raises SinkInputError on bad input, a missing centroid, or when closed."""
        if self._closed:
            raise SinkInputError(f"JSON summary {self.path.name} is closed")
        frame_index, time_s, track_id = pose.frame_index, pose.time_s, pose.track_id
        ambiguous, centroid_px = pose.ambiguous, pose.centroid_px
        raw = check_pose("raw55", pose.raw)
        filtered = check_pose("filtered55", pose.filtered)
        check_joints(pose.joints_m)
        if centroid_px is None:
            raise SinkInputError("the JSON summary needs centroid_px (x, y) in pixels")
        centroid = np.asarray(centroid_px, dtype=np.float64)
        if centroid.shape != (2,) or not np.all(np.isfinite(centroid)):
            raise SinkInputError(f"centroid_px must be two finite numbers, got {centroid_px!r}")
        novelty = known_novelty(getattr(pose, "novelty", None))
        time_s = checked_time(time_s)
        runner_up = None
        if getattr(pose, "runner_up", None) is not None:
            alt = check_pose("runner_up55", pose.runner_up)
            probability = checked_probability("runner_up_probability",
                                              pose.runner_up_probability)
            runner_up = {
                "frame": int(frame_index),
                "probability": round(probability, _DECIMALS),
                "heading_deg": round(math.degrees(math.atan2(alt[1], alt[0])), _DECIMALS),
                "pose": np.round(alt, _DECIMALS).tolist()}
        # Everything is checked: from here on the row is written whole.
        self.end_frame(frame_index)
        track = self._tracks.setdefault(int(track_id), {
            "frames": [], "time_s": [], "centroid_px": [], "heading_deg": [],
            "heading_norm": [], "ambiguous": [], "novelty": [], "pose": [], "runner_up": []})
        track["frames"].append(int(frame_index))
        track["time_s"].append(round(float(time_s), _DECIMALS))
        track["centroid_px"].append(np.round(centroid, 3).tolist())
        track["heading_deg"].append(
            round(math.degrees(math.atan2(filtered[1], filtered[0])), _DECIMALS))
        track["heading_norm"].append(round(math.hypot(raw[0], raw[1]), _DECIMALS))
        track["ambiguous"].append(bool(ambiguous))
        track["novelty"].append(None if novelty is None else round(novelty, 4))
        self._unfamiliar[int(track_id)] = (self._unfamiliar.get(int(track_id), 0)
                                           + is_unfamiliar(novelty))
        track["pose"].append(np.round(filtered, _DECIMALS).tolist())
        if runner_up is not None:
            track["runner_up"].append(runner_up)

    def summary(self) -> dict:
        """The summary document as it stands (see the module docstring)."""
        wall = 0.0 if self._start is None else self._clock() - self._start
        frames = len(self._frames)
        tracks = []
        for track_id in sorted(self._tracks):
            track = self._tracks[track_id]
            heading = np.radians(track["heading_deg"])
            mean = math.degrees(math.atan2(np.sin(heading).mean(), np.cos(heading).mean()))
            tracks.append({
                "id": track_id, "first_frame": track["frames"][0],
                "last_frame": track["frames"][-1], "n_frames": len(track["frames"]),
                **track,
                "ambiguous_frames": int(sum(track["ambiguous"])),
                "unfamiliar_frames": self._unfamiliar.get(track_id, 0),
                "heading_mean_deg": round(mean, _DECIMALS),
            })
        return {"format": FORMAT, "version": VERSION, "frames": frames,
                "fps": round(frames / wall, 3) if wall > 0 else 0.0,
                "video_fps": self.video_fps, "wall_time_s": round(wall, 3),
                "poses": self.pose_kind, "tracks": tracks}

    def save(self) -> None:
        """Write the summary so far, atomically."""
        write_json_atomically(self.path, self.summary())

    def close(self) -> None:
        """Write the summary and put it in place; idempotent. If that fails, the partial file
        is removed and an existing summary is left as it was."""
        if self._closed:
            return
        self._closed = True
        try:
            text = json.dumps(self.summary(), allow_nan=False, separators=(",", ":"))
            self._file.write(text.encode("utf-8"))
            self._file.commit()
        except BaseException:
            self._file.discard()
            raise

    def abandon(self) -> None:
        """Stop without writing (a run that tracked nobody): the partial file is removed and
        the path keeps what it held; idempotent."""
        if self._closed:
            return
        self._closed = True
        self._file.discard()

    def __enter__(self) -> "JsonSummarySink":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()
