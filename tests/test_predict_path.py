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
