"""The aSLIP baseline on spring-mass hops whose truth is the aSLIP model itself."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from conftest import one_line_error
from typer.testing import CliRunner

from symrom.baselines.aslip import (
    GRAVITY,
    PAPER_PARAMS,
    ASlip,
    ASlipParams,
    aslip_acceleration,
    fit_aslip,
    fit_aslip_rollout,
    stance_pivots,
)
from symrom.cli import app
from symrom.data.io import write_dataset
from symrom.evaluate.metrics import evaluate_model, rollout_errors
from symrom.evaluate.tables import table2
from symrom.names import BASE_POS
from symrom.robots import total_mass
from symrom.rollout.integrate import RolloutOptions, rollout
from symrom.testing import make_slip_dataset

runner = CliRunner()


@pytest.fixture(scope="module")
def slip():
    ds, truth = make_slip_dataset(n_jumps=6, n_samples=300, seed=3)
    return ds, ASlipParams(**truth)


def test_generator_hops(slip):
    ds, _ = slip
    flight = ds.phase == ds.phase_names.index("flight")
    for j in range(ds.n_jumps):  # every jump: launch, flight, landing
        ph = ds.phase[ds.jump == j]
        first_flight = int(np.argmax(ph == 1))
        assert ph[0] == 0 and first_flight > 0 and (ph[first_flight:] == 0).any()
    # The stored wrench is the actuation force m u, zero in flight.
    assert np.all(ds.u[flight, 12:15] == 0) and np.abs(ds.u[~flight, 14]).max() > 0


def test_fit_recovers_spring(slip):
    ds, truth = slip
    p = fit_aslip(ds, ds.rows_of("train"), truth.m)
    assert p.m == truth.m
    assert p.k_s == pytest.approx(truth.k_s, rel=0.02)
    assert p.l_0 == pytest.approx(truth.l_0, rel=0.02)


def test_fit_tolerates_noisy_accelerations(slip):
    ds, truth = slip
    rng = np.random.default_rng(0)
    noisy = replace(ds, ddq=ds.ddq + 0.2 * rng.standard_normal(ds.ddq.shape))  # 0.2 m/s^2
    p = fit_aslip(noisy, m=truth.m)
    assert p.k_s == pytest.approx(truth.k_s, rel=0.02)
    assert p.l_0 == pytest.approx(truth.l_0, rel=0.02)


def test_mass_must_be_given_for_robots_without_urdf(slip):
    ds, _ = slip
    with pytest.raises(ValueError, match="mass"):
        fit_aslip(ds)


def test_urdf_total_mass():
    assert 10.0 < total_mass("go1") < 16.0  # Go1: about 12-13 kg
    assert 10.0 < total_mass("a1") < 16.0


def test_pivot_is_mean_of_feet_in_contact(slip):
    ds, _ = slip
    fp = ds.foot_pos.copy()
    fp[0] = [[0, 0, 0], [1, 0, 0], [0, 2, 0], [9, 9, 9]]
    c = ds.contact.copy()
    c[0] = [1, 1, 1, 0]
    piv = stance_pivots(replace(ds, foot_pos=fp, contact=c))
    np.testing.assert_allclose(piv[0], [1 / 3, 2 / 3, 0])


def test_acceleration_form():
    p = ASlipParams(k_s=100.0, l_0=0.5, m=2.0)
    b = np.array([[0.0, 0.0, 0.3], [0.0, 0.0, 0.3]])
    piv = np.zeros((2, 3))
    u = np.array([[1.0, 2.0, 3.0]] * 2)
    a = aslip_acceleration(p, b, piv, u, np.array([True, False]))
    np.testing.assert_allclose(a[0], GRAVITY + [1, 2, 3] + [0, 0, 100 * 0.2 / 2])
    np.testing.assert_allclose(a[1], GRAVITY)  # flight: gravity only


@pytest.mark.parametrize("method", ["lsoda", "rk4"])
def test_true_params_reproduce_the_trajectory(slip, method):
    ds, truth = slip
    ro = rollout(ASlip(truth), ds, options=RolloutOptions(method=method))
    assert not ro.diverged.any()
    err = rollout_errors(ds, ro)
    assert err.shape == (ds.n_samples, 3)
    assert np.abs(err).max() < 1e-4  # m, over 0.6 s of hopping


@pytest.mark.parametrize("method", ["lsoda", "rk4"])
def test_reset_restarts_from_the_truth(slip, method):
    ds, truth = slip
    wrong = replace(truth, k_s=0.5 * truth.k_s)
    j = int(ds.jumps_in("test")[0])
    ro = rollout(ASlip(wrong), ds, [j], RolloutOptions(method=method, reset=0.1))
    b_true = ds.q[ds.jump == j][:, BASE_POS]
    every = int(round(0.1 / ds.dt))
    np.testing.assert_allclose(ro.q_pred[0][::every], b_true[::every], atol=1e-12)
    assert not np.allclose(ro.q_pred[0][1:every], b_true[1:every], atol=1e-6)


@pytest.mark.parametrize("reset", [None, 0.1])
@pytest.mark.parametrize("k_scale", [0.7, 1e6])
def test_the_compiled_rk4_is_the_numpy_rk4_bit_for_bit(slip, reset, k_scale):
    """The aSLIP's compiled integrator (the default) against the NumPy RK4 of any model: the same
    paths, the same divergence samples (a spring a million times too stiff diverges)."""
    ds, truth = slip
    model = ASlip(replace(truth, k_s=k_scale * truth.k_s))
    opts = RolloutOptions("rk4", reset=reset, substeps=2)
    fast, slow = rollout(model, ds, options=opts), rollout(model, ds, options=replace(opts, backend="numpy"))
    assert np.array_equal(fast.diverged_at, slow.diverged_at)
    assert fast.diverged.any() == (k_scale > 1)
    for a, b in zip(fast.q_pred, slow.q_pred):
        assert np.array_equal(a, b, equal_nan=True)


@pytest.mark.parametrize("method", ["lsoda", "rk4"])
def test_absurd_model_is_flagged(slip, method):
    ds, truth = slip
    crazy = replace(truth, k_s=1e9, l_0=100.0)
    m, _ = evaluate_model(ASlip(crazy), ds, "test", resets=(None,),
                    options=RolloutOptions(method=method, max_steps=200))
    full = m.full
    assert full.diverged_jumps == m.n_jumps
    # Each is scored up to its divergence (sample 0 is the true start), no further.
    assert full.scored_samples == pytest.approx(sum(d.t for d in full.diverged) / ds.dt)
    assert full.scored_samples < 0.1 * full.samples


def test_metrics_layout(slip):
    ds, truth = slip
    m, _ = evaluate_model(ASlip(truth), ds, "test", resets=(None, 0.1), options=RolloutOptions("rk4"),
                          data_name="d.h5")
    m = m.to_dict()  # the layout of metrics.json
    assert set(m) == {"format_version", "model", "data", "split", "n_jumps", "integrator", "drift_limits",
                      "phases", "horizons"}
    assert m["format_version"] == 3 and m["phases"] == "logged"
    assert m["split"] == "test" and m["n_jumps"] == len(ds.jumps_in("test")) and m["data"] == "d.h5"
    assert list(m["horizons"]) == ["full", "0.1"]
    for h in m["horizons"].values():
        assert h["diverged_jumps"] == 0 and h["diverged"] == [] and h["drifted_jumps"] == 0
        assert h["samples"] == h["scored_samples"] == int(ds.rows_of("test").sum())
        assert list(h["components"]) == ["x", "y", "z"]
        for c in h["components"].values():
            assert set(c) == {"mean", "std", "mae", "rmse"}
            assert c["rmse"] < 1e-4
    json.dumps(m)
    assert "| Full |" in table2(m, components=("x", "y", "z"))


def test_paper_params():
    assert (PAPER_PARAMS.k_s, PAPER_PARAMS.l_0, PAPER_PARAMS.m) == (250.0, 0.32, 12.01)


# ----------------------------------------------------------------------------- CLI
@pytest.fixture(scope="module")
def slip_file(slip, tmp_path_factory):
    path = tmp_path_factory.mktemp("aslip") / "slip.h5"
    write_dataset(slip[0], path)
    return path


def test_cli_fits_writes_and_refuses_to_overwrite(slip, slip_file, tmp_path):
    _, truth = slip
    out = tmp_path / "aslip"
    r = runner.invoke(app, ["aslip", str(slip_file), "--out", str(out), "--mass", str(truth.m),
                            "--integrator", "rk4"])
    assert r.exit_code == 0, r.output
    assert {p.name for p in out.iterdir()} == {"metrics.json", "params.json", "table.md"}
    params = json.loads((out / "params.json").read_text())
    assert params["k_s"] == pytest.approx(truth.k_s, rel=0.02) and params["m"] == truth.m
    metrics = json.loads((out / "metrics.json").read_text())
    assert list(metrics["horizons"]) == ["full", "0.1"] and metrics["integrator"] == "rk4"
    assert "| Full |" in (out / "table.md").read_text()

    before = (out / "params.json").read_text()
    r = runner.invoke(app, ["aslip", str(slip_file), "--out", str(out), "--mass", str(truth.m)])
    one_line_error(r, "--force")
    assert (out / "params.json").read_text() == before

    r = runner.invoke(app, ["aslip", str(slip_file), "--out", str(out), "--fixed", "--k-s", "1000",
                            "--integrator", "rk4", "--force"])
    assert r.exit_code == 0, r.output
    params = json.loads((out / "params.json").read_text())
    assert (params["k_s"], params["l_0"], params["m"]) == (1000.0, PAPER_PARAMS.l_0, PAPER_PARAMS.m)
    assert params["source"].startswith("fixed") and params["model"] == "aslip" and params["format_version"] == 2


def test_cli_errors(slip_file, tmp_path):
    out = tmp_path / "x"
    one_line_error(runner.invoke(app, ["aslip", str(slip_file), "--out", str(out)]), "--mass")
    one_line_error(runner.invoke(app, ["aslip", str(slip_file), "--out", str(out), "--k-s", "3"]),
                    "--fixed")
    one_line_error(runner.invoke(app, ["aslip", str(slip_file), "--out", str(out), "--fixed",
                                        "--integrator", "euler"]), "lsoda")
    one_line_error(runner.invoke(app, ["aslip", str(slip_file), "--out", str(out), "--fixed",
                                        "--split", "val"]), "'val'")
    one_line_error(runner.invoke(app, ["aslip", str(slip_file), "--out", str(out), "--fixed",
                                        "--l0", "-1"]), "l_0")
    assert not out.exists()


def test_rollout_fit_recovers_the_spring_from_a_wrong_start(slip):
    ds, truth = slip
    start = replace(truth, k_s=0.6 * truth.k_s, l_0=1.1 * truth.l_0)
    fitted, record = fit_aslip_rollout(ds, m=truth.m, start=start)
    assert fitted.k_s == pytest.approx(truth.k_s, rel=0.02)
    assert fitted.l_0 == pytest.approx(truth.l_0, rel=0.02)
    assert [s["reset_s"] for s in record.stages] == [0.1, 0.3, None]
    assert all(s["cost_after"] <= s["cost_before"] for s in record.stages)


def test_newton_is_exact_when_the_logged_force_is_the_whole_force(slip):
    from symrom.baselines.newton import Newton

    ds, truth = slip
    # Log the whole force (spring and actuation) as the ground force: Newton's law is then
    # the truth, up to holding the force over each 2 ms sample.
    u = ds.u.copy()
    u[:, 12:15] = truth.m * (ds.ddq[:, BASE_POS] - GRAVITY)
    full = replace(ds, u=u)
    m, _ = evaluate_model(Newton(truth.m), full, "test", resets=(None, 0.1), options=RolloutOptions("rk4"))
    for key, bound in (("full", 1e-2), ("0.1", 1e-3)):  # m; the hold error grows with the horizon
        h = m.horizons[key]
        assert list(h.components) == ["x", "y", "z"] and h.diverged_jumps == 0
        assert max(c.rmse for c in h.components.values()) < bound
    # On the logged actuation alone it misses the spring, and the aSLIP does not.
    newton, _ = evaluate_model(Newton(truth.m), ds, "test", resets=(None,), options=RolloutOptions("rk4"))
    aslip, _ = evaluate_model(ASlip(truth), ds, "test", resets=(None,), options=RolloutOptions("rk4"))
    z = lambda m: m.rmse("z")  # noqa: E731
    assert z(newton) > 100 * z(aslip)
    with pytest.raises(ValueError, match="mass"):
        Newton(0.0)


def test_cli_newton_and_rollout_fit(slip, slip_file, tmp_path):
    _, truth = slip
    r = runner.invoke(app, ["newton", str(slip_file), "--out", str(tmp_path / "n"), "--mass", str(truth.m),
                            "--integrator", "rk4"])
    assert r.exit_code == 0, r.output
    assert set(json.loads((tmp_path / "n" / "metrics.json").read_text())["horizons"]["full"]["components"]) \
        == {"x", "y", "z"}
    r = runner.invoke(app, ["newton", str(slip_file), "--out", str(tmp_path / "nf"), "--fit", "--integrator", "rk4",
                            "--mass", str(truth.m)])
    assert r.exit_code == 0, r.output
    params = json.loads((tmp_path / "nf" / "params.json").read_text())
    assert params["model"] == "affine_force" and np.shape(params["A"]) == (3, 3) and "train split" in params["source"]
    r = runner.invoke(app, ["aslip", str(slip_file), "--out", str(tmp_path / "a"), "--mass", str(truth.m),
                            "--fit", "rollout", "--integrator", "rk4"])
    assert r.exit_code == 0, r.output
    params = json.loads((tmp_path / "a" / "params.json").read_text())
    assert "rollout" in params["source"] and params["k_s"] == pytest.approx(truth.k_s, rel=0.02)
    assert len(params["stages"]) == 3
    one_line_error(runner.invoke(app, ["aslip", str(slip_file), "--out", str(tmp_path / "b"), "--mass", "3",
                                       "--fit", "bogus"]), "--fit")


def test_a_fitted_affine_force_law_recovers_a_planted_gain(slip):
    """Base accelerations made from a known A, c (contact) and c_f (flight) are recovered
    exactly, and the law survives its params.json round trip."""
    from symrom.baselines import from_params
    from symrom.baselines.com import flight_rows, input_acceleration
    from symrom.baselines.newton import AffineForce

    ds = replace(slip[0], ddq=slip[0].ddq.copy())
    A = np.array([[0.9, 0.2, 0.0], [0.0, 1.0, 0.0], [-0.1, 0.3, 1.1]])
    c, c_f = np.array([0.05, 0.0, -9.5]), np.array([0.2, 0.0, -10.2])
    flight = flight_rows(ds)
    acc = np.where(flight[:, None], c_f, c + input_acceleration(ds, 12.0) @ A.T)
    ds.ddq[:, BASE_POS] = acc
    fit = AffineForce.fit(ds, m=12.0)
    np.testing.assert_allclose(fit.A, A, atol=1e-9)
    np.testing.assert_allclose(fit.c, c, atol=1e-9)
    np.testing.assert_allclose(fit.c_f, c_f, atol=1e-9)
    again = from_params(fit.to_dict())
    np.testing.assert_array_equal(again.A, fit.A)
    with pytest.raises(ValueError, match="shape"):
        AffineForce(12.0, np.eye(2), c, c_f)
