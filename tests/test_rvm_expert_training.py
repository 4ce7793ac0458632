"""train_mixture_model with sparse RVM experts: the experts, their calibrated variance, files."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from regressor.angles import pose_angles, wrap_deg
from regressor.optional_parts import gives_variance, predict_batch, predict_variance
from regressor.pose_model import load_pose_model
from regressor.model_writer import save_pose_model
from regressor.sparse_rvm import SparseRVMRegressor
from regressor.stacking import stack_frames
from tests.test_heading_index_training import _dataset, _options
from lab.training import train_mixture_model, validation_mask
from regressor.pose_model import frame_descriptors
from regressor.training import calibrate_variance


@pytest.fixture(scope="module")
def trained():
    data, X, codebook, settings = _dataset()
    model, report = train_mixture_model(data, X, codebook, settings, _options(), 30.0,
                                        log=lambda m: None)
    val = validation_mask(data)
    Xs = stack_frames(frame_descriptors(X, model.transform), model.stack_depth,
                      sequence_ids=data.sequence)[val]
    return model, report, Xs, data.pose[val]


def test_the_default_experts_are_sparse_rvms_fitted_on_all_their_rows(trained):
    model, report, _, _ = trained
    experts = model.mixture.experts_
    assert all(isinstance(e, SparseRVMRegressor) for e in experts)
    assert [e.n_train_ for e in experts] == report["expert_rows"]
    assert all(len(e.relevance_) <= 20 for e in experts)


def test_the_variance_is_calibrated_on_the_validation_rows(trained):
    model, report, Xs, truth = trained
    predicted = predict_batch(model, Xs)
    z = wrap_deg(pose_angles(predicted) - pose_angles(truth))
    scale = model.variance_calibration * predict_variance(model, Xs)
    q = np.einsum("ni,ij,nj->n", z, np.linalg.inv(model.measurement_covariance), z) / 54
    assert np.mean(q / scale) == pytest.approx(1.0, rel=1e-6)
    assert report["variance_calibration"] == pytest.approx(model.variance_calibration, abs=1e-3)
    c, _ = calibrate_variance(predicted, truth, model.measurement_covariance,
                              predict_variance(model, Xs))
    assert c == pytest.approx(model.variance_calibration)


def test_the_trained_model_round_trips_with_its_variance(trained, tmp_path):
    model, _, Xs, _ = trained
    save_pose_model(tmp_path / "m.npz", model)
    loaded = load_pose_model(tmp_path / "m.npz")
    assert loaded.variance_calibration == model.variance_calibration
    np.testing.assert_allclose(predict_variance(loaded, Xs[:30]), predict_variance(model, Xs[:30]),
                               rtol=1e-2)


def test_dls_experts_are_still_trained_on_request():
    data, X, codebook, settings = _dataset()
    model, report = train_mixture_model(data, X, codebook, settings,
                                        replace(_options(), expert="dls"), 30.0,
                                        log=lambda m: None)
    assert not gives_variance(model) and model.variance_calibration is None
    assert "variance_calibration" not in report
    with pytest.raises(ValueError, match="expert"):
        train_mixture_model(data, X, codebook, settings, replace(_options(), expert="svm"),
                            30.0, log=lambda m: None)
