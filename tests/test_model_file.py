"""Model files: round trip, and refusal of altered, foreign or inconsistent files."""
import json

import numpy as np
import pytest

from regressor.model_file import FORMAT_VERSION, ModelFileError, load_model
from regressor.model_writer import save_model


def _parts(R=4, K=3, D=5, k=2):
    rng = np.random.default_rng(0)
    return dict(codebook_centres=rng.normal(size=(D, 7)), codebook_sigma=0.3,
                descriptor_n_bins=12, descriptor_mode="soft", stack_depth=k, transform="sqrt",
                basis="gaussian", width=1.5, centres=rng.normal(size=(R, k * D)),
                relevance=np.arange(R), coef=rng.normal(size=(R, K)), intercept=rng.normal(size=K),
                output_mean=np.zeros(K), output_std=np.ones(K),
                measurement_covariance=np.eye(K), process_noise=np.full(K, 0.1),
                description={"sequences": 7, "source": "synthetic"})


def _raw(path):
    with np.load(path, allow_pickle=False) as npz:
        return {k: npz[k] for k in npz.files}


def test_round_trip_keeps_every_part(tmp_path):
    parts = _parts()
    path = save_model(tmp_path / "m.npz", parts)
    m = load_model(path)
    assert m.format_version == FORMAT_VERSION and int(m["stack_depth"]) == 2 \
        and str(m["basis"]) == "gaussian"
    np.testing.assert_array_equal(m["coef"], parts["coef"])
    np.testing.assert_array_equal(m["centres"], parts["centres"])
    assert json.loads(str(m["description"])) == parts["description"] \
        and float(m["codebook_sigma"]) == 0.3
    assert str(m["descriptor_mode"]) == "soft"


def test_a_changed_array_is_refused_by_the_checksum(tmp_path):
    path = save_model(tmp_path / "m.npz", _parts())
    raw = _raw(path)
    raw["coef"] = raw["coef"].copy()
    raw["coef"].view(np.uint8)[3] ^= 0x01          # flip one bit of one weight
    np.savez(path, **raw)
    with pytest.raises(ModelFileError, match="checksum"):
        load_model(path)


def test_a_flipped_byte_in_the_file_is_refused(tmp_path):
    path = tmp_path / "m.npz"
    raw = dict(_parts(), description="{}")
    save_model(path, raw)
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))
    with pytest.raises(ModelFileError):
        load_model(path)


def test_an_unsupported_version_is_refused(tmp_path):
    path = save_model(tmp_path / "m.npz", _parts())
    raw = _raw(path)
    raw["format_version"] = np.int64(FORMAT_VERSION + 1)
    np.savez(path, **raw)
    with pytest.raises(ModelFileError, match="version"):
        load_model(path)


def test_a_dropped_part_is_refused(tmp_path):
    path = save_model(tmp_path / "m.npz", _parts())
    raw = _raw(path)
    del raw["intercept"]
    np.savez(path, **raw)
    with pytest.raises(ModelFileError, match="checksum"):
        load_model(path)
    del raw["checksum"]
    np.savez(path, **raw)
    with pytest.raises(ModelFileError, match="checksum"):
        load_model(path)


@pytest.mark.parametrize("change, problem", [
    (dict(intercept=np.zeros(5)), "intercept"),
    (dict(centres=np.zeros((2, 10))), "centres"),
    (dict(centres=np.zeros((4, 11))), "stack_depth"),
    (dict(coef=np.full((4, 3), np.nan)), "NaN"),
    (dict(basis="cubic"), "basis"),
    (dict(measurement_covariance=np.array([[1.0, 2.0, 0], [0, 1, 0], [0, 0, 1]])), "symmetric"),
    (dict(description="not json"), "JSON"),
    (dict(stack_depth=0), "stack_depth"),
])
def test_inconsistent_parts_are_refused_on_save(tmp_path, change, problem):
    with pytest.raises(ModelFileError, match=problem):
        save_model(tmp_path / "m.npz", {**_parts(), **change})


def test_missing_and_pickled_files_are_refused(tmp_path):
    with pytest.raises(ModelFileError, match="not found"):
        load_model(tmp_path / "absent.npz")
    path = tmp_path / "objects.npz"
    np.savez(path, format_version=np.int64(1), thing=np.array([{"a": 1}], dtype=object))
    with pytest.raises(ModelFileError):
        load_model(path)
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(ModelFileError, match="not a model file"):
        load_model(tmp_path / "junk.npz")


def test_a_text_file_is_not_a_model_file_rather_than_pickled_data(tmp_path):
    text = tmp_path / "notes.txt"
    text.write_text("a plain text file given as --model\n" * 20)
    with pytest.raises(ModelFileError, match="not a model file") as caught:
        load_model(text)
    assert "pickle" not in str(caught.value)


def test_checksum_error_says_it_catches_accidents_not_tampering(tmp_path):
    path = save_model(tmp_path / "m.npz", coef=np.ones((2, 3)), intercept=np.zeros(3))
    with np.load(path, allow_pickle=False) as npz:
        raw = {k: npz[k] for k in npz.files}
    raw["coef"] = raw["coef"] * 2
    np.savez(path, **raw)
    with pytest.raises(ModelFileError, match="not deliberate tampering"):
        load_model(path)
