"""The cmu_extra motion (expmap sequences, dances) as CMU-skeleton trials for the data set.

Route: scripts/convert_cmu_extra.py writes each sequence, converted to the 31-joint CMU
skeleton at 30 fps, as a BVH file into a cache folder; sequences.dataset.build_dataset takes
those files like ../cmu trials (read_bvh reads them; nothing in the builder changes). Trial
names start "xm_" (expmap) or "xd_" (dances), so they never collide with CMU trial ids.
Sequences that repeat ../cmu trials are left out (DUPLICATES, evidence in docs/cmu_extra.md).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

from regressor.errors import SilhouettePoseError

from .bvh import Motion
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


def extra_training_files(bvh_dir: str | Path) -> list[Path]:
    """The converted BVH files of bvh_dir (written by scripts/convert_cmu_extra.py) that are
    not duplicates, sorted: pass them to build_dataset with the ../cmu training files."""
    return sorted(p for p in Path(bvh_dir).glob("x[md]_*.bvh") if p.stem not in DUPLICATES)


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

