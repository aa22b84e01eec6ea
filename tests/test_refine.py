"""Rollout-aware refinement: exact sensitivities, and a stable model where least squares is not."""

from dataclasses import replace

import numpy as np
import pytest

from symrom.evaluate.metrics import evaluate_model
from symrom.learn.estimator import trajectories
from symrom.learn.plugins import regressor_from_dict
from symrom.learn.regressors.refine import Refine
from symrom.learn.regressors.stlsq import STLSQ
from symrom.learn.shooting import Parameters, cut_windows, simulate
from symrom.learn.training import TrainConfig, train
from symrom.rollout.integrate import RolloutOptions
from symrom.testing import make_lagged_dataset


@pytest.fixture(scope="module")
def lagged():
    # Stiff, lightly damped latents whose logged accelerations lag the motion by 20 ms (a causal
    # filter): least squares on them reads the lag as negative damping. Seven training jumps of
    # 0.8 s are enough for the refinement to recover the planted damping.
    return make_lagged_dataset(10, 400)


@pytest.fixture(scope="module")
def least_squares(lagged):
    """The least-squares model of the lagged data: the start of the refinements below."""
    return train(lagged[0], TrainConfig())


def test_sensitivities_match_finite_differences(planted_block):
    ds, _ = planted_block
    model = train(ds, TrainConfig())
    win = cut_windows(trajectories(ds, ds.rows_of("train"), model.autoencoder)[:3], 60)
    params = Parameters.of(model.mask)
    theta = params.vector(model.Xi)
    limit = np.full(4, 1e9)
    X, V, S, alive = simulate(model.library, model.Xi, params, win, ds.dt, limit, substeps=2)
    assert alive.all()
    rng = np.random.default_rng(0)
    for t in rng.choice(params.size, 5, replace=False):
        h = 1e-6 * max(1.0, abs(theta[t]))
        up, down = theta.copy(), theta.copy()
        up[t] += h
        down[t] -= h
        Xp, Vp, _, _ = simulate(model.library, params.matrix(up, model.Xi.shape), params, win, ds.dt, limit,
                                substeps=2, sensitivities=False)
        Xm, Vm, _, _ = simulate(model.library, params.matrix(down, model.Xi.shape), params, win, ds.dt, limit,
                                substeps=2, sensitivities=False)
        fd = np.concatenate([Xp - Xm, Vp - Vm], axis=2) / (2 * h)
        np.testing.assert_allclose(S[..., t], fd, rtol=1e-4, atol=1e-6 * np.abs(fd).max())


def test_coefficients_held_fixed_act_in_the_rollout(planted_block):
    """Parameters of one phase only, the other phase's coefficients held in Xi: the same rollout
    as with every coefficient a parameter, on both backends, and those parameters' columns of
    the sensitivities (what ``Refine(hold=...)`` fits with)."""
    ds, _ = planted_block
    model = train(ds, TrainConfig())
    win = cut_windows(trajectories(ds, ds.rows_of("train"), model.autoencoder)[:3], 120)
    assert len(set(np.unique(win.phase))) == 2  # the windows cross both phases
    limit = np.full(4, 1e9)
    every = Parameters.of(model.mask)
    Xi = model.Xi * model.mask
    contact = model.mask.copy()
    contact[model.phase_names.index("flight")] = False
    some = Parameters.of(contact)
    cols = np.flatnonzero(contact[model.mask])  # the contact entries among all active ones, C order
    for backend in ("table", "numpy"):
        X, V, S, _ = simulate(model.library, Xi, every, win, ds.dt, limit, stride=5, backend=backend)
        Xh, Vh, Sh, _ = simulate(model.library, Xi, some, win, ds.dt, limit, stride=5, backend=backend)
        np.testing.assert_allclose(Xh, X, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(Vh, V, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(Sh, S[..., cols], rtol=1e-10, atol=1e-10 * np.abs(S).max())
    with pytest.raises(ValueError, match="hold: no phase named"):
        Refine(hold=("air",)).fit(*_problem(ds, model))


def _problem(ds, model):
    """The regression problem of ``model``'s training rows, its rollouts over every third
    training jump (what the tests of the refinement's settings compare holds on any jumps),
    and ``model``'s coefficients."""
    from symrom.learn.estimator import phase_data
    from symrom.learn.regressors.base import Coefficients, RegressionProblem

    rows = ds.rows_of("train")
    phases = phase_data(ds, rows, model.autoencoder, model.library, 1.0, model.phase_names)
    trajs = trajectories(ds, rows, model.autoencoder)[::3]
    return RegressionProblem(model.library, list(model.phase_names), phases, np.ones(2), ds.dt, trajs), \
        Coefficients(model.Xi, model.mask)


def test_least_squares_on_lagged_accelerations_is_unstable(least_squares):
    assert max(s.max_real for s in least_squares.stability()) > 0.5  # /s: the lag reads as negative damping


def test_refinement_recovers_a_stable_accurate_model(lagged, least_squares):
    ds, truth = lagged
    ls = least_squares
    refined = train(ds, TrainConfig(refine=True))
    np.testing.assert_array_equal(refined.mask, ls.mask)  # the support is kept
    assert max(s.max_real for s in refined.stability()) < 0.2
    m_ls, _ = evaluate_model(ls, ds, "test", resets=(None,), options=RolloutOptions("rk4"))
    m_ref, _ = evaluate_model(refined, ds, "test", resets=(None,), options=RolloutOptions("rk4"))
    err = lambda m: np.mean([c.rmse for c in m.full.components.values()])  # noqa: E731
    assert m_ref.full.diverged_jumps == 0
    assert m_ls.full.diverged_jumps > 0 or err(m_ref) < 0.2 * err(m_ls)
    # Damping back near the planted values.
    names = refined.library.feature_names
    k = refined.phase_names.index("contact")
    damping = sorted(-refined.Xi[k, names.index(f"dxi{i}"), i - 1] for i in (1, 2))
    assert damping == pytest.approx([0.4, 0.6], abs=0.15)
    stages = refined.phase_info["contact"].report["refinement"]["stages"]
    assert stages[-1]["window_s"] is None and stages[-1]["cost_after"] < stages[-1]["cost_before"]


def test_short_weight_trades_the_whole_jump_for_the_short_windows(lagged, least_squares):
    """The stage of whole jumps scores the short windows short_weight times: its starting cost
    (the same start for both) grows by (weight - 1) times their cost, and the fit that weighs
    them more ends nearer the truth over them and farther over whole jumps."""
    ds, _ = lagged
    problem, init = _problem(ds, least_squares)
    fits = {w: Refine(windows=(0.05, None), short_weight=w).fit(problem, init) for w in (1.0, 30.0)}
    stages = {w: f.report["contact"]["refinement"]["stages"] for w, f in fits.items()}
    assert stages[1.0][0] == stages[30.0][0]  # the short windows alone: the weight changes nothing
    assert stages[30.0][1]["cost_before"] > stages[1.0][1]["cost_before"]
    from symrom.learn.plugins import regressor_from_dict

    weighted = Refine(short_weight=30.0, hold=("flight",))
    assert regressor_from_dict(weighted.to_dict()) == weighted  # the model file's record reads back
    assert "short_weight" not in Refine().to_dict()  # records of models refined before it stay as they were

    def costs(fit):
        """The cost of ``fit`` over the short windows and over whole jumps (a one-stage schedule's
        starting cost; one evaluation, so nothing is fitted)."""
        return tuple(Refine(windows=(w,), max_nfev=1).fit(problem, fit).report["contact"]["refinement"]
                     ["stages"][0]["cost_before"] for w in (0.05, None))

    (s1, w1), (s30, w30) = costs(fits[1.0]), costs(fits[30.0])
    assert s30 < s1 and w30 > w1


def test_polish_refits_one_phase_alone_after_the_schedule(lagged, least_squares):
    """``polish`` is the schedule's result with each named phase refined again alone: the other
    phases end as the schedule left them, the polished one as a held-phase refinement from there
    gives it, its short-window cost falls, and the support stays."""
    ds, _ = lagged
    problem, init = _problem(ds, least_squares)
    plain = Refine(windows=(0.05, None)).fit(problem, init)
    polished = Refine(windows=(0.05, None), polish=("flight",), polish_windows=(0.05, None),
                      polish_weight=50.0).fit(problem, init)
    alone = Refine(windows=(0.05, None), hold=("contact",), short_weight=50.0).fit(problem, plain)
    np.testing.assert_array_equal(polished.Xi[0], plain.Xi[0])  # contact: held while flight is polished
    np.testing.assert_allclose(polished.Xi[1], alone.Xi[1], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(polished.mask, plain.mask)
    assert not np.array_equal(polished.Xi[1], plain.Xi[1])
    stages = polished.report["flight"]["refinement"]["polish"]
    assert stages[0]["cost_after"] < stages[0]["cost_before"]
    assert "polish" not in polished.report["contact"]["refinement"]
    from symrom.learn.plugins import regressor_from_dict

    record = Refine(polish=("flight",), polish_windows=(0.1, None), polish_weight=10.0)
    assert regressor_from_dict(record.to_dict()) == record
    assert "polish" not in Refine().to_dict()
    with pytest.raises(ValueError, match="polish: no phase named"):
        Refine(polish=("air",)).fit(problem, init)


def test_refine_settings_are_checked():
    with pytest.raises(ValueError, match="velocity_weight"):
        Refine(STLSQ(), velocity_weight=0.0)
    with pytest.raises(ValueError, match="short_weight"):
        Refine(STLSQ(), short_weight=0.0)
    with pytest.raises(ValueError, match="window"):
        Refine(STLSQ(), windows=())
    with pytest.raises(ValueError, match="polish_weight"):
        Refine(STLSQ(), polish=("flight",), polish_weight=-1.0)
    with pytest.raises(ValueError, match="are held"):
        Refine(STLSQ(), polish=("flight",), hold=("flight",))
    with pytest.raises(ValueError, match="needs refine"):
        TrainConfig(polish=("flight",))


def test_budget_prunes_a_dense_model_to_the_planted_support(planted_axis):
    # Every term kept by least squares (threshold 0): 44 coefficients, 19 of them planted.
    # Pruned by rollout saliency to a budget of 19, the refinement must keep exactly the planted
    # terms (pruning by any other order, e.g. the largest first, would not) and their values.
    ds, truth = planted_axis
    planted = truth.Xi != 0
    est = TrainConfig(latent_dim=2, poly_order=1, threshold=0.0, refine=True,
                      max_terms=int(planted.sum())).estimator()
    assert est.regressor.after_pruning == "last"
    # Which terms the saliency keeps does not need the whole default schedule, every training
    # jump or small pruning steps: two stages on ten jumps, halving the terms a round, recover
    # the planted support as well.
    budget = replace(est.regressor, windows=(0.05, None), max_jumps=10, prune_share=0.5)
    # After each pruning the refinement goes on from the last stage it kept, not from the
    # shortest windows again; the whole schedule again finds the same support. The three fits
    # share one encoder and one fit of the contact guards.
    dense, pruned, again = est.fit_variants(ds, [budget.initial, budget,
                                                 replace(budget, after_pruning="schedule")])
    assert dense.mask.sum() > planted.sum() + 10
    np.testing.assert_array_equal(pruned.mask, planted)
    rel = np.abs(pruned.Xi[planted] - truth.Xi[planted]) / np.abs(truth.Xi[planted])
    assert rel.max() <= 0.05
    rounds = pruned.phase_info["contact"].report["refinement"]["prunings"]
    assert len(rounds) >= 2 and rounds[-1]["active_after"] == planted.sum()
    assert pruned.provenance.training.settings["max_terms"] == planted.sum()
    last = len(pruned.phase_info["contact"].report["refinement"]["stages"]) - 1
    assert all(len(r["stages"]) <= len(budget.windows) - last for r in rounds)
    np.testing.assert_array_equal(again.mask, planted)
    assert all(len(r["stages"]) > 1 for r in again.phase_info["contact"].report["refinement"]["prunings"])


def test_budget_settings_are_checked():
    with pytest.raises(ValueError, match="max_terms"):
        Refine(STLSQ(), max_terms=0)
    with pytest.raises(ValueError, match="prune_share"):
        Refine(STLSQ(), prune_share=0.0)
    with pytest.raises(ValueError, match="after_pruning"):
        Refine(STLSQ(), max_terms=5, after_pruning="twice")
    # a record from before the setting was pruned by the whole schedule again; without a budget
    # the setting is not recorded
    record = Refine(STLSQ(), max_terms=5).to_dict()
    assert record["after_pruning"] == "last" and "after_pruning" not in Refine(STLSQ()).to_dict()
    del record["after_pruning"]
    assert regressor_from_dict(record).after_pruning == "schedule"
    with pytest.raises(ValueError, match="needs refine"):
        TrainConfig(max_terms=10)


def test_keep_leaves_a_phase_whole_while_the_others_are_pruned(lagged, least_squares):
    """``keep``: the pruning holds the kept phase at the refinement's coefficients (bit for bit)
    and prunes the others until the whole model is within the budget; if the kept phase alone
    fills the budget, every phase is pruned as without ``keep``."""
    ds, _ = lagged
    problem, _ = _problem(ds, least_squares)
    init = STLSQ(threshold=0.0).fit(problem)  # every term
    n_flight, n = int(init.mask[1].sum()), int(init.mask.sum())
    assert 0 < n_flight < n - 3
    # What ``keep`` holds and prunes does not depend on how many terms go a round: halving
    # rounds keep the five fits cheap.
    settings = dict(windows=(0.05, None), prune_share=0.5)
    plain = Refine(**settings).fit(problem, init)
    budget = n_flight + 2
    kept = Refine(**settings, max_terms=budget, keep=("flight",)).fit(problem, init)
    assert kept.mask.sum() == budget and kept.mask[0].sum() == 2
    np.testing.assert_array_equal(kept.mask[1], plain.mask[1])
    np.testing.assert_array_equal(kept.Xi[1], plain.Xi[1])
    np.testing.assert_array_equal(kept.unpruned.Xi, plain.Xi)  # the refinement before the pruning
    assert len(kept.report["contact"]["refinement"]["prunings"]) > 1
    everything = Refine(**settings, max_terms=budget).fit(problem, init)
    assert everything.mask[1].sum() < n_flight  # without keep the flight is pruned too
    filled = Refine(**settings, max_terms=n_flight, keep=("flight",)).fit(problem, init)
    same = Refine(**settings, max_terms=n_flight).fit(problem, init)
    np.testing.assert_array_equal(filled.Xi, same.Xi)
    np.testing.assert_array_equal(filled.mask, same.mask)
    record = Refine(max_terms=5, keep=("flight",))
    assert regressor_from_dict(record.to_dict()) == record and "keep" not in Refine(max_terms=5).to_dict()
    with pytest.raises(ValueError, match="needs max_terms"):
        Refine(keep=("flight",))
    with pytest.raises(ValueError, match="are held"):
        Refine(max_terms=5, keep=("flight",), hold=("flight",))
    with pytest.raises(ValueError, match="keep: no phase named"):
        Refine(max_terms=5, keep=("air",)).fit(problem, init)
    with pytest.raises(ValueError, match="needs max_terms"):
        TrainConfig(refine=True, keep=("flight",))
