"""The front/back chain's priors a model carries (regressor.canonical_priors): the file parts,
their checks, learning them, and the tracker reading a model's own rather than the shipped
model's."""
from __future__ import annotations

import numpy as np
import pytest

from regressor.canonical_priors import CanonicalPriors
from regressor.model_writer import canonical_priors_arrays
from tracker.tracks.hypotheses import (CANONICAL_FRONT_EDGES, DEFAULT_CANONICAL_PRIORS,
                                canonical_hypotheses, canonical_priors, chain_options)
from test_side_classifier import _body, _classifier


def _priors(**changes) -> CanonicalPriors:
    values = dict(switch=(0.01, 0.02), front_edges=(0.0, 0.5), by_front=(0.2, 0.9),
                  overall=0.55)
    values.update(changes)
    return CanonicalPriors(**values)


def test_the_priors_survive_the_file_parts_round_trip():
    priors = _priors()
    parts = canonical_priors_arrays(priors)
    assert all(k.startswith("canonical_prior_") and v.dtype == np.float64
               for k, v in parts.items())
    assert CanonicalPriors.from_arrays(parts) == priors
    assert CanonicalPriors.from_arrays({"other": np.zeros(1)}) is None


def test_a_file_with_the_parts_of_removed_mechanisms_still_loads_without_them():
    """Model files written before the raw-side table was removed carry
    canonical_prior_raw_side_*: read as if they were not there; not written any more."""
    removed = {"canonical_prior_raw_side_edges": np.array([0.0, 0.5]),
               "canonical_prior_raw_side_by_norm": np.array([0.5, 0.7]),
               "canonical_prior_raw_side_overall": np.float64(0.6)}
    parts = {**canonical_priors_arrays(_priors()), **removed}
    assert CanonicalPriors.from_arrays(parts) == _priors()
    assert not set(removed) & set(canonical_priors_arrays(_priors()))


@pytest.mark.parametrize("change, message", [
    ({"switch": (0.1, 1.0)}, "switch must be two probabilities"),
    ({"switch": (0.0, 0.04)}, "switch must be two probabilities"),
    ({"switch": (0.1,)}, "switch must be two probabilities"),
    ({"front_edges": (0.0, 5.0)}, "must stay below 1"),
    ({"by_front": (0.5,)}, "one value per edge"),
    ({"front_edges": (0.1, 0.5)}, "edges must increase from 0"),
    ({"front_edges": (0.0, 0.0)}, "edges must increase from 0"),
    ({"by_front": (0.2, 1.5)}, "must hold probabilities"),
    ({"overall": 1.0}, "strictly between 0 and 1"),
    ({"overall": 0.0}, "strictly between 0 and 1"),
    ({"by_front": (np.nan, 0.5)}, "non-finite"),
])
def test_inconsistent_priors_are_refused_with_a_named_problem(change, message):
    with pytest.raises(ValueError, match=message):
        _priors(**change)
    # and the same from a file's parts
    parts = {**canonical_priors_arrays(_priors()),
             **{f"canonical_prior_{k}": np.asarray(v, dtype=np.float64)
                for k, v in change.items()}}
    with pytest.raises(ValueError, match=message):
        CanonicalPriors.from_arrays(parts)


@pytest.mark.parametrize("tamper, message", [
    (lambda p: p.pop("canonical_prior_overall"), "incomplete"),
    (lambda p: p.update(canonical_prior_extra=np.zeros(2)), "unknown part"),
    (lambda p: p.update(canonical_prior_switch=np.array([0, 0], np.int64)), "must hold floats"),
    (lambda p: p.update(canonical_prior_overall=np.array([0.5, 0.5])), "has shape"),
    (lambda p: p.update(canonical_prior_by_front=np.float64(0.5)), "has shape"),
])
def test_tampered_parts_are_refused(tamper, message):
    parts = canonical_priors_arrays(_priors())
    tamper(parts)
    with pytest.raises(ValueError, match=message):
        CanonicalPriors.from_arrays(parts)


def test_learned_statistics_become_priors_with_empty_bins_taking_the_overall_rate():
    from lab.hypothesis_priors import priors_from_statistics
    stats = {"switch_probability": [0.03, 0.0], "by_front": [0.3, None, 0.5, 0.6, 0.7, 0.8],
             "canonical_overall": 0.62}
    priors = priors_from_statistics(stats, CANONICAL_FRONT_EDGES)
    assert priors.switch == (0.03, 0.001)            # a state never left stays reachable
    assert priors.by_front[1] == pytest.approx(0.62) and priors.overall == pytest.approx(0.62)
    always = priors_from_statistics({"switch_probability": [0.03, 0.04],
                                     "by_front": [1.0] * 6, "canonical_overall": 1.0},
                                    CANONICAL_FRONT_EDGES)
    assert always.overall == pytest.approx(0.999)          # never certain


def test_the_shipped_tables_are_the_default_priors():
    assert DEFAULT_CANONICAL_PRIORS.switch == (0.025, 0.041)
    assert DEFAULT_CANONICAL_PRIORS.front_edges == CANONICAL_FRONT_EDGES


def test_the_chain_weighs_a_pair_by_the_priors_it_is_given():
    """A classifier that is right only half the time at a given probability carries no
    evidence; one right 9 times in 10 there does."""
    member, raw = _body(20.0), _body(20.0, seed=3)
    blind = _priors(by_front=(0.55, 0.55))
    sure = _priors(by_front=(0.1, 0.9))
    e_blind = canonical_hypotheses(raw, member, 0.97, blind).log_evidence
    e_sure = canonical_hypotheses(raw, member, 0.97, sure).log_evidence
    assert e_blind[0] - e_blind[1] == pytest.approx(0.0, abs=1e-9)
    assert e_sure[0] - e_sure[1] == pytest.approx(np.log(0.9 / 0.55) - np.log(0.1 / 0.45))
    # the default is the shipped model's
    np.testing.assert_allclose(canonical_hypotheses(raw, member, 0.97).log_evidence,
                               canonical_hypotheses(raw, member, 0.97,
                                                    DEFAULT_CANONICAL_PRIORS).log_evidence)


def test_the_tracker_takes_a_models_own_priors_else_the_default():
    class Model:
        gives_canonical_pairs, training_fps = True, 30.0
        canonical_priors = None

    model = Model()
    assert canonical_priors(model) is DEFAULT_CANONICAL_PRIORS
    assert chain_options(model)["switch"] == DEFAULT_CANONICAL_PRIORS.switch
    model.canonical_priors = _priors()
    assert canonical_priors(model) is model.canonical_priors
    assert chain_options(model)["switch"] == (0.01, 0.02)


def test_a_mixture_model_saves_and_loads_its_priors_and_its_pairs_use_them(tmp_path):
    pytest.importorskip("sklearn")
    from test_mixture import _mixture_model, assert_refused_when_changed
    from regressor.angles import wrap_deg
    from regressor.limb_net_training import fit_limb_net
    from regressor.model_file import load_model
    from regressor.pose_model import PoseModelError, load_pose_model
    from regressor.model_writer import save_pose_model
    from tracker.tracks.proposals import propose_batch
    model, x = _mixture_model()
    rng = np.random.default_rng(3)
    targets = np.column_stack([np.ones(len(x)), np.zeros(len(x)),
                               wrap_deg(40 * np.tanh(x[:, :1]) + rng.normal(0, 1, (len(x), 53)))])
    model.limb_net = fit_limb_net(x, targets, np.zeros(53), np.eye(55)[0], members=1,
                                  hidden=(8,), max_iter=20)
    model.canonical_priors = _priors()
    with pytest.raises(PoseModelError, match="need the model's side classifier"):
        save_pose_model(tmp_path / "noclf.npz", model)
    model.side_classifier = _classifier(P=8)
    path = tmp_path / "priors.npz"
    save_pose_model(path, model)
    loaded = load_pose_model(path)
    assert loaded.canonical_priors == model.canonical_priors
    # the loaded model's hypotheses are weighed by its own priors, not the default
    hyps = propose_batch(loaded, x[:3])
    for h in hyps:
        again = canonical_hypotheses(h.raw, h.limbs, h.front, model.canonical_priors)
        np.testing.assert_allclose(h.log_evidence, again.log_evidence)
    assert chain_options(loaded)["switch"] == (0.01, 0.02)
    # priors without the classifier, or broken, are refused on load
    side_parts = [k for k in load_model(path).parts if k.startswith("side_net_")]
    assert_refused_when_changed(path, [
        (dict.fromkeys(side_parts), "need a side classifier"),
        ({"canonical_prior_by_front": np.array([0.5, 2.0])}, "must hold probabilities")])


def test_only_a_mixture_carries_canonical_priors(tmp_path):
    from test_mixture import assert_only_a_mixture_carries
    priors = _priors()
    assert_only_a_mixture_carries(tmp_path, "canonical_priors", priors,
                                  canonical_priors_arrays(priors))


@pytest.mark.slow
def test_learn_hypothesis_priors_never_saves_over_a_model(tmp_path):
    """--save refuses the model it reads and any existing file, with a one-line usage error
    before any learning."""
    import subprocess
    import sys
    from pathlib import Path
    script = Path(__file__).resolve().parents[1] / "scripts" / "learn_hypothesis_priors.py"
    model = tmp_path / "model.npz"
    model.write_bytes(b"not read")
    same = tmp_path / "." / "model.npz"                    # the same file, spelled otherwise
    for save in (model, same):
        out = subprocess.run([sys.executable, str(script), "--model", str(model), "--save",
                              str(save)], capture_output=True, text=True, timeout=60)
        assert out.returncode == 2 and "would overwrite the model" in out.stderr
        assert "Traceback" not in out.stderr
    other = tmp_path / "other.npz"
    other.write_bytes(b"kept")
    out = subprocess.run([sys.executable, str(script), "--model", str(model), "--save",
                          str(other)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and "exists" in out.stderr and other.read_bytes() == b"kept"
    assert model.read_bytes() == b"not read"


def test_learn_hypothesis_priors_saves_a_copy_with_the_learned_priors(tmp_path, monkeypatch,
                                                                      capsys):
    """--save writes a new model file carrying the priors it learned; the model it read is
    unchanged. (The learning itself is replaced by a stand-in: it renders 28 sequences.)"""
    from conftest import load_script
    from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
    module = load_script("learn_hypothesis_priors")
    cmu = tmp_path / "cmu"
    cmu.mkdir()
    learned = _priors()
    out = tmp_path / "with_priors.npz"
    # the regressor's steps need the validation trials: refused up front, nothing written
    with pytest.raises(SystemExit) as exit_info:
        module.main(["--cmu", str(cmu), "--save", str(out)])
    assert exit_info.value.code == 2 and "02_02.bvh not found" in capsys.readouterr().err
    assert not out.exists()
    for stem in ("02_02", "08_03", "05_02", "06_10", "09_04", "02_05", "07_12"):
        (cmu / f"{stem}.bvh").write_text("")
    monkeypatch.setattr(module, "regressor_flip_statistics", lambda model, files: {})
    monkeypatch.setattr(module, "learn_canonical_priors", lambda model, files: (learned, {}))
    before = DEFAULT_MODEL_PATH.read_bytes()
    assert module.main(["--cmu", str(cmu), "--save", str(out)]) == 0
    assert load_pose_model(out).canonical_priors == learned
    assert DEFAULT_MODEL_PATH.read_bytes() == before
    # and never over an existing file
    with pytest.raises(SystemExit):
        module.main(["--cmu", str(cmu), "--save", str(out)])
    assert load_pose_model(out).canonical_priors == learned
