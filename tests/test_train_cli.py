"""scripts/train.py refuses absurd options in one line before any slow step (rendering the
data set alone takes minutes): nothing is rendered or written."""
from __future__ import annotations

import pytest

from conftest import load_script, refused_in_one_line


@pytest.fixture(scope="module")
def train():
    return load_script("train")


@pytest.mark.parametrize("options, says", [
    (["--layout-grid", "-3"], "--layout-grid must be in 0..64, got -3"),
    (["--stack", "0"], "--stack must be in 1..30"),
    (["--experts", "0"], "--experts must be in 1..1000"),
    (["--max-views", "0"], "--max-views must be in 1..360"),
    (["--lam", "nan"], "--lam must be a positive number"),
    (["--width-scale", "-1"], "--width-scale must be a positive number"),
    (["--components", "10"], "needs --components >= 50"),
    (["--clean"], "--layout-grid needs the video-like masks"),
    (["--limb-net-reversed", "1.5"], "--limb-net-reversed must be in 0..1, got 1.5"),
    (["--spliced", "-1"], "--spliced must be in 0..10000, got -1"),
    (["--limb-nets", "0"], "a limb head of expert weights (--limb-nets 0) needs --expert dls"),
    (["--expert", "svm"], "argument --expert: invalid choice"),
    (["--backgrounds", "procedural"], "--backgrounds needs --masks realistic"),
    (["--masks", "realistic", "--clean", "--layout-grid", "0"],
     "--masks realistic makes video-like masks; --clean trains on the plain renders"),
    (["--masks", "realistic", "--backgrounds", "no-such-rooms"],
     "--backgrounds: folder not found: no-such-rooms"),
    (["--masks", "plain"], "argument --masks: invalid choice: 'plain'"),
])
def test_absurd_options_are_refused_before_rendering(train, tmp_path, capsys, options, says):
    cache, out = tmp_path / "cache", tmp_path / "model.npz"
    err = refused_in_one_line(train, options + ["--bvh-dir", str(tmp_path / "no-bvh"),
                                                "--cache", str(cache), "--out", str(out)],
                              capsys)
    assert says in err
    assert not cache.exists() and not out.exists()


def test_the_baseline_rvm_on_clean_renders_is_still_accepted(train, tmp_path, capsys):
    """--clean with the single RVM (the README's baseline command) passes the checks: it fails
    only later, on the missing motion capture, with its own one-line error."""
    assert train.main(["--regressor", "rvm", "--clean", "--bvh-dir", str(tmp_path / "no-bvh"),
                       "--cache", str(tmp_path / "cache"), "--out", str(tmp_path / "m.npz")]) == 1
    err = capsys.readouterr().err.strip()
    assert "must be" not in err and "no-bvh" in err and len(err.splitlines()) == 1
