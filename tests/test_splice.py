"""Spliced motions (sequences.splice): each limb's joints, and only they, come from the donor's
stretch; the recipe is reproducible; held-out trials and mismatched skeletons are refused."""
from __future__ import annotations

import json

import numpy as np
import pytest

from sequences.bvh import read_bvh, write_bvh
from sequences.splice import (LIMBS, SpliceConfig, SpliceError, joint_parts, splice_limbs,
                              spliced_motions, write_spliced_files)
from sequences.skeleton import CMU_JOINT_NAMES, CMU_PARENTS
from tests.synthetic import cmu_motion, joint

J = len(CMU_JOINT_NAMES)


def _motion(T: int, value: float, fps: float = 120.0, source: str = "m"):
    """Every joint angle of frame t is value + t + 0.25 (so a copied stretch is recognisable;
    not whole numbers, which read_bvh would take for an added T-pose)."""
    euler = value + 0.25 + np.arange(T, dtype=float)[:, None, None] + np.zeros((T, J, 3))
    root = np.c_[value + np.arange(T), np.full(T, 17.0), np.zeros(T)]   # moves frame by frame
    return cmu_motion(euler, root, fps=fps, source=source)


def test_joint_parts_follow_the_skeleton():
    parts = dict(zip(CMU_JOINT_NAMES, joint_parts(CMU_JOINT_NAMES, CMU_PARENTS)))
    assert parts["LeftForeArm"] == parts["LeftHandIndex1"] == parts["LThumb"] == "left arm"
    assert parts["RightToeBase"] == parts["RightUpLeg"] == "right leg"
    # LHipJoint is a pelvis bone above the leg; the folded spine joints are torso.
    assert parts["LHipJoint"] == parts["LowerBack"] == parts["Spine"] == "torso"
    assert parts["Neck1"] == parts["Head"] == "head"


def test_a_spliced_limb_is_the_donors_stretch_and_nothing_else_changes():
    base, donor = _motion(10, 0.0), _motion(40, 1000.0)
    out = splice_limbs(base, {"right arm": (donor, 25)})
    parts = np.array(joint_parts(base.names, base.parents))
    arm = parts == "right arm"
    assert arm.sum() == 7
    np.testing.assert_array_equal(out.euler_deg[:, arm], donor.euler_deg[25:35][:, arm])
    np.testing.assert_array_equal(out.euler_deg[:, ~arm], base.euler_deg[:, ~arm])
    np.testing.assert_array_equal(out.root_position, base.root_position)
    np.testing.assert_array_equal(base.euler_deg, _motion(10, 0.0).euler_deg)   # untouched


def test_refusals():
    base = _motion(10, 0.0)
    with pytest.raises(SpliceError, match="not 10 from frame 5"):
        splice_limbs(base, {"left leg": (_motion(12, 5.0), 5)})
    with pytest.raises(SpliceError, match="unknown limb 'torso'"):
        splice_limbs(base, {"torso": (_motion(10, 5.0), 0)})
    with pytest.raises(SpliceError, match="frame rates differ"):
        splice_limbs(base, {"left leg": (_motion(10, 5.0, fps=30.0), 0)})
    other = _motion(10, 5.0)
    other.names = list(other.names)
    other.names[joint("LeftFoot")] = "LeftAnkle"
    with pytest.raises(SpliceError, match="skeleton differs"):
        splice_limbs(base, {"left leg": (other, 0)})
    with pytest.raises(SpliceError, match="must be 1..10000"):
        SpliceConfig(n_motions=0)


def _trials(folder, names, T=300):
    paths = []
    for k, name in enumerate(names):
        path = folder / f"{name}.bvh"
        write_bvh(path, _motion(T, 100.0 * k, source=name))
        paths.append(path)
    return paths


def test_spliced_motions_follow_their_recipes_and_repeat(tmp_path):
    files = _trials(tmp_path, ["02_01", "05_01", "08_02"])
    config = SpliceConfig(n_motions=6, seconds=1.0, limb_share=0.6, seed=3)
    made = spliced_motions(files, config)
    again = spliced_motions(files, config)
    parts = np.array(joint_parts(CMU_JOINT_NAMES, CMU_PARENTS))
    originals = {p.stem: read_bvh(p, fps=None) for p in files}
    spliced_limbs = 0
    for (motion, recipe), (motion2, _) in zip(made, again):
        np.testing.assert_array_equal(motion.euler_deg, motion2.euler_deg)
        assert motion.n_frames == 120
        name, start = recipe["base"]
        torso = parts == "torso"
        np.testing.assert_array_equal(motion.euler_deg[:, torso],
                                      originals[name].euler_deg[start:start + 120, torso])
        np.testing.assert_array_equal(motion.root_position,
                                      originals[name].root_position[start:start + 120])
        for limb in LIMBS:
            source, first = recipe.get(limb, recipe["base"])
            sel = parts == limb
            np.testing.assert_array_equal(motion.euler_deg[:, sel],
                                          originals[source].euler_deg[first:first + 120, sel])
            spliced_limbs += limb in recipe
    assert 0 < spliced_limbs < 6 * 4       # a share of the limbs, not none, not all


def test_held_out_trials_are_never_spliced(tmp_path):
    files = _trials(tmp_path, ["02_01", "16_11"])
    with pytest.raises(SpliceError, match="held-out trials"):
        spliced_motions(files, SpliceConfig(n_motions=1, seconds=1.0))


def test_written_files_carry_the_recipe_in_their_names(tmp_path):
    files = _trials(tmp_path, ["02_01", "05_01"])
    out = write_spliced_files(files, SpliceConfig(n_motions=2, seconds=1.0), tmp_path / "out")
    assert [p.is_file() for p in out] == [True, True]
    assert out[0].stem.startswith("spliced-") and out[0].stem.endswith("-000")
    recipes = json.loads(next((tmp_path / "out").glob("*.json")).read_text())
    assert sorted(recipes) == sorted(p.stem for p in out)
    assert read_bvh(out[1], fps=None).n_frames == 120
    # Already written: kept as they are, not made again.
    out[0].write_text(out[0].read_text() + "\n")
    stamp = out[0].read_text()
    again = write_spliced_files(files, SpliceConfig(n_motions=2, seconds=1.0), tmp_path / "out")
    assert again == out and out[0].read_text() == stamp
    other = write_spliced_files(files, SpliceConfig(n_motions=2, seconds=1.0, seed=1),
                                tmp_path / "out")
    assert {p.stem for p in other}.isdisjoint({p.stem for p in out})
