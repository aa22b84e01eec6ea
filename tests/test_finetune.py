"""Fine-tuning on a few jumps of a perturbed system (the sim-to-real step)."""

import copy

import numpy as np
import pytest

import symrom
from symrom.evaluate.metrics import evaluate_model
from symrom.learn.finetune import FineTuneConfig, finetune
from symrom.learn.training import TrainConfig, train
from symrom.rollout.integrate import RolloutOptions
from symrom.testing import PLANTED_2D, make_planted_dataset


@pytest.fixture(scope="module")
def source_data():
    return make_planted_dataset(24, 400, embedding="block", seed=5)[0]


@pytest.fixture(scope="module")
def source_and_target(source_data):
    source = source_data
    shifted = copy.deepcopy(PLANTED_2D)
    shifted["contact"][0]["xi1"] = -7.0   # a stiffer leg
    shifted["contact"][1]["nu2"] = 2.0    # weaker actuation
    shifted["flight"][1]["dxi2"] = -0.6   # more drag
    target, truth = make_planted_dataset(6, 400, embedding="block", seed=6, equations=shifted,
                                         embedding_seed=5, noise=3e-3)
    return train(source, TrainConfig()), target, truth


def _full_rmse(model, ds):
    m, _ = evaluate_model(model, ds, "test", resets=(None,), options=RolloutOptions(method="rk4"))
    return np.mean([c.rmse for c in m.full.components.values()])


def test_finetuning_moves_towards_the_new_system(source_and_target):
    model, target, truth = source_and_target
    tuned = finetune(model, target, config=FineTuneConfig(method="acceleration"))
    np.testing.assert_array_equal(tuned.autoencoder.W_e, model.autoencoder.W_e)
    assert _full_rmse(tuned, target) < 0.5 * _full_rmse(model, target)
    names = tuned.library.feature_names
    k = tuned.phase_names.index("contact")
    assert tuned.Xi[k, names.index("xi1"), 0] == pytest.approx(-7.0, rel=0.05)
    assert tuned.provenance.finetune.source == target.source


def test_prior_weight_interpolates(source_and_target):
    model, target, _ = source_and_target
    stiff = finetune(model, target, config=FineTuneConfig(prior_weight=1e6, method="acceleration"))
    np.testing.assert_allclose(stiff.Xi, model.Xi, atol=1e-3)
    free = finetune(model, target, config=FineTuneConfig(prior_weight=0.0, method="acceleration"))
    names = free.library.feature_names
    assert free.Xi[0, names.index("xi1"), 0] == pytest.approx(-7.0, rel=0.05)
    with pytest.raises(ValueError, match="no fine-tuning rows"):
        finetune(model, target, rows=np.zeros(target.n_samples, bool))


def test_rollout_finetuning_moves_towards_the_new_system(source_and_target):
    model, target, _ = source_and_target
    tuned = finetune(model, target, config=FineTuneConfig(method="rollout"))
    assert tuned.provenance.finetune.config["method"] == "rollout"
    np.testing.assert_array_equal(tuned.mask, model.mask)  # the rollout fit keeps the support
    # Both fine-tunings reach the target's 3 mm noise floor (the source errs by twice that).
    assert _full_rmse(tuned, target) < 0.55 * _full_rmse(model, target)
    assert _full_rmse(tuned, target) < 1.1 * _full_rmse(finetune(model, target), target)
    k = tuned.phase_names.index("contact")
    assert tuned.Xi[k, tuned.library.feature_names.index("xi1"), 0] == pytest.approx(-7.0, rel=0.1)


def test_rollout_finetuning_keeps_the_phases_the_rows_lack(source_and_target):
    model, target, _ = source_and_target
    k = target.phase_names.index("flight")
    rows = target.rows_of("train") & (target.phase == k)
    tuned = finetune(model, target, rows=rows, config=FineTuneConfig(method="rollout", refit_decoder=False))
    c = model.phase_names.index("contact")
    np.testing.assert_array_equal(tuned.Xi[c], model.Xi[c])
    assert tuned.provenance.finetune.phases_kept == ("contact",)
    assert not np.array_equal(tuned.Xi[model.phase_names.index("flight")], model.Xi[model.phase_names.index("flight")])


def test_unknown_finetuning_method_is_refused():
    with pytest.raises(ValueError, match="fine-tuning method"):
        FineTuneConfig(method="gradient")


def test_a_model_fitted_by_the_estimator_is_finetuned_with_its_own_sparsity(source_data, source_and_target):
    """The threshold, measure and ridge of fine-tuning come from the source's regressor as
    its model file records it, however it was fitted (not only through ``train``)."""
    _, target, _ = source_and_target
    rom = symrom.SymbolicROM(regressor=symrom.STLSQ(threshold=0.05, measure="explained")).fit(source_data)
    trained = train(source_data, TrainConfig(threshold=0.05, measure="explained"))
    np.testing.assert_array_equal(rom.model.Xi, trained.Xi)  # the same source, fitted two ways
    acc = FineTuneConfig(method="acceleration")
    a, b = finetune(rom.model, target, config=acc), finetune(trained, target, config=acc)
    np.testing.assert_array_equal(a.mask, b.mask)
    np.testing.assert_allclose(a.Xi, b.Xi, atol=1e-12)
    used = a.provenance.finetune.regressor
    assert (used["kind"], used["threshold"], used["measure"]) == ("finetune", 0.05, "explained")


def test_a_model_without_a_recorded_regressor_is_refused(source_and_target):
    from dataclasses import replace

    from symrom.model.hybrid import ModelDataError

    model, target, _ = source_and_target
    bare = replace(model, estimator={})
    with pytest.raises(ModelDataError, match="estimator.regressor: the model records no regressor"):
        finetune(bare, target, config=FineTuneConfig(method="acceleration"))
