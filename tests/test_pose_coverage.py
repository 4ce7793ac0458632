"""scripts/pose_coverage.py's measure on hand-made poses: the nearest training pose over the 53
body angles, per body part, and the parts put together."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import load_script


@pytest.fixture(scope="module")
def cov():
    return load_script("pose_coverage")


def test_nearest_distance_is_the_mean_absolute_wrapped_difference(cov):
    """The heading columns never count; 179 and -179 are 2 degrees apart."""
    training = np.zeros((2, 55))
    training[1, 2:] = 10.0
    training[:, 0] = [1.0, -1.0]                      # headings differ: ignored
    query = np.zeros((1, 55))
    query[0, 2:] = 3.0
    query[0, 1] = 1.0
    assert cov.nearest_distance(query, training, np.arange(2, 55)) == pytest.approx([3.0])
    a, b = np.zeros((1, 55)), np.zeros((1, 55))
    a[0, 2:], b[0, 2:] = 179.0, -179.0
    assert cov.nearest_distance(a, b, np.arange(2, 55)) == pytest.approx([2.0])


def test_parts_may_come_from_different_training_poses(cov):
    """A query with the legs of one training pose and the arms of another: far from both as a
    whole, at 0 by parts; each part's distance is that part's own."""
    columns = cov.part_columns()
    legs = np.r_[columns["left leg"], columns["right leg"]]
    arms = np.r_[columns["left arm"], columns["right arm"]]
    assert sorted(np.r_[tuple(columns.values())]) == list(range(2, 55))
    first, second = np.zeros(55), np.zeros(55)
    first[legs], second[arms] = 40.0, 30.0
    query = np.zeros((1, 55))
    query[0, legs], query[0, arms] = 40.0, 30.0
    got = cov.coverage(query, np.stack([first, second]))
    assert got["whole"] == pytest.approx([min(30.0 * 24, 40.0 * 18) / 53])
    for part in cov.PARTS:
        assert got[part] == pytest.approx([0.0])
    assert got["parts"] == pytest.approx([0.0])
    query[0, columns["head"]] = 5.0                   # no training head has 5 degrees
    got = cov.coverage(query, np.stack([first, second]))
    assert got["head"] == pytest.approx([5.0])
    assert got["parts"] == pytest.approx([5.0 * 6 / 53])


def test_many_queries_in_chunks_give_each_its_own_nearest(cov, monkeypatch):
    rng = np.random.default_rng(0)
    training = rng.uniform(-180, 180, (50, 55))
    queries = training[[3, 7, 11]] + 1.0
    monkeypatch.setattr(cov, "_CHUNK_VALUES", 1)      # one query at a time
    assert cov.nearest_distance(queries, training, np.arange(2, 55)) == pytest.approx([1.0] * 3)
    summary = cov.summarize(cov.coverage(queries, training))
    assert summary["frames"] == 3 and summary["whole"] == pytest.approx(1.0)


def test_joint_distance_ignores_the_heading_and_sees_the_posture(cov):
    """The same pose facing elsewhere is at 0 mm; a bent knee is not."""
    from sequences.pose_vector import pose_vector_names
    names = pose_vector_names()
    standing = np.zeros((1, 55))
    standing[0, 0] = 1.0
    turned = standing.copy()
    turned[0, :2] = [0.0, 1.0]
    bent = standing.copy()
    bent[0, names.index("LeftLeg_x")] = 90.0
    training = cov.posture_mm(standing)
    assert cov.nearest_joint_distance(cov.posture_mm(turned), training) == pytest.approx([0.0],
                                                                                        abs=1e-3)
    far = cov.nearest_joint_distance(cov.posture_mm(bent), training)
    assert 10.0 < far[0] < 200.0            # the left ankle and foot moved, ~0.4 m each


def test_missing_folders_and_absurd_rates_are_refused_in_one_line(cov, tmp_path, capsys):
    from conftest import refused_in_one_line
    assert "--pose2sim folder not found" in refused_in_one_line(
        cov, ["--pose2sim", str(tmp_path / "none")], capsys)
    assert "--fps must be in (0, 120], got 0.0" in refused_in_one_line(cov, ["--fps", "0"],
                                                                       capsys)
