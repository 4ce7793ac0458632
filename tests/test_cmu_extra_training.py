"""The converted cmu_extra sequences in training, opt-in (train.py / build_dataset.py --extra):
held-out sequences left out, about a fixed number of silhouettes per sequence (views of short
ones, windows of long ones), and the sources a model records in its description."""
from __future__ import annotations

import numpy as np
import pytest

from sequences.bvh import read_bvh, write_bvh
from sequences.cmu_extra import (EXTRA_HELD_OUT, CmuExtraError, extra_dataset_trials,
                                 extra_training_files, extra_trials, source_of, source_sequence,
                                 training_sources)
from sequences.expmap import expmap_to_motion

from conftest import load_script, refused_in_one_line


def _write(path, frames: int) -> None:
    """A 30-fps converted file of ``frames`` frames whose root height counts the frames."""
    rows = np.zeros((frames, 117))
    rows[:, 1] = np.arange(frames)
    motion = expmap_to_motion(rows, fps=None, drop_tpose=False)
    motion.fps = 30.0
    write_bvh(path, motion)


def test_short_sequences_get_views_and_long_ones_windows(tmp_path):
    """200 rows a sequence: a 50-frame one whole from 4 views; a 1000-frame one once, as 4
    windows of 50 consecutive frames spread over it (first and last frames included), each
    window its own trial of one view, read back as the same frames."""
    _write(tmp_path / "xm_train_jumping_2.bvh", 50)
    _write(tmp_path / "xd_salsa_02.bvh", 1000)
    files, views = extra_trials(sorted(tmp_path.glob("*.bvh")), tmp_path / "w", 30.0, 200)
    names = [f.stem for f in files]
    assert names == ["xd_salsa_02_at00000", "xd_salsa_02_at00317", "xd_salsa_02_at00633",
                     "xd_salsa_02_at00950", "xm_train_jumping_2"]
    assert views == {**{n: 1 for n in names[:4]}, "xm_train_jumping_2": 4}
    source = read_bvh(tmp_path / "xd_salsa_02.bvh", fps=None, drop_tpose=False)
    for f in files[:4]:
        window = read_bvh(f, fps=None, drop_tpose=False)
        start = int(f.stem[-5:])
        assert window.n_frames == 50 and window.fps == pytest.approx(30.0)
        np.testing.assert_allclose(window.root_position,
                                   source.root_position[start:start + 50], atol=1e-6)
    assert {source_sequence(n) for n in names} == {"xd_salsa_02", "xm_train_jumping_2"}


def test_a_sequence_just_over_the_rows_gives_windows_that_do_not_overlap(tmp_path):
    _write(tmp_path / "xd_indian_06.bvh", 201)
    files, _ = extra_trials([tmp_path / "xd_indian_06.bvh"], tmp_path / "w", 30.0, 200)
    starts = [int(f.stem[-5:]) for f in files]
    assert len(starts) == 4 and np.all(np.diff(starts) >= 50) and starts[-1] + 50 <= 201


def test_held_out_and_repeated_sequences_are_left_out(tmp_path):
    for name in ("xm_test_jumping_1", "xm_train_jumping_2", "xm_train_walking_1",
                 "xd_salsa_16", "xd_salsa_17"):
        _write(tmp_path / f"{name}.bvh", 20)
    files, views, rows = extra_dataset_trials(tmp_path, tmp_path / "w", 30.0, 200)
    assert [f.stem for f in files] == ["xd_salsa_17", "xm_train_jumping_2"]
    assert rows == 2 * 20 * 10              # at most --max-views (10) views of 20 frames
    assert [p.stem for p in extra_training_files(tmp_path)] == [
        "xd_salsa_16", "xd_salsa_17", "xm_test_jumping_1", "xm_train_jumping_2"]


def test_held_out_holds_one_of_each_kind():
    actions = {n[len("xm_test_"):] if n.startswith("xm_test_") else n[len("xm_train_"):]
               for n in EXTRA_HELD_OUT if n.startswith("xm_")}
    assert {a.rsplit("_", 1)[0] for a in actions} == {
        "basketball_signal", "directing_traffic", "jumping", "running", "soccer", "walking",
        "walking_extra", "washwindow"}
    assert {n.rsplit("_", 1)[0] for n in EXTRA_HELD_OUT if n.startswith("xd_")} == {
        "xd_salsa", "xd_indian", "xd_martial"}


def test_a_folder_without_converted_files_is_one_line(tmp_path):
    with pytest.raises(CmuExtraError, match="no converted cmu_extra files"):
        extra_dataset_trials(tmp_path, tmp_path / "w", 30.0)
    with pytest.raises(CmuExtraError, match="folder not found"):
        extra_dataset_trials(tmp_path / "none", tmp_path / "w", 30.0)


def test_sources_count_sequences_frames_and_rows():
    """Two views of a 3-frame ../cmu trial: 1 sequence, 3 frames, 6 rows; two windows of one
    dance: 1 sequence, their 4 frames; an expmap walk; a spliced motion on its own line."""
    trials = (["02_01"] * 6 + ["xd_salsa_02_at00000"] * 2 + ["xd_salsa_02_at00100"] * 2
              + ["xm_test_walking_extra_7"] * 3 + ["spliced-abc-000"])
    frames = [0, 1, 2, 0, 1, 2, 0, 1, 0, 1, 0, 1, 2, 0]
    assert training_sources(trials, frames) == {
        "cmu": {"sequences": 1, "frames": 3, "rows": 6},
        "cmu_extra_expmap": {"sequences": 1, "frames": 3, "rows": 3},
        "cmu_extra_dances": {"sequences": 1, "frames": 4, "rows": 4},
        "cmu_spliced": {"sequences": 1, "frames": 1, "rows": 1}}
    assert source_of("16_11") == "cmu"


@pytest.mark.parametrize("script, options", [("train", ["--regressor", "rvm", "--clean"]),
                                             ("build_dataset", [])])
def test_a_missing_or_empty_extra_folder_is_refused_before_rendering(script, options, tmp_path,
                                                                     capsys):
    bvh = tmp_path / "bvh"
    bvh.mkdir()
    (bvh / "01_01.bvh").write_text("")
    (tmp_path / "empty").mkdir()
    module = load_script(script)
    for folder, says in ((tmp_path / "converted", "--extra folder not found: "),
                         (tmp_path / "empty", "no converted cmu_extra files")):
        err = refused_in_one_line(module, options + ["--bvh-dir", str(bvh), "--extra",
                                                     str(folder), "--cache",
                                                     str(tmp_path / "c")], capsys)
        assert says in err and str(folder) in err
    assert not (tmp_path / "c").exists()


@pytest.mark.parametrize("script", ["train", "build_dataset"])
def test_absurd_extra_rows_are_refused(script, tmp_path, capsys):
    module = load_script(script)
    with pytest.raises(SystemExit) as exit_:
        module.main(["--extra-rows-per-trial", "0", "--cache", str(tmp_path / "c"),
                     "--bvh-dir", str(tmp_path)])
    assert exit_.value.code == 2
    assert "--extra-rows-per-trial must be in 1..1000000, got 0" in capsys.readouterr().err


def test_the_model_description_records_the_sources():
    """Every model records its sources (../cmu alone too), so `python -m regressor describe`
    prints them; windows of one dance are one sequence there, and the cmu_extra held-out
    sequences join the held-out trials when the extras trained."""
    from sequences.dataset import HELD_OUT_TRIALS, Dataset, DatasetConfig
    from lab.training import TrainingOptions
    train = load_script("train")
    n = 7
    data = Dataset(masks=np.zeros((n, 2, 2), bool), pose=np.zeros((n, 55)),
                   sequence=np.array([0, 0, 1, 1, 2, 2, 2]), frame=np.array([0, 1, 0, 1, 0, 1, 2]),
                   azimuth_deg=np.zeros(n), elevation_deg=np.zeros(n),
                   trials=["02_01", "xd_salsa_02_at00000", "xd_salsa_02_at00100"],
                   trial_of_sequence=["02_01", "xd_salsa_02_at00000", "xd_salsa_02_at00100"])
    described = train.model_description(data, DatasetConfig(), TrainingOptions(), {}, extra=True)
    assert described["trials"] == ["02_01", "xd_salsa_02"]
    assert described["sources"] == {"cmu": {"sequences": 1, "frames": 2, "rows": 2},
                                    "cmu_extra_dances": {"sequences": 1, "frames": 5, "rows": 5}}
    assert described["held_out"] == list(HELD_OUT_TRIALS) + list(EXTRA_HELD_OUT)
    plain = train.model_description(data, DatasetConfig(), TrainingOptions(), {}, extra=False)
    assert plain["held_out"] == list(HELD_OUT_TRIALS)
