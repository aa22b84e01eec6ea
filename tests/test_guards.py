"""Learned contact switching: a planted switching rule is recovered; guards round-trip and print."""

import json

import numpy as np
import pytest
from conftest import as_format

from symrom.learn.guards import fit_guards
from symrom.learn.training import TrainConfig, train
from symrom.model.guards import Guard, feature_names, first_switch, switch
from symrom.model.persistence import FORMAT_VERSION, ModelFileError, load_model, model_to_dict, save_model

DT = 0.002


def _stacked(jumps: list[np.ndarray]):
    """Jumps of rows (x, v, nu, phase) as z (N, 3), phase (N,) and bounds (J, 2)."""
    lengths = np.array([len(r) for r in jumps])
    ends = np.cumsum(lengths)
    rows = np.concatenate(jumps)
    return rows[:, :3], rows[:, 3].astype(int), np.c_[ends - lengths, ends]


def _planted_hops(n_jumps: int, seed: int):
    """Hops of a 1-latent ball (l = 1): z = [xi, dxi, nu]. Contact -> flight once the height
    reaches 0.30 m rising (after 20 ms in contact); flight -> contact when it falls to 0.25 m."""
    rng = np.random.default_rng(seed)
    jumps = []
    for _ in range(n_jumps):
        push = rng.uniform(14.0, 20.0)
        x, v, p, k_in, rows = 0.2, 0.0, 0, 0, []
        for _k in range(400):
            nu = push if p == 0 else 0.0
            if p == 0 and k_in * DT >= 0.02 and x >= 0.30:
                p, k_in = 1, 0
            elif p == 1 and x <= 0.25:
                p, k_in = 0, 0
            nu = push if p == 0 else 0.0
            rows.append((x, v, nu, p))
            a = nu - 9.81 - (8.0 * v if p == 0 else 0.0)
            x, v, k_in = x + DT * v, v + DT * a, k_in + 1
        jumps.append(np.array(rows))
    return _stacked(jumps)


def test_a_planted_switching_rule_is_recovered():
    Z, phase, bounds = _planted_hops(12, seed=0)
    assert len(np.unique(phase)) == 2 and (np.diff(phase) != 0).sum() >= 12
    guards = {(g.source, g.target): g for g in fit_guards(Z, phase, bounds[:8], bounds[8:],
                                                          ["contact", "flight"], DT)}
    lift, touch = guards[("contact", "flight")], guards[("flight", "contact")]
    assert lift.terms == ["xi1"] and touch.terms == ["xi1"]
    assert lift.weights[0] > 0 and abs(-lift.bias / lift.weights[0] - 0.30) < 0.01
    assert touch.weights[0] < 0 and abs(-touch.bias / touch.weights[0] - 0.25) < 0.01
    # timing on the validation jumps within a sample or two
    assert lift.report["val_loss_s"] <= 2 * DT and touch.report["val_loss_s"] <= 2 * DT
    assert "xi1 >= 0.3" in lift.text() and r"\xi_{1} \geq" in lift.text(latex=True)


def test_inputs_are_left_out_unless_asked():
    Z, phase, bounds = _planted_hops(8, seed=1)
    for g in fit_guards(Z, phase, bounds[:6], bounds[6:], ["contact", "flight"], DT):
        assert all(not t.startswith("nu") for t in g.terms)


def test_switching_respects_the_dwell_and_picks_the_largest_guard():
    names = ["contact", "partial", "flight"]
    a = Guard("contact", "partial", ["xi1"], [1.0], -1.0, min_dwell_s=0.01)
    b = Guard("contact", "flight", ["dxi1"], [1.0], -1.0, min_dwell_s=0.0)
    z = np.array([3.0, 2.0, 0.0])  # a: g = 2, b: g = 1
    assert switch([a, b], names, 0, 4, DT, z) == 2  # a still dwelling
    assert switch([a, b], names, 0, 5, DT, z) == 1  # both fire: the larger g
    Z = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [3.0, 0.0, 0.0]])
    assert first_switch([a], names, 0, -10, DT, Z, 0) == (2, 1)
    assert first_switch([a], names, 0, 0, DT, Z, 0) is None  # dwell not over by sample 2
    with pytest.raises(ValueError, match="term 'nu3'"):
        Guard("contact", "flight", ["nu3"], [1.0], 0.0, 0.0).value(np.zeros(3))
    assert feature_names(2) == ["xi1", "xi2", "dxi1", "dxi2", "nu1", "nu2"]


@pytest.fixture(scope="module")
def model(planted_block):
    ds, _ = planted_block
    return train(ds, TrainConfig(latent_dim=2))


def test_fit_learns_guards_that_round_trip_and_print(model, tmp_path):
    assert {(g.source, g.target) for g in model.guards} == {("contact", "flight"), ("flight", "contact")}
    path = tmp_path / "model.json"
    save_model(model, path)
    d = json.loads(path.read_text())
    assert d["format_version"] == FORMAT_VERSION and len(d["guards"]) == 2
    back = load_model(path)
    for g, h in zip(model.guards, back.guards):
        assert (g.source, g.target, g.terms, g.bias, g.min_dwell_s) == (h.source, h.target, h.terms, h.bias,
                                                                         h.min_dwell_s)
        np.testing.assert_array_equal(g.weights, h.weights)
    text = back.equations().text()
    assert "contact switches (guards):" in text and "contact -> flight: when" in text
    assert r"\mathrm{contact} \to \mathrm{flight}:\ " in back.equations().latex()


def test_older_files_load_without_guards_and_bad_guards_are_named(model, tmp_path):
    d = as_format(model_to_dict(model), 3)
    del d["guards"]
    path = tmp_path / "old.json"
    path.write_text(json.dumps(d))
    assert load_model(path).guards is None
    d = model_to_dict(model)
    d["guards"][1]["terms"] = ["speed"]
    path.write_text(json.dumps(d))
    with pytest.raises(ModelFileError, match="term 'speed'"):
        load_model(path)
    d = model_to_dict(model)
    del d["guards"][0]["bias"]
    path.write_text(json.dumps(d))
    with pytest.raises(ModelFileError, match=r"guards\[0\]: 'bias'"):
        load_model(path)


def _reference_losses(p, windows, levels, dt):
    """The timing loss as first written: a running maximum and a search per window."""
    total = np.zeros(levels.size)
    for a, end, e, kind in windows:
        r = np.maximum.accumulate(p[a:end])
        kf = np.searchsorted(r, levels, side="left")
        L = end - a
        if kind == 0:
            err = np.where(kf < L, np.abs(kf - e), max(L - e, 1))
        elif kind == 1:
            err = np.maximum(e - kf, 0)
        else:
            err = np.where(kf < L, L - kf, 0)
        total += err
    return total * dt / max(len(windows), 1)


def test_the_compiled_losses_equal_a_search_per_window_bit_for_bit():
    from symrom.learn.guards import _arrays, _grid, _losses, _windows, stays

    Z, phase, bounds = _planted_hops(10, seed=3)
    rng = np.random.default_rng(0)
    P = np.stack([Z[:, 0], -Z[:, 1], Z[:, :2] @ [0.3, -0.7], rng.standard_normal(len(Z))])
    P[2, 17] = np.nan  # a NaN reaches every level, as numpy's search treats it
    all_stays = stays(phase, bounds)
    for src, tgt in ((0, 1), (1, 0)):
        windows = _windows(all_stays, phase, src, tgt, 5)
        assert {kind for *_, kind in windows} >= {0, 2}
        levels, n = _grid(P, windows)
        loss = _losses(P, _arrays(windows), levels, n, DT)
        for f in range(len(P)):
            np.testing.assert_array_equal(loss[f, :n[f]], _reference_losses(P[f], windows, levels[f, :n[f]], DT))
            assert np.isinf(loss[f, n[f]:]).all()


def test_guards_refit_on_a_drifting_path_follow_its_drift():
    from symrom.learn.guards import guard_fit, refit_guards

    Z, phase, bounds = _planted_hops(12, seed=0)
    names = ["contact", "flight"]
    fit = guard_fit(Z, phase, bounds[:8], bounds[8:], names, DT)
    assert {g.target for g in fit.guards} == {"flight", "contact"}
    assert all(len(f) > 1 for f in fit.finalists.values())
    # a model's own path of the same jumps, its height 2 cm low throughout
    own = Z.copy()
    own[:, 0] -= 0.02
    refit = {(g.source, g.target): g for g in refit_guards(fit, own, phase, bounds[:8], bounds[8:], names, DT,
                                                           "a drifting path")}
    lift, touch = refit[("contact", "flight")], refit[("flight", "contact")]
    assert lift.terms == ["xi1"] and abs(-lift.bias / lift.weights[0] - 0.28) < 0.01
    assert touch.terms == ["xi1"] and abs(-touch.bias / touch.weights[0] - 0.23) < 0.01
    assert lift.report["refit_on"] == "a drifting path" and lift.report["refit_val_loss_s"] <= 2 * DT
    # the first fit's guards on that path miss by far more
    assert lift.report["first_fit_loss_s"] > 5 * lift.report["refit_val_loss_s"]
    # on the logged path itself the first fit stays
    same = refit_guards(fit, Z, phase, bounds[:8], bounds[8:], names, DT, "the logged path")
    assert [(g.terms, g.bias) for g in same] == [(g.terms, g.bias) for g in fit.guards]


def _planted_froggy(n_jumps: int, seed: int, push_s: float = 0.2):
    """Hops of a 1-latent body through contact (0), partial (1), flight (2) and a landing stay
    (3, the label ``free_path_guards`` gives a stay at another place of the sequence): the
    controller ends contact ``push_s`` (+ one sample for some jumps) after it began, whatever
    the state (its push and the start differ from jump to jump); lift-off when the height
    reaches 0.40 m rising, touchdown when it falls to 0.30 m."""
    rng = np.random.default_rng(seed)
    jumps = []
    for _ in range(n_jumps):
        push, extra = rng.uniform(13.0, 22.0), int(rng.integers(0, 2))
        x, v, p, k_in, rows = rng.uniform(0.1, 0.25), rng.uniform(-0.5, 0.5), 0, 0, []
        for _k in range(500):
            if p == 0 and k_in >= round(push_s / DT) + extra:
                p, k_in = 1, 0
            elif p == 1 and x >= 0.40 and v > 0:
                p, k_in = 2, 0
            elif p == 2 and x <= 0.30:
                p, k_in = 3, 0
            nu = push if p == 0 else 1.3 * push if p == 1 else 0.0
            rows.append((x, v, nu, p))
            a = nu - 9.81 - (8.0 * v if p in (0, 1) else 0.0) if p != 3 else -20.0 * v
            x, v, k_in = x + DT * v, v + DT * a, k_in + 1
        jumps.append(np.array(rows))
    return _stacked(jumps)


def test_a_switch_on_the_controllers_clock_is_learned_as_a_clock_and_a_state_switch_is_not():
    from symrom.learn.guards import CLOCK, GuardFit, clock, guard_fit, refit_guards

    Z, phase, bounds = _planted_froggy(14, seed=0)
    names = ["contact", "partial", "flight", "landing"]
    fit = guard_fit(Z, phase, bounds[:10], bounds[10:], names, DT)
    state = {(g.source, g.target): g for g in fit.guards}
    offered = GuardFit(fit.guards, {k: v + [CLOCK] for k, v in fit.finalists.items()})
    got = {(g.source, g.target): g for g in refit_guards(offered, Z, phase, bounds[:10], bounds[10:], names, DT,
                                                         "the logged path")}
    front = got[("contact", "partial")]
    assert front.clock and front.terms == [] and front.bias == 0.0
    assert abs(front.min_dwell_s - 0.2) <= DT + 1e-12
    assert front.report["refit_val_loss_s"] <= DT  # half the jumps switch a sample later
    assert front.report["first_fit_loss_s"] > 3 * front.report["refit_val_loss_s"]  # no state marks it
    assert front.text() == f"contact -> partial: after {front.min_dwell_s:.3g} s in contact"
    # lift-off and touchdown are the state's: the clock is offered there too and loses
    for pair in (("partial", "flight"), ("flight", "landing")):
        assert not got[pair].clock and got[pair].terms == state[pair].terms
    # the clock reads on past the logged switch (what the model would do had it stayed) and
    # starts again at the next stay in the source phase
    t = clock(np.array([0, 0, 1, 1, 0, 2]), np.array([[0, 6]]), DT, 0)
    np.testing.assert_allclose(t, np.array([0, 1, 2, 3, 0, 1]) * DT)


def test_a_clock_guard_switches_round_trips_and_is_refused_where_a_plan_needs_the_state(model, tmp_path):
    from dataclasses import replace

    from symrom.plan.guards import LearnedGuards

    names = ["contact", "partial", "flight"]
    tick = Guard("contact", "partial", [], [], 0.0, min_dwell_s=10 * DT)
    assert tick.clock and tick.indices(2).dtype == np.int64
    z = np.zeros(6)
    assert switch([tick], names, 0, 9, DT, z) == 0 and switch([tick], names, 0, 10, DT, z) == 1
    assert first_switch([tick], names, 0, -4, DT, np.zeros((20, 6)), 0) == (6, 1)
    with pytest.raises(ValueError, match="a clock .* has bias 0"):
        Guard("contact", "partial", [], [], 1.0, 0.1)
    lift = next(g for g in model.guards if g.target == "flight")
    clocked = replace(model, guards=[Guard(lift.source, lift.target, [], [], 0.0, 0.3) if g is lift else g
                                     for g in model.guards])
    save_model(clocked, tmp_path / "m.json")
    back = load_model(tmp_path / "m.json")
    assert [(g.terms, g.min_dwell_s) for g in back.guards] == [(g.terms, g.min_dwell_s) for g in clocked.guards]
    assert "contact -> flight: after 0.3 s in contact" in back.equations().text()
    with pytest.raises(ValueError, match="contact -> flight guard is a clock"):
        LearnedGuards.of(back)


def test_a_clock_counts_from_the_phase_start_in_a_prediction_started_inside_the_phase(model, planted_block):
    from dataclasses import replace

    ds, _ = planted_block
    a, b = ds.jump_bounds()[int(ds.jumps_in("test")[0])]
    clocked = replace(model, guards=[Guard("contact", "flight", [], [], 0.0, 0.2) if g.target == "flight" else g
                                     for g in model.guards])
    at = round(0.2 / ds.dt)
    whole = clocked.predict_path(ds.q[a], ds.dq[a], ds.u[a:b], ds.dt)
    assert whole.switches[0]["k"] == at and whole.switches[0]["target"] == "flight"
    k0 = 30  # started 30 samples into the contact phase: the clock has run that long
    late = clocked.predict_path(ds.q[a + k0], ds.dq[a + k0], ds.u[a + k0:b], ds.dt, dwell0=k0 * ds.dt)
    assert late.switches[0]["k"] == at - k0
    fresh = clocked.predict_path(ds.q[a + k0], ds.dq[a + k0], ds.u[a + k0:b], ds.dt)
    assert fresh.switches[0]["k"] == at
