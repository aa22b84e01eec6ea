"""Free prediction: predict_path on the logged schedule is the rollout; guards decide phases."""

import numpy as np
import pytest

from symrom.learn.estimator import SymbolicROM
from symrom.learn.training import TrainConfig, train
from symrom.model.path import NoGuardsError
from symrom.rollout.integrate import RolloutOptions, rollout


@pytest.fixture(scope="module")
def fitted(planted_block):
    ds, _ = planted_block
    model = train(ds, TrainConfig(latent_dim=2, poly_order=2))  # trig, monomials and inputs
    return model, ds, int(ds.jumps_in("test")[0])


@pytest.mark.parametrize("backend", ["table", "numpy", "generated"])
def test_the_logged_schedule_reproduces_the_rollout(fitted, backend):
    model, ds, j = fitted
    a, b = ds.jump_bounds()[j]
    opts = RolloutOptions(method="rk4", backend=backend)
    ro = rollout(model, ds, [j], opts)
    names = [ds.phase_names[k] for k in ds.phase[a:b]]
    p = model.predict_path(ds.q[a], ds.dq[a], ds.u[a:b], ds.dt, phases=names, options=opts)
    np.testing.assert_allclose(p.q, ro.q_pred[0], atol=1e-9, rtol=0)
    np.testing.assert_allclose(p.xi, ro.xi[0], atol=1e-9, rtol=0)
    assert p.phase_labels == names and p.diverged_at == -1
    assert [s["k"] for s in p.switches] == list(np.flatnonzero(np.diff(ds.phase[a:b])) + 1)


def test_a_callable_input_gives_the_same_path(fitted):
    model, ds, j = fitted
    a, b = ds.jump_bounds()[j]
    seen = []

    def inputs(t, state):
        seen.append((t, state.phase, state.q.shape))
        return ds.u[a + state.k]

    ph = model.phase_index(ds)[a:b]
    arr = model.predict_path(ds.q[a], ds.dq[a], ds.u[a:b], ds.dt, phases=ph)
    fn = model.predict_path(ds.q[a], ds.dq[a], inputs, ds.dt, phases=ph, n=b - a)
    np.testing.assert_allclose(fn.q, arr.q, atol=1e-9, rtol=0)
    np.testing.assert_allclose(fn.dq, arr.dq, atol=1e-9, rtol=0)
    assert len(seen) == b - a and seen[1][0] == pytest.approx(ds.dt) and seen[0][2] == (18,)


def test_guards_decide_the_phases_alike_for_arrays_and_callables(fitted):
    model, ds, j = fitted
    a, b = ds.jump_bounds()[j]
    arr = model.predict_path(ds.q[a], ds.dq[a], ds.u[a:b], ds.dt)
    fn = model.predict_path(ds.q[a], ds.dq[a], lambda t, s: ds.u[a + s.k], ds.dt, n=b - a)
    assert arr.switches == fn.switches
    np.testing.assert_allclose(fn.q, arr.q, atol=1e-9, rtol=0)
    # each switch is where its guard first fires after the dwell, on the predicted path
    for s in arr.switches:
        g = next(g for g in model.guards if (g.source, g.target) == (s["source"], s["target"]))
        z = np.r_[arr.xi[s["k"]], arr.dxi[s["k"]], model.autoencoder.encode_input(ds.u[a + s["k"]][None])[0]]
        assert g.value(z) >= 0
    # the same path as the schedule it predicted
    again = model.predict_path(ds.q[a], ds.dq[a], ds.u[a:b], ds.dt, phases=arr.phase)
    np.testing.assert_array_equal(again.q, arr.q)


def test_estimator_predict_path_and_errors(planted_block, fitted):
    model, ds, j = fitted
    a, b = ds.jump_bounds()[j]
    rom = SymbolicROM(latent_dim=2)
    rom.model_ = model
    np.testing.assert_array_equal(rom.predict_path(ds.q[a], ds.dq[a], ds.u[a:b], ds.dt).q,
                                  model.predict_path(ds.q[a], ds.dq[a], ds.u[a:b], ds.dt).q)
    with pytest.raises(ValueError, match=r"phases: shape \(3,\)"):
        model.predict_path(ds.q[a], ds.dq[a], ds.u[a:b], ds.dt, phases=["contact"] * 3)
    with pytest.raises(ValueError, match=r"phases\[1\]: 'swim'"):
        model.predict_path(ds.q[a], ds.dq[a], ds.u[a:a + 2], ds.dt, phases=["contact", "swim"])
    with pytest.raises(ValueError, match=r"inputs: shape \(5, 12\)"):
        model.predict_path(ds.q[a], ds.dq[a], np.zeros((5, 12)), ds.dt, phases=["contact"] * 5)
    with pytest.raises(ValueError, match="n: the number of samples"):
        model.predict_path(ds.q[a], ds.dq[a], lambda t, s: ds.u[a], ds.dt)
    with pytest.raises(ValueError, match="at sample 0"):
        model.predict_path(ds.q[a], ds.dq[a], lambda t, s: np.zeros(3), ds.dt, n=4)
    old = type(model)(**{**model.__dict__, "guards": None})
    with pytest.raises(NoGuardsError, match="no contact guards"):
        old.predict_path(ds.q[a], ds.dq[a], ds.u[a:b], ds.dt)


def test_a_diverging_path_is_reported(fitted):
    model, ds, j = fitted
    a, b = ds.jump_bounds()[j]
    u = ds.u[a:b] * 1e6
    p = model.predict_path(ds.q[a], ds.dq[a], u, ds.dt, phases=model.phase_index(ds)[a:b])
    assert p.diverged and np.isnan(p.q[p.diverged_at:]).all() and np.isfinite(p.q[:p.diverged_at]).all()


def test_evaluate_with_predicted_phases_reports_switching_times(fitted, tmp_path):
    import json

    from conftest import one_line_error
    from typer.testing import CliRunner

    from symrom.cli import app
    from symrom.data.io import write_dataset
    from symrom.evaluate.metrics import evaluate_model
    from symrom.evaluate.switching import predicted_rollout
    from symrom.model.persistence import model_to_dict, save_model

    model, ds, j = fitted
    jumps = ds.jumps_in("test")
    # a guard that never fires keeps the first phase: every logged switch is missed
    never = type(model)(**{**model.__dict__, "guards": [type(g)(**{**g.__dict__, "bias": -1e9})
                                                         for g in model.guards]})
    m, _ = evaluate_model(never, ds, "test", (None,), RolloutOptions(method="rk4"), phases="predicted")
    sw = m.switching["contact->flight"]
    assert sw["matched"] == 0 and sw["missed"] == sw["logged"] == len(jumps)
    # resets put the logged phase back, held until the next reset when no guard fires
    ro, ph = predicted_rollout(never, ds, jumps, RolloutOptions(method="rk4", reset=0.1))
    logged = model.phase_index(ds)
    a, b = ds.jump_bounds()[jumps[0]]
    every = round(0.1 / ds.dt)
    np.testing.assert_array_equal(ph[0], np.repeat(logged[a:b:every], every)[:b - a])
    save_model(model, tmp_path / "m.json")
    write_dataset(ds, tmp_path / "d.h5")
    r = CliRunner().invoke(app, ["evaluate", str(tmp_path / "m.json"), str(tmp_path / "d.h5"), "--out",
                                 str(tmp_path / "ev"), "--integrator", "rk4", "--phases", "predicted"])
    assert r.exit_code == 0, r.output
    metrics = json.loads((tmp_path / "ev" / "metrics.json").read_text())
    assert metrics["phases"] == "predicted" and set(metrics["switching"]) >= {"contact->flight"}
    assert "Switching times" in (tmp_path / "ev" / "table.md").read_text()
    one_line_error(CliRunner().invoke(app, ["evaluate", str(tmp_path / "m.json"), str(tmp_path / "d.h5"),
                                            "--out", str(tmp_path / "e2"), "--phases", "predicted"]),
                   "--integrator rk4")
    d = model_to_dict(model)
    d["guards"] = None
    (tmp_path / "old.json").write_text(json.dumps(d))
    one_line_error(CliRunner().invoke(app, ["evaluate", str(tmp_path / "old.json"), str(tmp_path / "d.h5"),
                                            "--out", str(tmp_path / "e3"), "--integrator", "rk4",
                                            "--phases", "predicted"]), "no contact guards")


def _bouncer(motion: str | None = "pronk"):
    """A planted hybrid system: the base height z on a spring in contact (rest 0.3 m, 20 rad/s,
    lightly damped), ballistic in flight; it lifts off at z >= 0.32 m and lands at z <= 0.30 m.
    Left alone, it bounces again and again."""
    from symrom.model.autoencoder import LinearAutoencoder
    from symrom.model.guards import Guard
    from symrom.model.hybrid import HybridModel
    from symrom.model.library import Library
    from symrom.model.provenance import DataRecord, Provenance
    from symrom.names import BASE_POS

    z = BASE_POS.start + 2
    W_e = np.zeros((1, 18))
    W_e[0, z] = 1.0
    ae = LinearAutoencoder(W_e, np.zeros(1), W_e.T.copy(), np.zeros(18))
    lib = Library.standard(1, poly_order=1, trig=False, inputs=False)
    assert lib.feature_names == ["1", "xi1", "dxi1"]
    k, c = 400.0, 0.5
    Xi = np.array([[[k * 0.3], [-k], [-c]], [[-9.81], [0.0], [0.0]]])
    guards = [Guard("contact", "flight", ["xi1"], [1.0], -0.32, 0.02),
              Guard("flight", "contact", ["xi1"], [-1.0], 0.30, 0.02)]
    return HybridModel(ae, lib, ["contact", "flight"], Xi, Xi != 0, np.array([1.0, 10.0]),
                       Provenance(DataRecord(motion=motion)), guards=guards), z


def test_a_free_prediction_takes_each_transition_of_the_motion_once():
    model, z = _bouncer()
    assert model.phase_sequence() == (0, 1, 0)  # a pronk: contact, flight, contact
    q0 = np.zeros(18)
    q0[z] = 0.25
    u = np.zeros((1500, 18))  # 3 s
    free = model.predict_path(q0, np.zeros(18), u, 0.002)
    assert [(s["source"], s["target"]) for s in free.switches] == [("contact", "flight"), ("flight", "contact")]
    assert free.phase[-1] == 0 and not free.diverged
    # the same system without its motion's sequence lifts off again after landing
    loose = model.predict_path(q0, np.zeros(18), u, 0.002, stage0=-1)
    assert len(loose.switches) > 3
    assert loose.switches[:2] == free.switches
    # a callable steps sample by sample and decides alike
    stepped = model.predict_path(q0, np.zeros(18), lambda t, s: np.zeros(18), 0.002, n=1500)
    assert stepped.switches == free.switches
    # a model of a motion the registry does not hold switches as its guards say
    other, _ = _bouncer(motion=None)
    assert other.phase_sequence() == () and len(other.predict_path(q0, np.zeros(18), u, 0.002).switches) > 3
    # started in flight (the second place of the sequence), it lands once and stays
    q1 = q0.copy()
    q1[z] = 0.45
    fall = model.predict_path(q1, np.zeros(18), u, 0.002, phase0="flight")
    assert [(s["source"], s["target"]) for s in fall.switches] == [("flight", "contact")]
    with pytest.raises(ValueError, match="stage0=2"):
        model.predict_path(q1, np.zeros(18), u, 0.002, phase0="flight", stage0=2)


def test_stages_along_a_sequence():
    from symrom.model.guards import advance, sequence_targets, stage_along

    froggy = (0, 1, 2, 0)  # contact, partial, flight, contact
    assert sequence_targets(froggy, 0) == {1, 2, 0}  # the phases later in it: partial, flight, contact
    assert sequence_targets(froggy, 2) == {0} and sequence_targets(froggy, 3) == frozenset()
    assert sequence_targets(froggy, -1) is None
    assert advance(froggy, 0, 2) == 2 and advance(froggy, 2, 0) == 3 and advance(froggy, -1, 1) == -1
    assert stage_along(froggy, np.array([0, 0, 1, 1, 2, 2, 0])) == 3
    assert stage_along(froggy, np.array([0, 2, 0])) == 3  # a jump without its partial phase
    assert stage_along(froggy, np.array([0, 1, 0])) == 3  # partial straight to contact: still forward
    assert stage_along(froggy, np.array([0, 2, 1])) == -1  # back into a phase the jump has left


def test_guards_levelled_along_free_predictions_switch_no_later_than_on_own_rollouts(fitted):
    # fit levels each guard again along free predictions, transition by transition; the grid's
    # fit_variants stops at the own rollouts. On the jumps they were levelled on, the free
    # predictions' switching errors can only shrink (a guard changes only when better on val),
    # and the levelled ones name their path.
    from symrom.evaluate.switching import predicted_rollout, switching_errors
    from symrom.learn.estimator import FREE_PATH

    model, ds, _ = fitted
    est = TrainConfig(latent_dim=2, poly_order=2).estimator()
    (own,) = est.fit_variants(ds, [est.regressor])
    assert FREE_PATH in [g.report.get("refit_on") for g in model.guards]  # this fit's touchdown moved
    assert FREE_PATH not in [g.report.get("refit_on") for g in own.guards]
    jumps = ds.jumps_in("val")
    errors = {}
    for name, m in (("own", own), ("free", model)):
        ro, ph = predicted_rollout(m, ds, jumps, RolloutOptions("rk4"))
        errors[name] = switching_errors(m, ds, jumps, ph, ro.diverged_at)
    for t, e in errors["free"].items():
        assert e["missed"] == errors["own"][t]["missed"] and e["extra"] == 0
        assert np.mean([abs(x["predicted_t"] - x["logged_t"]) for x in e["errors"]]) <= np.mean(
            [abs(x["predicted_t"] - x["logged_t"]) for x in errors["own"][t]["errors"]]) + ds.dt
