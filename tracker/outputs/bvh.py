"""BVH export: one file per track, written on close() (atomic.write_beside), a lock
``.PREFIX.bvh.lock`` failing a second sink on the same folder and prefix at once; angles from
bvh_write.pose_vectors_to_motion, frames on a regular grid (docs/code_notes/outputs.md)."""
from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from sequences.bvh_write import pose_vectors_to_motion, write_bvh
from sequences.motion import Motion
from sequences.skeleton import CMU_JOINT_NAMES, CMU_PARENTS, CMU_REST_OFFSETS, CMU_UNIT_M
from sequences.skeleton_tables import CMU_REST_END_SITES
from tracker.outputs.atomic import LockFile, write_beside
from tracker.outputs.files import ClosedOnExit, beside_name
from tracker.outputs.geometry import SinkInputError, check_joints, check_pose, checked_time

if TYPE_CHECKING:
    from tracker.pipeline import TrackedPose

_ROOT_CHANNELS = ["Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"]
_JOINT_CHANNELS = ["Zrotation", "Yrotation", "Xrotation"]


def default_cmu_template(fps: float) -> Motion:
    """A one-frame rest Motion of the CMU skeleton (subject 02's bone lengths, ZYX channels as
    in the CMU BVH conversion), for writing BVH without a motion-capture file at hand."""
    names = list(CMU_JOINT_NAMES)
    return Motion(
        names=names, parents=CMU_PARENTS.copy(), offsets=CMU_REST_OFFSETS.copy(),
        end_sites=CMU_REST_END_SITES.copy(),
        channels=[list(_ROOT_CHANNELS if p < 0 else _JOINT_CHANNELS) for p in CMU_PARENTS],
        euler_deg=np.zeros((1, len(names), 3)), root_position=np.zeros((1, 3)),
        fps=float(fps), source="")


def regular_rows(times_s: np.ndarray, fps: float) -> np.ndarray:
    """Rows (round((times_s[-1] - times_s[0]) fps) + 1,) int of a regular grid at ``fps`` over
    times_s (N,) increasing seconds: the latest at or before the grid time plus half a step (a
    time rounded a little late still lands on its own frame)."""
    count = int(round((times_s[-1] - times_s[0]) * fps)) + 1
    grid = times_s[0] + (np.arange(count) + 0.5) / fps
    return np.maximum(np.searchsorted(times_s, grid, side="right") - 1, 0)


class BVHSink(ClosedOnExit):
    """Collect each track's poses and root positions; write one BVH per track on close.
    directory: where files go (created if missing); files are ``<prefix>_<track id>.bvh``.
    fps: video frame rate (frames per second of the frame indices). template: the skeleton
    (a Motion, e.g. a CMU file read with sequences.bvh.read_bvh); None: default_cmu_template.
    min_frames: shortest track that gets a file. After close(), ``paths``: track id -> file."""

    def __init__(self, directory: str | Path, fps: float, prefix: str = "track",
                 template: Motion | None = None, min_frames: int = 1):
        if not (math.isfinite(fps) and fps > 0):
            raise SinkInputError(f"fps must be a positive number, got {fps}")
        self.directory = Path(directory)
        self.fps = float(fps)
        self.prefix = prefix
        self.template = default_cmu_template(fps) if template is None else template
        self.min_frames = int(min_frames)
        self._root = int(np.flatnonzero(np.asarray(self.template.parents) < 0)[0])
        # Per track, per frame: (frame index, time s, pose (55,), Hips position (3,) m).
        self._tracks: dict[int, list[tuple[int, float, np.ndarray, np.ndarray]]] = {}
        self.paths: dict[int, Path] = {}
        self.closed = False
        # The folders this sink makes (innermost first), removed again if empty by abandon().
        self._made = [p for p in (self.directory, *self.directory.parents) if not p.exists()]
        self.directory.mkdir(parents=True, exist_ok=True)
        try:
            self._lock = LockFile(beside_name(self.directory / f".{prefix}.bvh", ".lock"))
        except BaseException:           # another run holds it: leave no folder of ours behind
            self._remove_made_folders()
            raise

    def write(self, pose: TrackedPose) -> None:
        """Keep pose.filtered (55,), Hips position pose.joints_m[0] (m) and pose.time_s (s) of
        this track and frame; a track's frames and times must increase (else SinkInputError)."""
        if self.closed:
            raise SinkInputError("BVH sink is closed")
        frame_index, track_id = pose.frame_index, pose.track_id
        filtered = check_pose("filtered55", pose.filtered)
        joints = check_joints(pose.joints_m)
        time_s = checked_time(pose.time_s)
        kept = self._tracks.setdefault(int(track_id), [])
        if kept and (int(frame_index) <= kept[-1][0] or time_s <= kept[-1][1]):
            raise SinkInputError(f"track {track_id}: frame {frame_index} at {time_s:g} s does "
                                 f"not follow frame {kept[-1][0]} at {kept[-1][1]:g} s")
        kept.append((int(frame_index), time_s, filtered, joints[0]))

    def end_frame(self, frame_index: int) -> None:
        """Nothing per frame: files are written on close."""

    def motion(self, track_id: int) -> Motion:
        """The Motion that close() writes for ``track_id`` (KeyError if never written)."""
        _, times, poses, roots = zip(*self._tracks[track_id])
        rows = regular_rows(np.asarray(times), self.fps)
        vectors = np.asarray(poses)[rows]
        root_cmu = np.asarray(roots)[rows] / CMU_UNIT_M - self.template.offsets[self._root]
        motion = pose_vectors_to_motion(vectors, self.template, root_position=root_cmu)
        motion.fps = self.fps
        motion.source = f"{self.prefix}_{track_id}.bvh"
        return motion

    def close(self) -> None:
        """Write one BVH per track with at least min_frames frames; idempotent."""
        if self.closed:
            return
        self.closed = True
        try:
            for track_id in sorted(self._tracks):
                if len(self._tracks[track_id]) < self.min_frames:
                    continue
                # A name past the file system's limit gets its prefix cut and hashed (beside_name).
                path = beside_name(self.directory / self.prefix, f"_{track_id}.bvh")
                motion = self.motion(track_id)
                write_beside(path, lambda partial: write_bvh(partial, motion))
                self.paths[track_id] = path
        finally:
            self._lock.release()

    def abandon(self) -> None:
        """Write nothing (a run tracked nobody); remove the folders it made if empty; idempotent."""
        if not self.closed:
            self.closed = True
            self._lock.release()
            self._remove_made_folders()

    def _remove_made_folders(self) -> None:
        """Remove the folders the constructor made, innermost first, while they are empty."""
        for folder in self._made:
            try:
                folder.rmdir()
            except OSError:                 # not empty (someone else's files): kept
                break
