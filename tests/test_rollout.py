import time

import numpy as np
import pytest

from symrom.evaluate.metrics import evaluate
from symrom.evaluate.tables import table2
from symrom.model.training import TrainConfig, train
from symrom.rollout.integrate import RolloutOptions, rollout


@pytest.fixture(scope="module")
def model_and_data(planted_block):
    ds, _ = planted_block
    return train(ds, TrainConfig()), ds


@pytest.mark.parametrize("method", ["lsoda", "rk4"])
def test_exploding_model_is_flagged_not_hung(model_and_data, method):
    model, ds = model_and_data
    bad = train(ds, TrainConfig())
    bad.Xi = bad.Xi.copy()
    names = bad.library.feature_names
    bad.Xi[:, names.index("xi1"), 0] = 400.0  # strong positive feedback: exponential blow-up
    t0 = time.perf_counter()
    metrics, ros = evaluate(bad, ds, "test", options=RolloutOptions(method=method))
    assert time.perf_counter() - t0 < 60
    full = metrics["horizons"]["full"]
    assert full["diverged_jumps"] == len(ds.jumps_in("test"))
    assert full["components"] == {}
    assert "diverged" in table2(metrics)
    assert all(d >= 0 for d in ros["full"].diverged_at)


@pytest.mark.parametrize("method", ["lsoda", "rk4"])
def test_reset_restarts_from_the_encoded_truth(model_and_data, method):
    model, ds = model_and_data
    j = int(ds.jumps_in("test")[0])
    ro = rollout(model, ds, [j], RolloutOptions(method=method, reset=0.1))
    a, b = ds.jump_bounds()[j]
    xi_true = model.autoencoder.encode(ds.q[a:b])
    every = int(round(0.1 / ds.dt))
    np.testing.assert_allclose(ro.xi[0][::every], xi_true[::every], atol=1e-12)
    assert not np.allclose(ro.xi[0][1:every], xi_true[1:every], atol=1e-12)


def test_shorter_horizon_is_more_accurate(model_and_data):
    model, ds = model_and_data
    model = train(ds, TrainConfig(latent_dim=1))  # an imperfect model drifts over the full horizon
    metrics, _ = evaluate(model, ds, "test", resets=(None, 0.1), options=RolloutOptions(method="rk4"))
    full = np.mean([c["rmse"] for c in metrics["horizons"]["full"]["components"].values()])
    short = np.mean([c["rmse"] for c in metrics["horizons"]["0.1"]["components"].values()])
    assert short < full


@pytest.mark.parametrize("backend", ["table", "generated"])
@pytest.mark.parametrize("reset", [None, 0.1])
def test_compiled_rk4_matches_the_numpy_reference(planted_block, reset, backend):
    from dataclasses import replace

    from symrom.model.training import TrainConfig, train

    ds, _ = planted_block
    model = train(ds, TrainConfig())
    names = model.library.feature_names
    Xi = model.Xi.copy()
    Xi[0, names.index("dxi1"), 0] = 60.0  # a fast unstable mode, so some rollouts diverge
    bad = replace(model, Xi=Xi, mask=model.mask | (Xi != 0))
    for m in (model, bad):
        a = rollout(m, ds, None, RolloutOptions("rk4", reset=reset, backend=backend))
        b = rollout(m, ds, None, RolloutOptions("rk4", reset=reset, backend="numpy"))
        np.testing.assert_array_equal(a.diverged_at, b.diverged_at)
        for x, y in zip(a.q_pred, b.q_pred):
            np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-12)
    assert rollout(bad, ds, None, RolloutOptions("rk4", backend=backend)).diverged.any()


def test_lsoda_with_the_generated_right_hand_side_matches(planted_block):
    from symrom.model.training import TrainConfig, train

    ds, _ = planted_block
    model = train(ds, TrainConfig())
    jumps = ds.jumps_in("test")
    a = rollout(model, ds, jumps, RolloutOptions("lsoda", backend="generated"))
    b = rollout(model, ds, jumps, RolloutOptions("lsoda", backend="numpy"))
    for x, y in zip(a.xi, b.xi):
        np.testing.assert_allclose(x, y, rtol=1e-9, atol=1e-10)
