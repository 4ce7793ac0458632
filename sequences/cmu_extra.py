"""The cmu_extra motion (expmap sequences, dances) as CMU-skeleton trials for the data set.

Route: scripts/convert_cmu_extra.py writes each sequence, converted to the 31-joint CMU
skeleton at 30 fps, as a BVH file into a cache folder; sequences.dataset.build_dataset takes
those files like ../cmu trials (read_bvh reads them; nothing in the builder changes). Trial
names start "xm_" (expmap) or "xd_" (dances), so they never collide with CMU trial ids.
Sequences that repeat ../cmu trials are left out (DUPLICATES, evidence in docs/cmu_extra.md).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Iterator

import numpy as np

from regressor.errors import SilhouettePoseError

from .bvh import Motion, read_bvh, write_bvh
from .expmap import expmap_files, expmap_name, read_expmap_motion
from .pose_vector import forward_kinematics
from .retarget import dance_files, dance_name, read_dance
from .skeleton import CMU_UNIT_M


class CmuExtraError(SilhouettePoseError, ValueError):
    """A converted file without the BVH header lines needed."""


#: Converted sequences that repeat a ../cmu trial (name -> that trial), found by
#: scripts/cmu_extra_duplicates.py: the same number of frames as the trial at 30 fps, median
#: nearest-pose distance 1-5 mm (others: 22 mm or more), matched frames in the trial's order.
#: xm_train_basketball_5 is 06_06, a held-out trial: leaving it out keeps it out of training.
DUPLICATES: dict[str, str] = {
    "xm_test_basketball_1": "06_07",
    "xm_train_basketball_1": "06_02",
    "xm_train_basketball_2": "06_03",
    "xm_train_basketball_3": "06_04",
    "xm_train_basketball_4": "06_05",
    "xm_train_basketball_5": "06_06",
    "xm_train_walking_1": "02_01",
    "xm_train_walking_2": "05_01",
    "xm_train_walking_3": "06_01",
    "xm_train_walking_4": "07_01",
    "xm_train_walking_5": "07_02",
    "xm_train_walking_extra_13": "08_02",
    "xm_train_walking_extra_14": "08_03",
    "xm_train_walking_extra_15": "08_08",
    "xm_train_walking_extra_16": "08_09",
    "xm_train_walking_extra_17": "08_10",
}


#: Median over frames of the lowest foot joint's height (ankles, toes), metres, in ../cmu's
#: walks (02_01 0.047, 05_02 0.042, 06_02 0.047, 09_01 0.054); converted motion is set to it.
FOOT_HEIGHT_M = 0.045
_FEET = ("LeftFoot", "RightFoot", "LeftToeBase", "RightToeBase")


def settle_on_floor(motion: Motion) -> Motion:
    """The motion raised or lowered (root height only) so that the median over frames of its
    lowest foot joint is FOOT_HEIGHT_M: the expmap files pose every subject on subject 02's
    bones (a taller subject's feet float) and some dances stand 6-10 cm below their floor."""
    P, _ = forward_kinematics(motion.offsets, motion.parents, motion.local_rotations(),
                              motion.root_position)
    feet = [motion.names.index(n) for n in _FEET]
    lowest = float(np.median(P[:, feet, 1].min(axis=1)))
    motion.root_position = motion.root_position.copy()
    motion.root_position[:, 1] += FOOT_HEIGHT_M / CMU_UNIT_M - lowest
    return motion


@dataclass
class Converted:
    """A converted sequence: motion on the CMU skeleton; residual_mm: (T, K) fit residual of
    a retargeted dance (None for expmap, whose skeleton is CMU's own)."""

    motion: Motion
    residual_mm: np.ndarray | None


@dataclass
class Item:
    """One source sequence: trial name, kind ("expmap" or "dances"), action, file, fps."""

    name: str
    kind: str
    action: str
    path: Path
    fps: float | None = 30.0

    def convert(self) -> Converted:
        """The sequence on the CMU skeleton at self.fps, its feet on the floor."""
        if self.kind == "expmap":
            return Converted(settle_on_floor(read_expmap_motion(self.path, fps=self.fps)), None)
        out = read_dance(self.path, fps=self.fps)
        return Converted(settle_on_floor(out.motion), out.residual_mm)


def convert_all(data_dir: str | Path, fps: float | None = 30.0) -> Iterator[Item]:
    """Every sequence of cmu_extra (``data_dir`` holding expmap/ and dances/), as Items to
    convert (expmap first, then the dances; each sorted by file)."""
    data_dir = Path(data_dir)
    for path in expmap_files(data_dir / "expmap"):
        yield Item(expmap_name(path), "expmap", path.parent.name, path, fps)
    for path in dance_files(data_dir / "dances"):
        yield Item(dance_name(path), "dances", path.parent.name, path, fps)


#: Converted sequences never trained on, kept for validation and reporting (as
#: sequences.dataset.HELD_OUT_TRIALS for ../cmu): one of each expmap action (the source's own
#: test sequence where it has one; directing_traffic_4, not _1 with its capture glitch), one
#: salsa dance with its partner (16 is 01's partner: the same dance), one Indian dance and one
#: martial art. walking and washwindow have one kept sequence each, so none trains.
EXTRA_HELD_OUT: tuple[str, ...] = (
    "xm_train_basketball_signal_5", "xm_train_directing_traffic_4", "xm_test_jumping_1",
    "xm_test_running_1", "xm_test_soccer_1", "xm_test_walking_1", "xm_test_walking_extra_6",
    "xm_test_washwindow_1",
    "xd_salsa_01", "xd_salsa_16", "xd_indian_04", "xd_martial_03",
)

#: Silhouettes per converted sequence by default when training with them: about 22,000 for
#: the 111 sequences beside the 71,456 of ../cmu (docs/cmu_extra.md, "Training with them").
EXTRA_ROWS_PER_TRIAL = 200

#: Names of the training sources in a model's description ("sources").
SOURCES = ("cmu", "cmu_extra_expmap", "cmu_extra_dances")
_WINDOW = re.compile(r"_at\d{5}$")


def extra_training_files(bvh_dir: str | Path, held_out: tuple[str, ...] = ()) -> list[Path]:
    """The converted BVH files of bvh_dir (written by scripts/convert_cmu_extra.py) that are
    not duplicates nor in held_out (e.g. EXTRA_HELD_OUT), sorted: pass them to build_dataset
    with the ../cmu training files."""
    skip = set(DUPLICATES) | set(held_out)
    return sorted(p for p in Path(bvh_dir).glob("x[md]_*.bvh") if p.stem not in skip)


def source_sequence(trial: str) -> str:
    """The sequence a data-set trial comes from: its name without a window's '_atNNNNN'
    (extra_trials cuts long sequences into windows named so)."""
    return _WINDOW.sub("", trial)


def source_of(trial: str) -> str:
    """The source a trial's name says it comes from: "cmu_extra_expmap" ("xm_"),
    "cmu_extra_dances" ("xd_"), "cmu_spliced" (sequences.splice's "spliced-"), else "cmu"."""
    if trial.startswith("xm_"):
        return "cmu_extra_expmap"
    if trial.startswith("xd_"):
        return "cmu_extra_dances"
    return "cmu_spliced" if trial.startswith("spliced-") else "cmu"


def extra_views(bvh_files, config_fps: float, rows_per_trial: int, max_views: int = 12,
                min_views: int = 1) -> dict[str, int]:
    """Views per converted trial for about rows_per_trial silhouettes each, as
    dataset.views_by_rows but from each file's own rate (its 'Frame Time'; views_by_rows
    assumes 120 fps and would give these 30-fps files 4x too many). Pass the result, merged
    with views_by_rows' for the ../cmu files, as build_dataset's ``views``."""
    out = {}
    for path in bvh_files:
        frames, fps = None, None
        with open(path, "r", errors="replace") as f:
            for line in f:
                if line.strip().startswith("Frames:"):
                    frames = int(line.split(":", 1)[1])
                elif line.strip().startswith("Frame Time:"):
                    fps = 1.0 / float(line.split(":", 1)[1])
                    break
        if frames is None or fps is None:
            raise CmuExtraError(f"{path}: no 'Frames:' and 'Frame Time:' lines")
        at_rate = frames * config_fps / fps
        out[Path(path).stem] = int(np.clip(round(rows_per_trial / max(at_rate, 1.0)),
                                           min_views, max_views))
    return out



def _windows(frames: int, rows: int, window: int) -> list[tuple[int, int]]:
    """(start, stop) frame ranges: about ``rows`` frames of a ``frames``-frame sequence in
    windows of about ``window`` consecutive frames spread evenly over it (all of it when it
    has no more than ``rows``)."""
    if frames <= rows:
        return [(0, frames)]
    count = max(1, int(round(rows / window)))
    length = max(1, rows // count)
    starts = np.round(np.linspace(0, frames - length, count)).astype(int)
    return [(int(s), int(s) + length) for s in starts]


def extra_trials(bvh_files, out_dir: str | Path, config_fps: float, rows_per_trial: int,
                 max_views: int = 10, window: int = 50) -> tuple[list[Path], dict[str, int]]:
    """(files, views) giving about rows_per_trial silhouettes per converted sequence: one no
    longer than that is rendered whole, from extra_views' number of views; a longer one once,
    as windows of about ``window`` frames (stacking needs consecutive frames) spread evenly
    over it, each written to out_dir as '<name>_atNNNNN.bvh' (frame NNNNN at its rate, kept
    if already there; each window is its own trial, seen from its own azimuth). Caps the
    long dances (up to 2,200 frames) so that the extras fit training's time budget."""
    out_dir = Path(out_dir)
    files, views = [], {}
    for path in map(Path, bvh_files):
        count = extra_views([path], config_fps, rows_per_trial, max_views)[path.stem]
        motion = None
        frames = _frame_count(path)
        ranges = _windows(frames, rows_per_trial, window)
        if len(ranges) == 1 and ranges[0] == (0, frames):
            files.append(path)
            views[path.stem] = count
            continue
        for start, stop in ranges:
            target = out_dir / f"{path.stem}_at{start:05d}.bvh"
            if not target.is_file():
                if motion is None:
                    motion = read_bvh(path, fps=None, drop_tpose=False)
                out_dir.mkdir(parents=True, exist_ok=True)
                part = replace(motion, euler_deg=motion.euler_deg[start:stop],
                               root_position=motion.root_position[start:stop])
                tmp = target.with_name(f".{target.name}.tmp")
                write_bvh(tmp, part)            # whole or not at all
                tmp.replace(target)
            files.append(target)
            views[target.stem] = 1
    return files, views


def extra_sources(folder: str | Path) -> list[Path]:
    """extra_training_files(folder, EXTRA_HELD_OUT); CmuExtraError (one line, in the scripts'
    --extra terms) when the folder is missing or holds none."""
    folder = Path(folder)
    if not folder.is_dir():
        raise CmuExtraError(f"--extra folder not found: {folder}")
    sources = extra_training_files(folder, held_out=EXTRA_HELD_OUT)
    if not sources:
        raise CmuExtraError(f"--extra {folder}: no converted cmu_extra files (write them with "
                            f"python scripts/convert_cmu_extra.py --out {folder})")
    return sources


def extra_dataset_trials(folder: str | Path, windows_dir: str | Path, config_fps: float,
                         rows_per_trial: int = EXTRA_ROWS_PER_TRIAL, max_views: int = 10
                         ) -> tuple[list[Path], dict[str, int], int]:
    """(files, views, silhouettes) of the converted sequences in ``folder`` to add to a
    training data set (scripts/train.py and build_dataset.py --extra): EXTRA_HELD_OUT left
    out, about rows_per_trial silhouettes each (extra_trials; windows written under
    windows_dir/rR). Raises CmuExtraError when the folder holds no converted files."""
    sources = extra_sources(folder)
    files, views = extra_trials(sources, Path(windows_dir) / f"r{rows_per_trial}", config_fps,
                                rows_per_trial, max_views)
    return files, views, sum(views[f.stem] * _frame_count(f) for f in files)


def _frame_count(path: Path) -> int:
    with open(path, "r", errors="replace") as f:
        for line in f:
            if line.strip().startswith("Frames:"):
                return int(line.split(":", 1)[1])
    raise CmuExtraError(f"{path}: no 'Frames:' line")


def training_sources(trials, frames) -> dict[str, dict[str, int]]:
    """What a data set holds by source (SOURCES order, then any other): {source:
    {"sequences": source sequences (windows counted once), "frames": distinct motion frames
    used (at the data set's rate), "rows": silhouettes}}, from each row's trial name (N,) and
    frame index in that trial (N,)."""
    trials, frames = np.asarray(trials), np.asarray(frames, dtype=np.int64)
    names, of_row = np.unique(trials, return_inverse=True)
    used = np.unique(of_row.astype(np.int64) * (int(frames.max(initial=0)) + 1) + frames)
    frames_of = np.bincount(used // (int(frames.max(initial=0)) + 1), minlength=len(names))
    rows_of = np.bincount(of_row, minlength=len(names))
    out: dict[str, dict[str, int]] = {}
    for name, n_frames, n_rows in zip(names, frames_of, rows_of):
        entry = out.setdefault(source_of(str(name)), {"sequences": set(), "frames": 0,
                                                      "rows": 0})
        entry["sequences"].add(source_sequence(str(name)))
        entry["frames"] += int(n_frames)
        entry["rows"] += int(n_rows)
    order = [s for s in SOURCES if s in out] + sorted(set(out) - set(SOURCES))
    return {s: {"sequences": len(out[s]["sequences"]), "frames": out[s]["frames"],
                "rows": out[s]["rows"]} for s in order}
