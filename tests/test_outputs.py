"""The library writes the output folders: one writer per file, strict JSON."""

import json
import math

import pytest

from symrom.evaluate.outputs import write_baseline, write_json, write_metrics
from symrom.learn.training import TrainConfig, train
from symrom.model.persistence import load_model, write_model_files


def _strict(path):
    """The file's JSON, refusing the NaN and Infinity tokens."""
    def refuse(token):
        raise ValueError(f"{path.name}: {token} is not JSON")
    return json.loads(path.read_text(), parse_constant=refuse)


def _metrics(rmse: float) -> dict:
    comps = {c: {"mean": 0.0, "std": 0.0, "mae": rmse, "rmse": rmse} for c in ("x", "y", "z")}
    return {"format_version": 2, "model": "m", "data": "d", "split": "test", "n_jumps": 1, "integrator": "rk4",
            "horizons": {"full": {"diverged_jumps": 0, "diverged": [], "samples": 10, "scored_samples": 10,
                                  "components": comps}}}


def test_non_finite_numbers_are_written_as_null(tmp_path):
    paths = write_metrics(tmp_path, _metrics(math.nan), title="t", components=("x", "y", "z"))
    assert [p.name for p in paths] == ["metrics.json", "table.md"]
    back = _strict(tmp_path / "metrics.json")
    assert back["horizons"]["full"]["components"]["x"]["rmse"] is None
    assert _strict(write_json(tmp_path / "a.json", {"a": [1.0, math.inf, -math.inf]}))["a"] == [1.0, None, None]


def test_a_baseline_folder_holds_metrics_table_and_its_files(tmp_path):
    from symrom.baselines import from_params
    from symrom.baselines.newton import Newton

    written = write_baseline(tmp_path, Newton(12.0, "the given mass"), _metrics(0.5), "Newton")
    assert {p.name for p in written} == {"metrics.json", "table.md", "params.json"}
    assert "**Newton**" in (tmp_path / "table.md").read_text()
    assert _strict(tmp_path / "metrics.json")["horizons"]["full"]["components"]["z"]["rmse"] == 0.5
    params = _strict(tmp_path / "params.json")  # the one params.json format: the baseline's own record
    assert params["model"] == "newton" and params["m"] == 12.0 and params["source"] == "the given mass"
    assert from_params(params) == Newton(12.0)


def test_a_model_folder_holds_the_model_and_its_equations(planted_axis, tmp_path):
    ds, _ = planted_axis
    model = train(ds, TrainConfig())
    assert {p.name for p in write_model_files(model, tmp_path)} == {"model.json", "equations.txt"}
    assert (tmp_path / "equations.txt").read_text() == load_model(tmp_path / "model.json").equations().text() + "\n"


def test_the_model_file_itself_still_refuses_non_finite_numbers(planted_axis, tmp_path):
    from symrom.model.persistence import ModelFileError

    ds, _ = planted_axis
    model = train(ds, TrainConfig())
    model.Xi[0, 0, 0] = math.nan
    with pytest.raises(ModelFileError, match="not a finite number"):
        write_model_files(model, tmp_path)
    assert not (tmp_path / "model.json").exists() and not (tmp_path / "equations.txt").exists()
