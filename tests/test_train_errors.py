"""scripts/train.py refuses, before any rendering, an --out it could not write or that would
overwrite what training reads or keeps (a BVH of --bvh-dir, also through a hard link, a file of
the --cache) and a negative --seed, in one line naming the option; Ctrl-C stops its worker
processes and ends it in one line (exit 130), the workers leaving Ctrl-C to it."""
from __future__ import annotations

import multiprocessing
import os
import signal
import time

import pytest

from conftest import load_script, refused_in_one_line


@pytest.fixture(scope="module")
def train():
    return load_script("train")


@pytest.fixture
def folders(tmp_path):
    """(a --bvh-dir holding one BVH, a --cache not yet made)."""
    bvh_dir = tmp_path / "bvh"
    bvh_dir.mkdir()
    (bvh_dir / "01_01.bvh").write_text("HIERARCHY\n")
    return bvh_dir, tmp_path / "cache"


def test_outputs_that_are_an_input_or_cannot_be_written_are_refused(train, folders, tmp_path,
                                                                   capsys):
    bvh_dir, cache = folders
    bvh = bvh_dir / "01_01.bvh"
    os.link(bvh, tmp_path / "linked.npz")

    def refused(out):
        return refused_in_one_line(train, ["--regressor", "rvm", "--clean", "--bvh-dir",
                                           str(bvh_dir), "--cache", str(cache), "--out",
                                           str(out)], capsys)
    assert "named like the motion capture in --bvh-dir" in refused(bvh)
    assert "named like the motion capture in --bvh-dir" in refused(bvh_dir / "new.bvh")
    assert "is the same file as --bvh-dir" in refused(tmp_path / "linked.npz")
    assert "is a folder" in refused(bvh_dir)
    assert "no folder" in refused(tmp_path / "none" / "model.npz")
    for kept in (cache / "descriptors-v2-abc.npz", cache / "dataset" / "model.npz"):
        assert "among the files training keeps in --cache" in refused(kept)
    assert bvh.read_text() == "HIERARCHY\n"
    assert not cache.exists() and sorted(p.name for p in bvh_dir.iterdir()) == ["01_01.bvh"]


def test_a_negative_seed_is_refused_naming_the_option(train, folders, tmp_path, capsys):
    bvh_dir, cache = folders
    err = refused_in_one_line(train, ["--seed", "-1", "--bvh-dir", str(bvh_dir), "--cache",
                                      str(cache), "--out", str(tmp_path / "m.npz")], capsys)
    assert "--seed must be in 0..2147483647, got -1" in err
    assert not cache.exists()


@pytest.mark.parametrize("flag, value", [("--views", "-1"), ("--codebook-centres", "0"),
                                         ("--codebook-centres", "5000")])
def test_views_and_codebook_size_out_of_range_are_refused_naming_the_option(
        train, folders, tmp_path, capsys, flag, value):
    bvh_dir, cache = folders
    err = refused_in_one_line(train, [flag, value, "--bvh-dir", str(bvh_dir), "--cache",
                                      str(cache), "--out", str(tmp_path / "m.npz")], capsys)
    assert f"{flag} must be in" in err and f"got {value}" in err
    assert not cache.exists()


def _sleep() -> None:
    time.sleep(60)


def test_ctrl_c_stops_the_workers_and_ends_in_one_line(train, monkeypatch, capfd):
    """A pool waits for its workers' tasks (a trial's rendering: a minute or more) before an
    interrupt gets through: Ctrl-C stops them first. A worker (forked) leaves Ctrl-C, which a
    terminal sends it too, to the main process: no traceback of its own."""
    if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        pytest.skip("Ctrl-C is not Python's default here")
    fork = multiprocessing.get_context("fork")
    workers = {}

    def training(argv):
        workers["busy"] = fork.Process(target=_sleep)
        workers["busy"].start()
        workers["interrupted"] = fork.Process(target=time.sleep, args=(0.5,))
        workers["interrupted"].start()
        os.kill(workers["interrupted"].pid, signal.SIGINT)
        workers["interrupted"].join(10)
        os.kill(os.getpid(), signal.SIGINT)              # as Ctrl-C reaches this process
        time.sleep(10)
        return 0
    monkeypatch.setattr(train, "_main", training)
    started = time.perf_counter()
    try:
        assert train.main([]) == 130
        assert time.perf_counter() - started < 5
        workers["busy"].join(5)
        assert workers["busy"].exitcode == -signal.SIGTERM
    finally:                                # never leave a sleeping worker behind
        for worker in workers.values():
            if worker.is_alive():
                worker.kill()
    assert workers["interrupted"].exitcode == 0            # it ignored Ctrl-C
    err = capfd.readouterr().err
    assert err.startswith("train: interrupted") and len(err.splitlines()) == 1
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
