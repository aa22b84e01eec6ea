import json

import numpy as np
import pytest

from symrom.model.persistence import ModelFileError, load_model, model_to_dict, save_model
from symrom.model.training import TrainConfig, train
from symrom.rollout.integrate import rollout


def test_round_trip_is_exact(planted_block, tmp_path):
    ds, _ = planted_block
    model = train(ds, TrainConfig(latent_dim=3, poly_order=2))
    path = tmp_path / "model.json"
    save_model(model, path)
    text = path.read_text()
    assert "pickle" not in text and json.loads(text)["format_version"] == 1
    back = load_model(path)
    for a, b in [(model.autoencoder.W_e, back.autoencoder.W_e), (model.autoencoder.W_d, back.autoencoder.W_d),
                 (model.Xi, back.Xi), (model.mask, back.mask)]:
        np.testing.assert_array_equal(a, b)
    assert back.library == model.library and back.phase_names == model.phase_names
    assert back.info["data_sha256"] == model.info["data_sha256"]
    j = ds.jumps_in("test")[:1]
    np.testing.assert_array_equal(rollout(model, ds, j).q_pred[0], rollout(back, ds, j).q_pred[0])
    assert back.equations_text() == model.equations_text()


@pytest.mark.parametrize("edit,needle", [
    (lambda d: d.update(format_version=7), "format_version"),
    (lambda d: d["encoder"].update(W_e=[[0.0] * 18]), "encoder.W_e"),
    (lambda d: d["phases"]["flight"].update(Xi=[[0.0]]), "phases.flight.Xi"),
    (lambda d: d["library"].update(poly_order=3), "library"),
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
