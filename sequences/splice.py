"""Spliced motions: training trials whose limbs come from other trials (issue 9, real video).

The motion capture covers walks, runs, dribbles, climbs and dances, and each limb moves in
step with the others as it did in those trials. A real person balancing on one leg with the
arms out (Pose2Sim's trial) is a median 10.7 degrees over the 53 body angles from the nearest
training pose; per body part (the nearest left arm, right arm, left leg, right leg, torso and
head taken apart) it is 6.1. A spliced motion keeps one trial's root, torso and head and takes
each limb, with some probability, from a stretch of another trial (its local joint rotations,
frame by frame, so the limb still moves as a limb does: the stacked input sees real motion):
the data set then holds bodies whose limbs do different things.

Measured before building this (a nearest-neighbour probe in the shipped model's input space,
databases of equal size rendered and degraded as the training set is, one-off drivers): on
Pose2Sim's four views the flexion error of the 16 nearest neighbours went 25.3 -> 20.9 degrees
when recombined poses were added to the real ones, while the held-out CMU trials stayed level
(16_11 12.8 -> 13.0, 06_06 11.0 -> 10.6, 06_08 9.9 -> 9.8). But a model trained with 24
spliced motions (``scripts/train.py --spliced 24``: 19,152 more silhouettes beside the 71,545)
did not carry that over (2026-12-04, docs/accuracy.md): Pose2Sim flexion 25.0 -> 26.3, and
smoothed corr8 lower on the validation videos (mean of five 0.519 -> 0.500) and the held-out
ones (16_11 0.801 -> 0.775). So it is not in the default recipe (``--spliced 0``). An
earlier try of made-up trials with one limb network (regressor/limb_net.py, "New
combinations", "Wider combinations", 2026-12-03) had found the same on the validation rows.

Limb joints are found by the skeleton: a joint belongs to the part of its nearest ancestor (or
itself) among the pose joints (sequences.pose_conversions.POSE_JOINT_PART, skeleton.FOLDED),
so fingers go with their hand and LHipJoint (a pelvis bone) with the torso.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from regressor.errors import SilhouettePoseError

from .bvh import Motion, read_bvh, write_bvh
from .pose_conversions import POSE_JOINT_PART
from .skeleton import FOLDED

#: The parts a spliced motion may take from another trial.
LIMBS: tuple[str, ...] = ("left arm", "right arm", "left leg", "right leg")
SPLICE_VERSION = 1


class SpliceError(SilhouettePoseError, ValueError):
    """Motions that cannot be spliced (different skeletons, too short) or bad options."""


@dataclass(frozen=True)
class SpliceConfig:
    """n_motions spliced motions of seconds each (at the files' own rate); each limb comes
    from another trial with probability limb_share; seed: everything random derives from
    it."""

    n_motions: int = 24
    seconds: float = 13.3
    limb_share: float = 0.6
    seed: int = 0

    def __post_init__(self):
        if not 1 <= self.n_motions <= 10_000:
            raise SpliceError(f"the number of spliced motions must be 1..10000, got "
                              f"{self.n_motions}")
        if not 0.5 <= self.seconds <= 600:
            raise SpliceError(f"spliced motions must last 0.5..600 s, got {self.seconds}")
        if not 0.0 < self.limb_share <= 1.0:
            raise SpliceError(f"the limb share must be in (0, 1], got {self.limb_share}")


def joint_parts(names: Sequence[str], parents: np.ndarray) -> list[str]:
    """Body part (POSE_JOINT_PART's names) of each joint (J,) of a CMU-named skeleton: the part
    of its nearest ancestor-or-self that is a pose joint or a folded joint's member."""
    part_of = dict(POSE_JOINT_PART)
    for joint, members in FOLDED.items():
        part_of.update({m: POSE_JOINT_PART[joint] for m in members})
    parts = []
    for j in range(len(names)):
        k = j
        while k >= 0 and names[k] not in part_of:
            k = int(parents[k])
        if k < 0:
            raise SpliceError(f"joint {names[j]} has no pose joint above it")
        parts.append(part_of[names[k]])
    return parts


def splice_limbs(base: Motion, donors: dict[str, tuple[Motion, int]]) -> Motion:
    """base with each limb in donors (part name -> (motion, first frame)) replaced by that
    motion's local rotations of the limb's joints from its first frame on, for base's T
    frames. Root, torso and head stay base's; bone lengths stay base's. Motions must share
    joint names and rotation orders and the frame rate."""
    parts = np.array(joint_parts(base.names, base.parents))
    euler = base.euler_deg.copy()
    T = base.n_frames
    for part, (donor, start) in donors.items():
        if part not in LIMBS:
            raise SpliceError(f"unknown limb {part!r}; limbs are {', '.join(LIMBS)}")
        if list(donor.names) != list(base.names) or \
                donor.rotation_orders() != base.rotation_orders():
            raise SpliceError(f"{donor.source or 'the donor'}: its skeleton differs from "
                              f"{base.source or 'the base'}'s")
        if donor.fps != base.fps:
            raise SpliceError(f"frame rates differ: {donor.fps} and {base.fps}")
        if not (0 <= start and start + T <= donor.n_frames):
            raise SpliceError(f"{donor.source or 'the donor'} has {donor.n_frames} frames, "
                              f"not {T} from frame {start}")
        joints = np.flatnonzero(parts == part)
        euler[:, joints] = donor.euler_deg[start:start + T, joints]
    return replace(base, euler_deg=euler, source="")


def spliced_motions(files: Sequence[str | Path], config: SpliceConfig
                    ) -> list[tuple[Motion, dict]]:
    """config.n_motions spliced motions from the BVH files (read at their own rate), each
    with its recipe {"base": (trial, first frame), limb: (trial, first frame), ...}. Only
    trials at least config.seconds long take part."""
    from .dataset import HELD_OUT_TRIALS, trial_name
    leaked = sorted({trial_name(f) for f in files} & set(HELD_OUT_TRIALS))
    if leaked:
        raise SpliceError(f"held-out trials {leaked} cannot be spliced into training motions")
    motions = {Path(f).stem: read_bvh(f, fps=None) for f in files}
    fps = {m.fps for m in motions.values()}
    if len(fps) != 1:
        raise SpliceError(f"the files have different frame rates: {sorted(fps)}")
    T = int(round(config.seconds * fps.pop()))
    long_enough = sorted(n for n, m in motions.items() if m.n_frames >= T)
    if len(long_enough) < 2:
        raise SpliceError(f"fewer than 2 trials last {config.seconds} s")
    rng = np.random.default_rng(config.seed)

    def stretch() -> tuple[str, int]:
        name = long_enough[rng.integers(len(long_enough))]
        return name, int(rng.integers(0, motions[name].n_frames - T + 1))

    out = []
    for _ in range(config.n_motions):
        base_name, base_start = stretch()
        base = motions[base_name]
        base = replace(base, euler_deg=base.euler_deg[base_start:base_start + T],
                       root_position=base.root_position[base_start:base_start + T])
        recipe, donors = {"base": (base_name, base_start)}, {}
        for limb in LIMBS:
            if rng.random() < config.limb_share:
                name, start = stretch()
                donors[limb] = (motions[name], start)
                recipe[limb] = (name, start)
        out.append((splice_limbs(base, donors), recipe))
    return out


def recipe_name(config: SpliceConfig, sources: Sequence[str | Path]) -> str:
    """'spliced-<digest>': the digest of the recipe (config, version, source trials). The
    spliced motions' trial names begin with it, so a data-set cache never mixes recipes."""
    text = json.dumps({"config": asdict(config), "version": SPLICE_VERSION,
                       "sources": sorted(Path(s).stem for s in sources)}, sort_keys=True)
    return f"spliced-{hashlib.sha256(text.encode()).hexdigest()[:10]}"


def write_spliced_files(files: Sequence[str | Path], config: SpliceConfig,
                        out_dir: str | Path) -> list[Path]:
    """Write the spliced motions of files as BVH files under out_dir, named
    '<recipe_name>-<i>' (kept if already there) with a JSON of their recipes beside,
    '<recipe_name>.json'; returns their paths, in order."""
    out_dir, name = Path(out_dir), recipe_name(config, files)
    paths = [out_dir / f"{name}-{i:03d}.bvh" for i in range(config.n_motions)]
    if all(p.is_file() for p in paths):
        return paths
    out_dir.mkdir(parents=True, exist_ok=True)
    recipes = {}
    for path, (motion, recipe) in zip(paths, spliced_motions(files, config)):
        tmp = path.with_suffix(".tmp")
        write_bvh(tmp, motion)
        tmp.replace(path)
        recipes[path.stem] = recipe
    (out_dir / f"{name}.json").write_text(
        json.dumps(recipes, indent=1), encoding="utf-8")
    return paths
