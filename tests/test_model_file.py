import json

import numpy as np
import pytest
from conftest import as_format

from symrom.learn.training import TrainConfig, train
from symrom.model.persistence import FORMAT_VERSION, ModelFileError, load_model, model_to_dict, save_model
from symrom.rollout.integrate import RolloutOptions, rollout


def test_round_trip_is_exact(planted_block, tmp_path):
    ds, _ = planted_block
    model = train(ds, TrainConfig(latent_dim=3, poly_order=2))
    path = tmp_path / "model.json"
    save_model(model, path)
    text = path.read_text()
    assert "pickle" not in text and json.loads(text)["format_version"] == FORMAT_VERSION
    back = load_model(path)
    for a, b in [(model.autoencoder.W_e, back.autoencoder.W_e), (model.autoencoder.W_d, back.autoencoder.W_d),
                 (model.Xi, back.Xi), (model.mask, back.mask)]:
        np.testing.assert_array_equal(a, b)
    assert back.library == model.library and back.phase_names == model.phase_names
    assert back.provenance == model.provenance and back.provenance.data.sha256 == model.provenance.data.sha256
    j = ds.jumps_in("test")[:1]
    rk4 = RolloutOptions("rk4")  # compiled: checks the model read back as LSODA would, in a fraction of the time
    np.testing.assert_array_equal(rollout(model, ds, j, rk4).q_pred[0], rollout(back, ds, j, rk4).q_pred[0])
    assert back.equations().text() == model.equations().text()
    for name in model.phase_names:
        a, b = model.phase_info[name], back.phase_info[name]
        assert (a.trained, a.n_rows, a.duration_s, a.report) == (b.trained, b.n_rows, b.duration_s, b.report)
        np.testing.assert_array_equal(a.operating_point, b.operating_point)
    stab = json.loads(text)["phases"]["contact"]["stability"]
    assert len(stab["eigenvalues"]) == 2 * model.latent_dim


def test_format_1_files_still_load(planted_block, tmp_path):
    ds, _ = planted_block
    model = train(ds, TrainConfig())
    d = as_format(model_to_dict(model), 1)
    lib = d["library"]
    d.update(library={"latent_dim": lib["latent_dim"], "poly_order": 1, "trig": True,
                                        "inputs": True, "feature_names": lib["feature_names"]})
    d["phases"] = {n: {k: v for k, v in ph.items() if k in ("Xi", "mask", "active_terms")}
                   for n, ph in d["phases"].items()}
    path = tmp_path / "v1.json"
    path.write_text(json.dumps(d))
    back = load_model(path)
    np.testing.assert_array_equal(back.Xi, model.Xi)
    assert back.library == model.library and back.phase_info == {}
    assert back.trained_phases() == model.phase_names


def test_custom_blocks_round_trip(planted_block, tmp_path):
    from symrom.learn.estimator import SymbolicROM
    from symrom.model.library import Custom, Inputs, Polynomial

    ds, _ = planted_block
    # What is read back here is the library: evaluated by NumPy, as the rollouts below do, it needs
    # no code compiled for it (seconds, which the guards' rollouts in the fit would spend).
    rom = SymbolicROM(2, Polynomial(1) + Inputs() + Custom(("xi1*nu1", "exp(-xi2**2)"), ("xi1 nu1", "bump")),
                      contact_guards=False)
    rom.fit(ds)
    rom.save(tmp_path / "m.json")
    back = SymbolicROM.load(tmp_path / "m.json")
    assert back.model.library == rom.model.library
    assert back.model.library.feature_names[-2:] == ["xi1 nu1", "bump"]
    j = ds.jumps_in("test")[:1]
    numpy = RolloutOptions("rk4", substeps=1, backend="numpy")
    np.testing.assert_array_equal(rom.simulate(ds, j, options=numpy).q_pred[0],
                                  back.simulate(ds, j, options=numpy).q_pred[0])


@pytest.mark.parametrize("edit,needle", [
    (lambda d: d.update(format_version=7), "format_version"),
    (lambda d: d["encoder"].update(W_e=[[0.0] * 18]), "encoder.W_e"),
    (lambda d: d["phases"]["flight"].update(Xi=[[0.0]]), "phases.flight.Xi"),
    (lambda d: d["library"]["blocks"][0].update(order=3), "library"),
    (lambda d: d["library"]["blocks"].append({"kind": "custom", "expressions": ["__import__('os')"]}),
     "unknown name '__import__'"),
    (lambda d: d["phases"]["flight"].update(operating_point=[0.0]), "phases.flight.operating_point"),
    (lambda d: d.pop("decoder"), "decoder"),
])
def test_bad_files_name_the_problem(planted_block, tmp_path, edit, needle):
    ds, _ = planted_block
    d = model_to_dict(train(ds, TrainConfig()))
    edit(d)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(d))
    with pytest.raises(ModelFileError, match=needle.replace(".", r"\.")):
        load_model(path)


def test_not_json(tmp_path):
    p = tmp_path / "m.json"
    p.write_text("{not json")
    with pytest.raises(ModelFileError, match="not valid JSON"):
        load_model(p)


def test_a_non_finite_model_is_refused_by_key_not_by_json(planted_block, tmp_path):
    ds, _ = planted_block
    model = train(ds, TrainConfig())
    path = tmp_path / "model.json"
    model.autoencoder.W_d[4, 1] = np.inf  # what a fit that blew up leaves
    with pytest.raises(ModelFileError, match=r"^decoder\.W_d\[4, 1\]: inf is not a finite number"):
        save_model(model, path)
    model.autoencoder.W_d[4, 1] = 1.0
    model.provenance = model.provenance.with_settings({"threshold": float("nan")})
    with pytest.raises(ModelFileError, match=r"^provenance\.training\.settings\.threshold: not a finite number"):
        save_model(model, path)
    assert not path.exists() and list(tmp_path.iterdir()) == []


def _exotic_rom():
    """An estimator whose every plug-in differs from the defaults."""
    import symrom

    return symrom.SymbolicROM(2, symrom.Polynomial(1) + symrom.Inputs(),
                              encoder=symrom.PCAEncoder(components=("x", "z", "pitch", "fr_kn"), scaling="spread"),
                              regressor=symrom.STLSQ(threshold=0.04, measure="explained", alpha=1e-6,
                                                     collinearity=0.999),
                              decoded_weight=0.5, contact_phase="contact", path_thresholds=(0.01, 0.1))


def test_load_restores_the_exact_plug_ins(planted_block, tmp_path):
    import symrom

    ds, _ = planted_block
    rom = _exotic_rom().fit(ds)
    rom.save(tmp_path / "m.json")
    assert json.loads((tmp_path / "m.json").read_text())["estimator"]["regressor"]["kind"] == "stlsq"
    back = symrom.SymbolicROM.load(tmp_path / "m.json")
    assert back.encoder == rom.encoder and back.regressor == rom.regressor
    assert (back.decoded_weight, back.contact_phase, back.path_thresholds) == (0.5, "contact", (0.01, 0.1))
    refit = back.fit(ds).model  # the restored estimator fits the same model again
    np.testing.assert_array_equal(refit.Xi, rom.model.Xi)


def test_every_plug_in_round_trips_through_the_registry():
    import symrom
    from symrom.learn.adam import Adam, AdamConfig
    from symrom.learn.encoders import AdamAutoencoder
    from symrom.learn.plugins import ENCODERS, REGRESSORS, encoder_from_dict, regressor_from_dict

    encoders = [symrom.PCAEncoder(), symrom.PCAEncoder(("x", "z"), "spread", 1),
                AdamAutoencoder(AdamConfig(epochs=7), ("x", "y"), seed=3)]
    regressors = [symrom.STLSQ(0.2, "contribution", 1e-3, 0.1, 0.99, 9), symrom.FineTune(0.5, 0.02, "explained"),
                  symrom.Refine(symrom.STLSQ(0.03), windows=(0.1, None), stride=2),
                  Adam(AdamConfig(learning_rate=1e-2), threshold=0.05, seed=4)]
    assert {type(e).kind for e in encoders} == set(ENCODERS) and {type(r).kind for r in regressors} == set(REGRESSORS)
    for e in encoders:
        d = json.loads(json.dumps(e.to_dict()))
        assert encoder_from_dict(d) == e and d["kind"] == type(e).kind
    for r in regressors:
        d = json.loads(json.dumps(r.to_dict()))
        assert regressor_from_dict(d) == r and d["kind"] == type(r).kind


@pytest.mark.parametrize("edit,needle", [
    (lambda d: d["estimator"]["regressor"].update(kind="lasso"), "estimator.regressor: unknown kind 'lasso'"),
    (lambda d: d["estimator"]["encoder"].update(whiten=True), "estimator.encoder: 'pca' has no setting 'whiten'"),
    (lambda d: d["estimator"].pop("encoder"), "estimator.encoder: not recorded"),
])
def test_load_refuses_what_it_cannot_restore(planted_block, tmp_path, edit, needle):
    import symrom

    ds, _ = planted_block
    d = model_to_dict(_exotic_rom().fit(ds).model)
    edit(d)
    path = tmp_path / "m.json"
    path.write_text(json.dumps(d))
    load_model(path)  # the model itself is fine
    with pytest.raises(ModelFileError, match=needle.replace(".", r"\.")):
        symrom.SymbolicROM.load(path)


def test_format_2_files_still_load_with_their_plug_ins(planted_block, tmp_path):
    import symrom

    ds, _ = planted_block
    rom = _exotic_rom().fit(ds)
    d = as_format(model_to_dict(rom.model), 2)
    est = d.pop("estimator")
    legacy = {"STLSQ": est["regressor"], "PCAEncoder": est["encoder"]}
    for name, rec in legacy.items():  # format 2 named the class instead of the kind
        rec.pop("kind")
        rec["name"] = name
    d["info"].update(encoder=est["encoder"], regressor=est["regressor"], decoded_weight=est["decoded_weight"])
    path = tmp_path / "v2.json"
    path.write_text(json.dumps(d))
    back = symrom.SymbolicROM.load(path)
    assert back.encoder == rom.encoder and back.regressor == rom.regressor and back.decoded_weight == 0.5
    np.testing.assert_array_equal(back.model.Xi, rom.model.Xi)


def test_format_4_info_reads_into_the_same_provenance(planted_block, tmp_path):
    """A format 4 file's untyped ``info`` (training, selection, fine-tuning, the command line's
    data_path) is read into the typed provenance a format 5 file holds, nothing lost."""
    from dataclasses import replace

    from symrom.model.provenance import FineTuneRecord, Provenance, SelectionRecord

    ds, _ = planted_block
    model = train(ds, TrainConfig(threshold=0.02), data_path="data/d.h5")
    prov = model.provenance.with_selection(SelectionRecord("all", 2, "poly1+trig+inputs", 0.02, False, 0.5, 9))
    model = replace(model, provenance=prov)
    path = tmp_path / "v4.json"
    d = as_format(model_to_dict(model), 4)
    d["info"]["note"] = "written by a tool"  # a key no part names: kept
    path.write_text(json.dumps(d))
    back = load_model(path)
    assert back.provenance.data == model.provenance.data and back.provenance.selection == prov.selection
    assert back.provenance.training == model.provenance.training
    assert back.provenance.training.settings["threshold"] == 0.02 and back.provenance.training.solver == "exact"
    assert dict(back.provenance.extra) == {"note": "written by a tool"}
    assert Provenance.from_info(back.provenance.to_info()) == back.provenance
    # a model fine-tuned by the command line: its one data_path was the fine-tuning data's
    tuned = prov.with_finetune(FineTuneRecord(config={"method": "calibrate"}, source_model="src/model.json",
                                              path="data/new.h5"))
    info = tuned.to_info()
    assert info["data_path"] == "data/new.h5" and "data/d.h5" not in json.dumps(info)
    assert Provenance.from_info(info).finetune.path == "data/new.h5" and tuned.data_path == "data/new.h5"


def test_provenance_is_immutable_and_read_back_as_settings(planted_block):
    import dataclasses

    ds, _ = planted_block
    config = TrainConfig(threshold=0.02, encoder_components=("x", "y", "z"), latent_dim=2)
    model = train(ds, config)
    with pytest.raises(dataclasses.FrozenInstanceError):
        model.provenance.data.robot = "a1"
    with pytest.raises(TypeError):
        model.provenance.training.settings["threshold"] = 1.0
    assert TrainConfig.from_provenance(model.provenance) == config
    assert TrainConfig.from_provenance(model.provenance, refine=True).refine
