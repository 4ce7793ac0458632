"""Shared fixtures: where the (optional) shared data lives."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("SILHOUETTE_POSE_SHARED", ROOT.parent / "shared"))
CMU_BVH = SHARED / "data" / "cmu" / "bvh"
ANKUR_MAT = SHARED / "data" / "ankur" / "ankurDataPoseSilhouette.mat"


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
