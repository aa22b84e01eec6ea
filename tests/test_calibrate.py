"""Fine-tuning that calibrates (the default method): on a planted target domain whose contact
dynamics have a known input-gain error and extra damping, 12 jumps recover the gain and
leave the flight equations, gravity included, untouched. Calibration then a rollout
refinement of the contact phase (``calibrate_rollout``): on a planted target domain whose
stance spring differs, 12 jumps recover the spring, the flight equations untouched."""

import copy
from dataclasses import replace

import numpy as np
import pytest

from symrom.evaluate.metrics import evaluate_model
from symrom.experiments.finetune import FineTuneCheck, run_finetune
from symrom.learn.calibrate import CalibrationError
from symrom.learn.finetune import FineTuneConfig, finetune
from symrom.learn.training import TrainConfig, train
from symrom.names import GRAVITY, Q_NAMES
from symrom.rollout.integrate import RolloutOptions
from symrom.testing import PLANTED_2D, embedding_matrix, make_planted_dataset

SEED = 11
GAIN = 0.85  # the target's actuation relative to the source's
DAMPING = 0.3  # 1/s of extra damping on both latents in contact (joint damping)
SPRING = 0.5  # the target's stance spring of the height latent relative to the source's (a softer ground)
Z = Q_NAMES.index("z")

CALIBRATE = FineTuneConfig(method="calibrate")  # what these tests are about (the default refines too)


def _height_latent() -> int:
    """The latent that carries the base height in the planted embedding."""
    E, _ = embedding_matrix("block", 2, np.random.default_rng(SEED))
    return int(np.flatnonzero(E[Z])[0])


def _equations(flight_g: float = GRAVITY, gain: float = 1.0, damping: float = 0.0,
               spring: float = 1.0) -> dict:
    """The planted equations with a ballistic flight: the latent that carries the base height
    falls at ``flight_g`` m/s^2 once decoded; contact's input terms scaled by ``gain``, its
    velocity terms lowered by ``damping`` and the height latent's own position term (its
    stance spring) scaled by ``spring``."""
    E, _ = embedding_matrix("block", 2, np.random.default_rng(SEED))
    owner = _height_latent()
    eqs = copy.deepcopy(PLANTED_2D)
    eqs["flight"][owner] = {"1": -flight_g / E[Z, owner]}
    for j, eq in enumerate(eqs["contact"]):
        for term in [t for t in eq if t.startswith("nu")]:
            eq[term] *= gain
        eq[f"dxi{j + 1}"] -= damping
    eqs["contact"][owner][f"xi{owner + 1}"] *= spring
    return eqs


def _target(**kw):
    # 17 jumps: 12 train, 3 val, 2 test; the source's embedding
    return make_planted_dataset(17, 400, embedding="block", seed=SEED + 1, equations=_equations(**kw),
                                embedding_seed=SEED)[0]


@pytest.fixture(scope="module")
def source():
    ds, _ = make_planted_dataset(24, 400, embedding="block", seed=SEED, equations=_equations())
    return train(ds, TrainConfig())


@pytest.fixture(scope="module")
def target():
    return _target(gain=GAIN, damping=DAMPING)


def test_calibration_recovers_the_input_gain_and_keeps_flight(source, target):
    assert target.jumps_in("train").size == 12
    tuned = finetune(source, target, config=CALIBRATE)
    rec = tuned.provenance.finetune.to_dict()
    contact = rec["calibration"]["phases"]["contact"]
    np.testing.assert_allclose(contact["gain"], GAIN, rtol=0.02)
    np.testing.assert_allclose(contact["damping"], -DAMPING, rtol=0.1)
    f = source.phase_names.index("flight")
    np.testing.assert_array_equal(tuned.Xi[f], source.Xi[f])  # bit for bit
    np.testing.assert_array_equal(tuned.mask, source.mask)  # every support kept
    np.testing.assert_array_equal(tuned.autoencoder.W_e, source.autoencoder.W_e)
    assert not rec["calibration"]["flight_test"]["contradicted"]
    assert rec["phases_refit"] == ["contact"]
    fg = rec["flight_gravity"]
    assert abs(fg["model"] / -GRAVITY - 1) < 0.05 and fg["ratio"] == pytest.approx(1.0, abs=0.05)
    # The calibrated contact equations are the source's with the inputs scaled and damping added.
    k = source.phase_names.index("contact")
    names = source.library.feature_names
    inputs = np.array(["nu" in n for n in names])
    for j in range(source.latent_dim):
        np.testing.assert_allclose(tuned.Xi[k, inputs, j], contact["gain"][j] * source.Xi[k, inputs, j])


def test_calibration_follows_data_that_contradict_the_flight_gravity(source):
    low = _target(flight_g=0.8 * GRAVITY)  # the data fall at 7.8 m/s^2, clearly not g
    tuned = finetune(source, low, config=CALIBRATE)
    rec = tuned.provenance.finetune.to_dict()
    test = rec["calibration"]["flight_test"]
    assert test["contradicted"] and test["mean"] == pytest.approx(0.2 * GRAVITY, rel=0.05)
    assert rec["calibration"]["phases"]["flight"]["calibrated"]
    assert rec["flight_gravity"]["model"] == pytest.approx(-0.8 * GRAVITY, rel=0.02)


def test_the_val_check_applies_to_calibration(source, target):
    res = run_finetune(source, target, FineTuneCheck(config=CALIBRATE))
    a = res.attempts[-1]
    assert a["accepted"] and a["score"] < a["score_before"]  # the gain error made the source worse
    record = res.to_dict()
    assert record["flight_gravity"]["ratio"] == pytest.approx(1.0, abs=0.05)
    assert record["calibration"]["phases"]["contact"]["calibrated"]


def test_a_first_attempt_passed_in_is_not_fitted_again_and_changes_nothing(source, target, monkeypatch):
    import symrom.experiments.finetune as ft

    check = FineTuneCheck(config=CALIBRATE)
    fresh = run_finetune(source, target, check)
    first = finetune(source, target, config=check.config)
    calls = []
    monkeypatch.setattr(ft, "finetune", lambda *a, **k: calls.append(1) or finetune(*a, **k))
    given = run_finetune(source, target, check, first=first)
    assert calls == [] and given.attempts == fresh.attempts  # accepted at the first weight, fitted once
    np.testing.assert_array_equal(given.model.Xi, fresh.model.Xi)
    np.testing.assert_array_equal(given.model.autoencoder.W_d, fresh.model.autoencoder.W_d)
    with pytest.raises(ValueError, match="prior_weight"):  # another fit is refused, naming what differs
        run_finetune(source, target, FineTuneCheck(config=replace(CALIBRATE, prior_weight=0.5)), first=first)
    with pytest.raises(ValueError, match="not a fine-tuning"):
        run_finetune(source, target, check, first=source)


def test_nothing_to_calibrate_is_refused_naming_what_would_work(source, target):
    names = source.library.feature_names
    drop = np.array([n == "1" or "nu" in n or n.startswith("dxi") for n in names])
    mask = source.mask.copy()
    mask[:, drop] = False
    bare = replace(source, mask=mask, Xi=np.where(mask, source.Xi, 0.0))
    with pytest.raises(CalibrationError, match="method='acceleration'"):
        finetune(bare, target, config=FineTuneConfig(method="calibrate", refit_decoder=False,
                                                     calibration_terms="support"))
    # by default an offset and a damping are calibration terms of every contact equation
    tuned = finetune(bare, target, config=FineTuneConfig(method="calibrate", refit_decoder=False))
    assert tuned.provenance.finetune.calibration["parameters"] == 2 * source.latent_dim
    with pytest.raises(ValueError, match="calibrate"):
        FineTuneConfig(threshold=0.1)


def test_every_equation_calibrated_recovers_a_planted_bias_and_damping(source, target):
    """A source whose contact equations lack their constant and their own velocity term (a
    torque bias and joint damping of the target domain the source never had): the default
    (``calibration_terms="every"``) adds both as calibration terms and recovers them (the
    full source's, calibrated), the gain still within 2 %; ``support`` cannot; neither touches
    the flight equations."""
    names = source.library.feature_names
    k, f = source.phase_names.index("contact"), source.phase_names.index("flight")
    one, vel = names.index("1"), [names.index(f"dxi{j + 1}") for j in range(source.latent_dim)]
    assert source.mask[k, one].all() and all(source.mask[k, v, j] for j, v in enumerate(vel))
    mask = source.mask.copy()
    mask[k, one] = False
    for j, v in enumerate(vel):
        mask[k, v, j] = False
    bare = replace(source, mask=mask, Xi=np.where(mask, source.Xi, 0.0))
    full = finetune(source, target, config=CALIBRATE)  # the reference: the full source, calibrated
    every = finetune(bare, target, config=CALIBRATE)
    rec = every.provenance.finetune.to_dict()["calibration"]
    contact = rec["phases"]["contact"]
    assert rec["terms"] == "every" and contact["offset_added"] == [True, True] == contact["damping_added"]
    np.testing.assert_array_equal(every.mask, source.mask)  # the terms back, nothing else
    np.testing.assert_array_equal(every.Xi[f], source.Xi[f])
    np.testing.assert_allclose(contact["gain"], GAIN, rtol=0.02)
    # the recovered constants, decoded to accelerations of q (m/s^2, rad/s^2), and dampings (1/s)
    planted = full.autoencoder.W_d @ full.Xi[k, one]
    np.testing.assert_allclose(every.autoencoder.W_d @ every.Xi[k, one], planted,
                               atol=0.03 * np.abs(planted).max())
    for j, v in enumerate(vel):
        assert every.Xi[k, v, j] == pytest.approx(full.Xi[k, v, j], rel=0.05)
    support = finetune(bare, target, config=FineTuneConfig(method="calibrate", calibration_terms="support"))
    srec = support.provenance.finetune.to_dict()["calibration"]["phases"]["contact"]
    assert srec["offset"] == [None, None] == srec["damping"] and srec["offset_added"] == [False, False]
    np.testing.assert_array_equal(support.mask, bare.mask)
    with pytest.raises(ValueError, match="calibration_terms"):
        FineTuneConfig(calibration_terms="all")


def test_calibrate_rollout_recovers_a_stance_spring_and_keeps_flight(source):
    """A target domain whose stance spring on the height latent is half the source's: no input
    gain, offset or damping expresses it, so calibration keeps the source's spring and its
    rollouts miss the height; ``calibrate_rollout`` refines the contact equations on rollouts of
    the 12 train jumps from the calibrated start, recovers the spring within 2 %, and leaves the
    flight equations bit for bit as calibration left them (gravity kept by construction)."""
    from symrom.learn.plugins import regressor_from_dict

    soft = _target(spring=SPRING)
    owner = _height_latent()
    names = source.library.feature_names
    k, f = source.phase_names.index("contact"), source.phase_names.index("flight")
    spring = names.index(f"xi{owner + 1}")
    planted = PLANTED_2D["contact"][owner][f"xi{owner + 1}"]
    assert source.Xi[k, spring, owner] == pytest.approx(planted, rel=0.01)
    cal = finetune(source, soft, config=CALIBRATE)
    assert FineTuneConfig().method == "calibrate_rollout"  # the default
    tuned = finetune(source, soft)
    assert cal.Xi[k, spring, owner] == source.Xi[k, spring, owner]  # calibration cannot move it
    assert tuned.Xi[k, spring, owner] == pytest.approx(SPRING * planted, rel=0.02)
    np.testing.assert_array_equal(tuned.Xi[f], source.Xi[f])  # bit for bit
    np.testing.assert_array_equal(tuned.Xi[f], cal.Xi[f])
    np.testing.assert_array_equal(tuned.mask, cal.mask)  # the calibrated support, nothing added
    np.testing.assert_array_equal(tuned.autoencoder.W_d, cal.autoencoder.W_d)
    rec = tuned.provenance.finetune.to_dict()
    assert rec["phases_rolled_out"] == ["contact"] and cal.provenance.finetune.phases_rolled_out == ()
    assert regressor_from_dict(rec["regressor"]).hold == ("flight",)
    assert rec["calibration"]["phases"]["contact"]["calibrated"]  # the refinement's start
    assert rec["flight_gravity"]["ratio"] == pytest.approx(1.0, abs=0.05)
    z_cal, z_tuned = (evaluate_model(m, soft, "test", (None,), RolloutOptions(method="rk4"))[0].rmse("z")
                      for m in (cal, tuned))
    assert z_tuned < 0.1 * z_cal
    with pytest.raises(ValueError, match="threshold"):
        FineTuneConfig(method="calibrate_rollout", threshold=0.1)
