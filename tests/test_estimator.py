"""The estimator API (fit / predict / simulate / equations / save / load), stability
diagnostics, and the guards between a model and the data it is used on."""

from dataclasses import replace

import numpy as np
import pytest
from conftest import one_line_error
from typer.testing import CliRunner

import symrom
import symrom.testing
from symrom.cli import app
from symrom.data.io import write_dataset
from symrom.model.hybrid import HybridModel, ModelDataError
from symrom.model.library import Inputs, Polynomial, Trigonometric
from symrom.rollout.integrate import rollout

runner = CliRunner()


def test_top_level_api(planted_axis, tmp_path):
    ds, truth = planted_axis
    for name in ("SymbolicROM", "TrainConfig", "read_dataset", "evaluate_model",
                 "STLSQ", "Refine", "PCAEncoder", "Polynomial", "Trigonometric", "Inputs", "Custom"):
        assert hasattr(symrom, name), name
    rom = symrom.SymbolicROM(2, Polynomial(1) + Trigonometric() + Inputs())
    with pytest.raises(ValueError, match="not fitted"):
        rom.predict(ds)
    assert rom.fit(ds) is rom
    # predict: the latent accelerations of the planted system, on rows never trained on
    test = ds.rows_of("test")
    ddxi = ds.ddq[test] @ rom.model.autoencoder.W_e.T
    np.testing.assert_allclose(rom.predict(ds, test), ddxi, atol=2e-3 * np.abs(ddxi).max())
    ro = rom.simulate(ds, ds.jumps_in("test"), reset=0.1)
    assert ro.components == symrom.names.Q_NAMES and not ro.diverged.any()
    assert "[contact]" in str(rom.equations()) and "\\ddot{\\xi}_{1}" in rom.equations().latex()
    rom.save(tmp_path / "m.json")
    back = symrom.SymbolicROM.load(tmp_path / "m.json")
    np.testing.assert_array_equal(back.model.Xi, rom.model.Xi)
    np.testing.assert_array_equal(back.simulate(ds, [0]).q_pred[0], rom.simulate(ds, [0]).q_pred[0])
    rk4 = symrom.RolloutOptions("rk4")  # the integrator is not what is checked here; LSODA's is slower
    metrics, _ = symrom.evaluate_model(back.model, ds, "test", options=rk4)
    assert metrics.full.diverged_jumps == 0
    # the fitted estimator itself is rolled out and scored like its model
    direct, _ = symrom.evaluate_model(rom, ds, "test", options=rk4)
    assert direct.full.components == metrics.full.components


# A planted system linear in the state: each latent j obeys ddxi_j = k_j xi_j + c_j dxi_j + (input,
# constant), so its eigenvalues are the roots of s^2 - c_j s - k_j, whatever the coordinates.
LINEAR = {"contact": [{"1": 0.5, "xi1": -6.0, "dxi1": -1.2, "nu1": 3.0},
                      {"1": -1.0, "xi2": -4.0, "dxi2": -0.8, "nu2": 2.5}],
          "flight": [{"xi1": -2.0, "dxi1": -0.6, "nu1": 1.5},
                     {"1": -3.0, "xi2": -1.0, "dxi2": -0.4}]}


def test_linear_planted_system_has_its_analytic_eigenvalues():
    ds, _ = symrom.testing.make_planted_dataset(n_jumps=24, n_samples=400, embedding="axis", noise=1e-4,
                                                seed=1, equations=LINEAR)
    model = symrom.SymbolicROM.from_config(symrom.TrainConfig(trig=False)).fit(ds).model
    stability = {st.phase: st for st in model.stability()}
    assert sorted(stability) == ["contact", "flight"]
    for phase, rows in LINEAR.items():
        expected = np.concatenate([np.roots([1.0, -row[f"dxi{j}"], -row[f"xi{j}"]])
                                   for j, row in enumerate(rows, start=1)])
        np.testing.assert_allclose(np.sort_complex(stability[phase].eigenvalues), np.sort_complex(expected),
                                   atol=1e-3)
        assert not stability[phase].fast_unstable


def _unstable(model: HybridModel) -> HybridModel:
    """The model with a strong anti-damping in contact: a fast unstable mode."""
    names = model.library.feature_names
    Xi = model.Xi.copy()
    Xi[model.phase_names.index("contact"), names.index("dxi1"), 0] = 40.0
    return replace(model, Xi=Xi, mask=model.mask | (Xi != 0))


def test_fast_unstable_mode_is_warned_and_shown(planted_axis, tmp_path):
    ds, _ = planted_axis
    model = symrom.SymbolicROM.from_config(symrom.TrainConfig()).fit(ds).model
    assert not any(s.fast_unstable for s in model.stability())
    bad = _unstable(model)
    warn = [s.warning() for s in bad.stability() if s.warning()]
    assert len(warn) == 1 and "'contact'" in warn[0] and "fast unstable mode" in warn[0]
    symrom.SymbolicROM(2).fit(ds).model  # noqa: B018 - a fitted estimator has its model
    path = tmp_path / "bad.json"
    symrom.model.persistence.save_model(bad, path)
    r = runner.invoke(app, ["equations", str(path)])
    assert r.exit_code == 0, r.output
    assert "eigenvalues" in r.output and "fast unstable mode" in r.output


def test_diverged_rollouts_record_when_they_left(planted_axis):
    ds, _ = planted_axis
    bad = _unstable(symrom.SymbolicROM.from_config(symrom.TrainConfig()).fit(ds).model)
    metrics, ros = symrom.evaluate_model(bad, ds, "test", resets=(None,),
                                   options=symrom.RolloutOptions("rk4"))
    full = metrics.full
    assert full.diverged_jumps == len(full.diverged) > 0
    ro = ros["full"]
    for d in full.diverged:
        i = list(ro.jumps).index(d.jump)
        assert d.t == pytest.approx(ro.diverged_at[i] * ds.dt)
        assert np.isnan(ro.q_pred[i][ro.diverged_at[i]:]).all() and np.isfinite(ro.q_pred[i][:ro.diverged_at[i]]).all()


# ------------------------------------------------------------------ guards
def test_phases_are_matched_by_name(planted_axis):
    ds, _ = planted_axis
    model = symrom.SymbolicROM.from_config(symrom.TrainConfig()).fit(ds).model
    # The same data with its phase list written in the other order: same rollout.
    flipped = replace(ds, phase_names=ds.phase_names[::-1], phase=(1 - ds.phase).astype(np.int8))
    j = ds.jumps_in("test")[:1]
    np.testing.assert_array_equal(rollout(model, ds, j).q_pred[0], rollout(model, flipped, j).q_pred[0])
    # A phase the model has no equations for is refused, naming it, the jump and the row.
    other = replace(ds, phase_names=["contact", "partial"])
    with pytest.raises(ModelDataError, match=r"phase 'partial' \(jump 0, row \d+\): the model has no equations"):
        rollout(model, other, [0])


def test_robot_and_layout_are_checked(planted_axis):
    ds, _ = planted_axis
    model = symrom.SymbolicROM.from_config(symrom.TrainConfig()).fit(ds).model
    with pytest.raises(ModelDataError, match="trained on 'planted', the data are of 'go1'"):
        rollout(model, replace(ds, robot="go1"), [0])
    shuffled = replace(model, provenance=replace(model.provenance, data=replace(
        model.provenance.data, q_names=model.provenance.data.q_names[::-1])))
    with pytest.raises(ModelDataError, match="joint layout"):
        rollout(shuffled, ds, [0])


def test_a_phase_without_training_rows_is_kept_untrained(planted_axis):
    ds, _ = planted_axis
    train_rows = ds.rows_of("train") & (ds.phase == ds.phase_names.index("contact"))
    model = symrom.SymbolicROM.from_config(symrom.TrainConfig()).fit(ds, rows=train_rows).model
    assert model.trained_phases() == ["contact"] and model.provenance.training.untrained_phases == ("flight",)
    assert not model.mask[model.phase_names.index("flight")].any()
    with pytest.raises(ModelDataError, match="phase 'flight'.*training data held no row of it"):
        rollout(model, ds, [0])


def test_cli_names_misuse_in_one_line(planted_axis, tmp_path):
    ds, _ = planted_axis
    data = tmp_path / "d.h5"
    write_dataset(ds, data)
    r = runner.invoke(app, ["train", str(data), "--out", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    other = tmp_path / "other.h5"
    write_dataset(replace(ds, robot="a1"), other)
    one_line_error(runner.invoke(app, ["evaluate", str(tmp_path / "m" / "model.json"), str(other),
                                       "--out", str(tmp_path / "e")]), "robot", "'a1'")
    assert not (tmp_path / "e").exists()
    nof = tmp_path / "noflight.h5"
    write_dataset(replace(ds, phase=np.zeros_like(ds.phase)), nof)  # every row contact: no flight rows
    r = runner.invoke(app, ["train", str(nof), "--out", str(tmp_path / "m2")])
    assert r.exit_code == 0, r.output
    assert "flight" in r.output and "no training rows" in r.output
