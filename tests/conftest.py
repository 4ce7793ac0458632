"""Shared fixtures: where the (optional) shared data lives; Ctrl-C as a terminal has it."""
from __future__ import annotations

import importlib.util
import os
import signal
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("SILHOUETTE_POSE_SHARED", ROOT.parent / "shared"))
CMU_BVH = SHARED / "data" / "cmu" / "bvh"
ANKUR_MAT = SHARED / "data" / "ankur" / "ankurDataPoseSilhouette.mat"
POSE2SIM_TRIAL = SHARED / "data" / "pose2sim" / "balancing"
POSE2SIM_SWINGS = SHARED / "data" / "pose2sim" / "swings"


def pytest_configure(config) -> None:
    """Several tests Ctrl-C a child process (track, a sink's writer) and check that it stops
    cleanly. A shell that starts the suite in the background (``pytest &`` in a script) starts
    it with SIGINT ignored, which every child inherits and rightly respects (track leaves an
    ignored SIGINT alone, as nohup expects): those children would never stop and the tests
    would time out (seen 2026-12-03). Give the suite, and so its children, the usual Ctrl-C."""
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def load_script(name: str) -> ModuleType:
    """A script of scripts/ (e.g. "evaluate_real") imported as a module, to test its parts."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def cut_run():
    """What tracker.run.track_video returns for a run a Ctrl-C ended early (3 frames)."""
    from tracker.run import TrackRun
    return TrackRun(frames=3, elapsed_s=0.1, interrupted=True, tracker=None)


def refused_in_one_line(script: ModuleType, argv: list[str], capsys) -> str:
    """Run a script's main(argv), expecting its parser to refuse the options: exit 2 and one
    line on stderr, no traceback. Returns that line."""
    with pytest.raises(SystemExit) as exit_:
        script.main(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    return err


@pytest.fixture(scope="session")
def cmu_bvh_dir() -> Path:
    """The CMU BVH folder of ../shared; skips the test when it is absent."""
    if not CMU_BVH.is_dir():
        pytest.skip(f"CMU motion capture not found at {CMU_BVH} (needs ../shared beside the repo)")
    return CMU_BVH


@pytest.fixture(scope="session")
def ankur_mat() -> Path:
    """The paper's descriptor data of ../shared; skips the test when it is absent."""
    if not ANKUR_MAT.is_file():
        pytest.skip(f"paper data not found at {ANKUR_MAT} (needs ../shared beside the repo)")
    return ANKUR_MAT


@pytest.fixture(scope="session")
def pose2sim_trial() -> Path:
    """Pose2Sim's balancing trial folder of ../shared; skips the test when it is absent."""
    if not POSE2SIM_TRIAL.is_dir():
        pytest.skip(f"Pose2Sim trial not found at {POSE2SIM_TRIAL} (needs ../shared beside the "
                    f"repo)")
    return POSE2SIM_TRIAL


@pytest.fixture(scope="session")
def pose2sim_swings() -> Path:
    """Pose2Sim's swings trial folder of ../shared (its calibration is balancing's); skips the
    test when either is absent."""
    if not POSE2SIM_SWINGS.is_dir() or not POSE2SIM_TRIAL.is_dir():
        pytest.skip(f"Pose2Sim swings trial not found at {POSE2SIM_SWINGS} (needs ../shared "
                    f"beside the repo)")
    return POSE2SIM_SWINGS
