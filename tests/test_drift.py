"""Drift: a rollout that stays inside its latent bound but leaves the physically possible
(base through the floor, travel beyond the data) is flagged per jump with its time."""

import json
from dataclasses import replace

import numpy as np
import pytest

from symrom.evaluate.metrics import DriftLimits, drift_events, evaluate_model
from symrom.evaluate.records import Metrics
from symrom.evaluate.tables import table2
from symrom.learn.training import TrainConfig, train
from symrom.names import Q_NAMES
from symrom.robots.stance import leg_length
from symrom.rollout.integrate import RolloutOptions
from symrom.testing import make_planted_dataset

Z = Q_NAMES.index("z")


@pytest.fixture(scope="module")
def go1_planted():
    """A planted dataset dressed as Go1 jumps: its base height lifted to 0.15 m and above, so
    that the ground rule (z = 0, a leg length below) applies; and a model trained on it."""
    ds, _ = make_planted_dataset(n_jumps=10, n_samples=400, embedding="block", noise=1e-4, seed=5)
    q = ds.q.copy()
    q[:, Z] += 0.15 - q[:, Z].min()
    ds = replace(ds, robot="go1", q=q)
    return ds, train(ds, TrainConfig())


def _falling(model, ds, accel: float):
    """The model with ``accel`` m/s^2 of extra downward base acceleration in flight: a
    constant in the flight equations along the decoder's z row (a wrong gravity)."""
    w = model.autoencoder.W_d[Z]  # (l,) m per latent unit
    Xi = model.Xi.copy()
    Xi[ds.phase_id("flight"), model.library.feature_names.index("1")] -= accel * w / (w @ w)
    return replace(model, Xi=Xi, mask=model.mask | (Xi != 0))


def test_a_good_rollout_is_not_flagged(go1_planted):
    ds, model = go1_planted
    metrics, _ = evaluate_model(model, ds, "test", (None, 0.1), RolloutOptions("rk4"))
    assert metrics.format_version == 3
    for h in metrics.horizons.values():
        assert h.drifted_jumps == 0 and h.drifted == ()
    assert metrics.drift_limits["leg_length"] == pytest.approx(leg_length("go1"))
    assert "Drifted" not in table2(metrics)


def test_a_fall_through_the_floor_is_flagged_when_it_happens(go1_planted):
    ds, model = go1_planted
    bad = _falling(model, ds, 80.0)
    metrics, ros = evaluate_model(bad, ds, "test", (None,), RolloutOptions("rk4"))
    full, ro = metrics.to_dict()["horizons"]["full"], ros["full"]
    leg = leg_length("go1")
    assert full["diverged_jumps"] == 0  # inside the latent bound: divergence alone misses it
    assert full["drifted_jumps"] == ro.jumps.size
    for ev, j, pred in zip(full["drifted"], ro.jumps, ro.q_pred):
        k = int(np.flatnonzero(pred[:, Z] < -leg)[0])  # the first sample a leg length below ground
        assert ev == {"jump": int(j), "t": round(k * ds.dt, 6), "component": "z",
                      "value": round(float(pred[k, Z]), 6), "limit": round(-leg, 6)}
        flight = np.flatnonzero(ds.phase[ds.jump == j] == ds.phase_id("flight"))
        assert flight[0] < k  # it falls once the wrong gravity acts
    assert full["scored_samples"] == full["samples"]  # drifted jumps are still scored
    rec = Metrics.from_dict(json.loads(json.dumps(metrics.to_dict())))
    assert rec.any_drifted and rec.horizons["full"].drifted[0].t == full["drifted"][0]["t"]
    assert rec.to_dict()["horizons"]["full"]["drifted"] == full["drifted"]
    text = table2(metrics)
    first = full["drifted"][0]
    assert "drifted" in text and f"jump {first['jump']} at {first['t']:.3f} s (z " in text


def test_drift_starts_at_the_first_sample_past_a_limit(go1_planted):
    ds, model = go1_planted
    metrics, ros = evaluate_model(model, ds, "test", (None,), RolloutOptions("rk4"))
    ro = ros["full"]
    limits = DriftLimits.of(ds)
    q0 = [p.copy() for p in ro.q_pred]
    X = Q_NAMES.index("x")
    a, b = ds.jump_bounds()[ro.jumps[0]]
    beyond = ds.q[a:b, X].max() + limits.margin["x"]
    q0[0][37:, X] = beyond + 0.01  # travels past the jump's range plus the margin from sample 37 on
    q0[0][50:, Z] = -2.0  # and through the floor later: the earlier breach is reported
    ev = drift_events(ds, replace(ro, q_pred=q0), limits)
    assert ev[0]["jump"] == int(ro.jumps[0]) and ev[0]["t"] == round(37 * ds.dt, 6)
    assert ev[0]["component"] == "x" and ev[0]["limit"] == pytest.approx(beyond)
    assert len(ev) == 1
    # A breach after the divergence is not drift: the rollout was already stopped there.
    div = replace(ro, q_pred=q0, diverged=np.r_[True, ro.diverged[1:]], diverged_at=np.r_[30, ro.diverged_at[1:]])
    assert drift_events(ds, div, limits) == []
    # The margin is the largest training jump's range of each base coordinate, at least a leg length.
    tr = ds.jump_bounds()[ds.jumps_in("train")]
    spread = max(np.ptp(ds.q[a:b, X]) for a, b in tr)
    assert limits.margin["x"] == pytest.approx(max(spread, leg_length("go1")))


def test_version_2_files_are_still_read(go1_planted):
    ds, model = go1_planted
    metrics, _ = evaluate_model(model, ds, "test", (None,), RolloutOptions("rk4"))
    old = json.loads(json.dumps(metrics.to_dict()))
    old["format_version"] = 2
    for h in old["horizons"].values():
        del h["drifted_jumps"], h["drifted"]
    rec = Metrics.from_dict(old)
    assert rec.horizons["full"].drifted_jumps is None and not rec.any_drifted
    assert "drifted" not in rec.to_dict()["horizons"]["full"]


def test_the_command_line_warns_of_drift(go1_planted, tmp_path):
    from typer.testing import CliRunner

    from symrom.cli import app
    from symrom.data.io import write_dataset
    from symrom.model.persistence import save_model

    ds, model = go1_planted
    write_dataset(ds, tmp_path / "d.h5")
    save_model(_falling(model, ds, 80.0), tmp_path / "bad.json")
    r = CliRunner().invoke(app, ["evaluate", str(tmp_path / "bad.json"), str(tmp_path / "d.h5"),
                                 "--integrator", "rk4", "--out", str(tmp_path / "ev")])
    assert r.exit_code == 0, r.output
    m = json.loads((tmp_path / "ev" / "metrics.json").read_text())
    first = m["horizons"]["full"]["drifted"][0]
    said = " ".join(r.output.split())
    assert f"drifted at horizon full (jump {first['jump']} at {first['t']:.3f} s (z" in said
    assert "diverged" not in said
