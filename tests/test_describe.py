"""python -m regressor describe: the model file's regressor, parts, training and settings."""
from __future__ import annotations

import json

import numpy as np
import pytest

from regressor.__main__ import main
from regressor.describe import _expert, describe_model
from regressor.mixture import DampedKernelRegressor
from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
from regressor.rvm import RVMRegressor
from regressor.sparse_rvm import SparseRVMRegressor


@pytest.fixture(scope="module")
def shipped():
    return load_pose_model(DEFAULT_MODEL_PATH)


def test_describes_each_expert_of_the_shipped_mixture_as_stored(shipped):
    info = describe_model(shipped)
    experts = info["regressor"]["experts"]
    stored = np.load(DEFAULT_MODEL_PATH, allow_pickle=False)["mixture_expert_offsets"]
    assert len(experts) == len(stored) - 1
    assert [e["basis_functions"] for e in experts] == np.diff(stored).tolist()
    assert info["regressor"]["basis_functions"] == int(stored[-1])


def test_training_sources_count_the_sequences_trained_on(shipped):
    sources = describe_model(shipped)["training"]["sources"]
    assert sum(s["sequences"] for s in sources.values()) == len(shipped.description["trials"])


def test_an_rvm_expert_is_described_by_its_relevance_vectors():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(80, 3))
    Y = np.sin(X[:, :1]) + 0.01 * rng.normal(size=(80, 1))
    rvm = RVMRegressor("gaussian").fit(X, Y)
    described = _expert(rvm)
    assert described["kind"] == "rvm"
    assert described["relevance_vectors"] == rvm.n_basis_ < 80
    sparse = SparseRVMRegressor(n_candidates=40).fit(X, Y)
    assert _expert(sparse) == {"kind": "rvm", "basis": "gaussian",
                               "basis_functions": len(sparse.relevance_),
                               "relevance_vectors": len(sparse.relevance_)}
    ridge = _expert(DampedKernelRegressor(n_centres=10).fit(X, Y))
    assert ridge == {"kind": "damped_least_squares", "basis": "gaussian", "basis_functions": 10}


def test_command_prints_json_naming_the_model(capsys):
    assert main(["describe", str(DEFAULT_MODEL_PATH)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["model"] == str(DEFAULT_MODEL_PATH)
    assert {"regressor", "parts", "training", "settings"} <= set(info)
    assert info["settings"]["shape_context"] == {"angular_bins": 12, "radial_bins": 5,
                                                 "edge_points": 300, "r_inner": 0.125,
                                                 "r_outer": 3.0}


def test_command_refuses_a_file_that_is_not_a_model_in_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a model")
    assert main(["describe", str(bad)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "bad.npz" in err and "Traceback" not in err


def test_command_without_a_subcommand_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as exit_:
        main([])
    assert exit_.value.code == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
