"""The command line on bad input: one line naming the problem, no traceback, no output written."""

from __future__ import annotations

import json
import os
import shutil
import stat

import h5py
import numpy as np
import pytest
from conftest import one_line_error
from typer.testing import CliRunner

from symrom.cli import app
from symrom.data.io import write_dataset
from symrom.model.persistence import FORMAT_VERSION
from symrom.testing import make_planted_dataset

N_PER_JUMP = 80
runner = CliRunner()


def _run(*args: str):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    ds, _ = make_planted_dataset(n_jumps=4, n_samples=N_PER_JUMP, seed=7)
    path = tmp_path_factory.mktemp("data") / "good.h5"
    write_dataset(ds, path)
    return path


@pytest.fixture(scope="module")
def model(good, tmp_path_factory):
    out = tmp_path_factory.mktemp("runs") / "run"
    r = _run("train", good, "--out", out)
    assert r.exit_code == 0, r.output
    return out / "model.json"


def _set(key, row, col, value):
    def edit(f):
        arr = f[key][()]
        arr[row, col] = value
        del f[key]
        f.create_dataset(key, data=arr)
    return edit


def _shape(f):
    arr = f["q"][()][:, :17]
    del f["q"]
    f.create_dataset("q", data=arr)


def _t_back(f):
    t = f["t"][()]
    t[N_PER_JUMP + 5] = -1.0
    del f["t"]
    f.create_dataset("t", data=t)


def _version(f):
    f.attrs["schema_version"] = 7


CORRUPTIONS = {
    "nan": (_set("q", N_PER_JUMP + 3, 2, np.nan), ["'q'", "non-finite", "jump 1", f"row {N_PER_JUMP + 3}"]),
    "shape": (_shape, ["'q'", "shape", "17"]),
    "missing": (lambda f: f.__delitem__("ddq"), ["'ddq'", "missing"]),
    "t_back": (_t_back, ["'t'", "jump 1", f"row {N_PER_JUMP + 5}"]),
    "flag3": (_set("contact", 9, 1, 3), ["'contact'", "flag 3", "jump 0", "row 9"]),
    "version": (_version, ["schema_version", "7"]),
}


@pytest.mark.parametrize("kind", [*CORRUPTIONS, "truncated", "not_hdf5"])
def test_train_on_corrupt_data(kind, good, tmp_path):
    bad = tmp_path / f"{kind}.h5"
    if kind == "truncated":
        bad.write_bytes(good.read_bytes()[:4000])
        needles = [bad.name, "HDF5"]
    elif kind == "not_hdf5":
        bad.write_text("this is not a dataset\n")
        needles = [bad.name, "HDF5"]
    else:
        shutil.copy(good, bad)
        edit, needles = CORRUPTIONS[kind]
        with h5py.File(bad, "r+") as f:
            edit(f)
    out = tmp_path / "run"
    one_line_error(_run("train", bad, "--out", out), *needles)
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == [bad.name]


def test_train_does_not_overwrite_without_force(good, tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / "keep.txt").write_text("precious")
    one_line_error(_run("train", good, "--out", out), str(out), "--force")
    assert [p.name for p in out.iterdir()] == ["keep.txt"]
    assert (out / "keep.txt").read_text() == "precious"
    r = _run("train", good, "--out", out, "--force")
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in out.iterdir()) == ["equations.txt", "model.json"]
    assert json.loads((out / "model.json").read_text())["format_version"] == FORMAT_VERSION


def _corrupt_model(model, tmp_path, edit):
    d = json.loads(model.read_text())
    edit(d)
    path = tmp_path / "model.json"
    path.write_text(json.dumps(d))
    return path


@pytest.mark.parametrize("kind", ["missing", "version", "W_e", "not_json"])
def test_evaluate_bad_model(kind, model, good, tmp_path):
    if kind == "missing":
        path, needles = tmp_path / "absent.json", ["absent.json", "no such file"]
    elif kind == "version":
        path = _corrupt_model(model, tmp_path, lambda d: d.update(format_version=9))
        needles = ["format_version", "9"]
    elif kind == "W_e":
        path = _corrupt_model(model, tmp_path, lambda d: d["encoder"].update(W_e=d["encoder"]["W_e"][:1]))
        needles = ["W_e", "shape", "(1, 18)"]
    else:
        path = tmp_path / "model.json"
        path.write_text("{not json")
        needles = ["model.json", "JSON"]
    out = tmp_path / "eval"
    one_line_error(_run("evaluate", path, good, "--out", out), *needles)
    assert not out.exists()


def test_evaluate_does_not_overwrite_without_force(model, good, tmp_path):
    out = tmp_path / "eval"
    out.mkdir()
    (out / "keep.txt").write_text("precious")
    one_line_error(_run("evaluate", model, good, "--out", out), "--force")
    assert [p.name for p in out.iterdir()] == ["keep.txt"]
    assert (out / "keep.txt").read_text() == "precious"


def test_evaluate_on_corrupt_data(model, good, tmp_path):
    bad = tmp_path / "bad.h5"
    shutil.copy(good, bad)
    with h5py.File(bad, "r+") as f:
        _set("contact", 9, 1, 3)(f)
    out = tmp_path / "eval"
    one_line_error(_run("evaluate", model, bad, "--out", out), "'contact'", "flag 3")
    assert not out.exists()


def _plain_log(path, drop=()):
    ds, _ = make_planted_dataset(n_jumps=2, n_samples=20, seed=1)
    from symrom.data.importers import write_plain_csv

    write_plain_csv(ds, path)
    if drop:
        rows = [line.split(",") for line in path.read_text().splitlines()]
        keep = [i for i, name in enumerate(rows[0]) if name not in drop]
        path.write_text("\n".join(",".join(r[i] for i in keep) for r in rows) + "\n")
    return path


def test_import_missing_column(tmp_path):
    log = _plain_log(tmp_path / "log.csv", drop=("pitch", "tau_rr_kn"))
    out = tmp_path / "real.h5"
    one_line_error(_run("import", log, "--robot", "go1", "--out", out),
                    "log.csv", "missing columns", "pitch", "tau_rr_kn")
    assert not out.exists()


def test_import_bad_cell(tmp_path):
    log = _plain_log(tmp_path / "log.csv")
    lines = log.read_text().splitlines()
    cells = lines[5].split(",")
    cells[3] = "1.2.3"
    lines[5] = ",".join(cells)
    log.write_text("\n".join(lines) + "\n")
    out = tmp_path / "real.h5"
    one_line_error(_run("import", log, "--robot", "go1", "--out", out),
                    "log.csv", "line 6", "'fr_hy'", "1.2.3")
    assert not out.exists()


@pytest.mark.parametrize("args, needles", [
    (["--robot", "spot"], ["unknown robot", "spot"]),
    (["--robot", "go1", "--split", "5,0,0"], ["--split", "5 jumps", "2"]),
    (["--robot", "go1", "--diff", "spline"], ["spline"]),
])
def test_import_bad_options(tmp_path, args, needles):
    log = _plain_log(tmp_path / "log.csv")
    out = tmp_path / "real.h5"
    one_line_error(_run("import", log, *args, "--out", out), *needles)
    assert not out.exists()


def test_import_missing_file(tmp_path):
    out = tmp_path / "real.h5"
    one_line_error(_run("import", tmp_path / "nope.csv", "--robot", "go1", "--out", out),
                    "nope.csv", "no such file")
    assert not out.exists()


def test_train_with_an_unknown_encoder_component(good, tmp_path):
    out = tmp_path / "run"
    one_line_error(_run("train", good, "--out", out, "--encoder-components", "x,heave"),
                   "encoder_components", "heave")
    assert not out.exists()


def test_output_folders_have_the_usual_permissions(good, tmp_path):
    old = os.umask(0o022)
    try:
        out = tmp_path / "run"
        assert _run("train", good, "--out", out).exit_code == 0
        assert stat.S_IMODE(out.stat().st_mode) == 0o755
        assert stat.S_IMODE((out / "model.json").stat().st_mode) == 0o644
    finally:
        os.umask(old)


def test_an_output_that_is_an_input_is_refused_even_with_force(good, model, tmp_path):
    data = tmp_path / "data.h5"
    shutil.copy(good, data)
    before = data.read_bytes()
    one_line_error(_run("train", data, "--out", data, "--force"), str(data), "is the input")
    assert data.read_bytes() == before
    run = tmp_path / "run"
    shutil.copytree(model.parent, run)
    one_line_error(_run("evaluate", run / "model.json", data, "--out", run, "--force"),
                   str(run), "holds the input", "model.json")
    assert (run / "model.json").read_text() == model.read_text()
    one_line_error(_run("newton", data, "--out", data, "--force"), "is the input")
    assert data.read_bytes() == before


@pytest.mark.parametrize("reset", ["0", "-0.1", "nan"])
def test_a_bad_reset_is_refused_before_any_work(model, good, tmp_path, reset):
    out = tmp_path / "eval"
    line = one_line_error(_run("evaluate", model, good, "--out", out, "--reset", reset), "--reset",
                          "positive number of seconds")
    assert "rollouts" not in line
    assert not out.exists()
    one_line_error(_run("newton", good, "--out", out, "--reset", reset), "--reset")


def test_an_unknown_motion_is_refused_on_import_and_in_a_dataset_file(good, tmp_path):
    bad = tmp_path / "bogus.h5"
    shutil.copy(good, bad)
    with h5py.File(bad, "r+") as f:
        f.attrs["motion"] = "bogus"
    out = tmp_path / "run"
    one_line_error(_run("train", bad, "--out", out), "attr 'motion'", "unknown motion 'bogus'")
    assert not out.exists()
    log = _plain_log(tmp_path / "log.csv")
    one_line_error(_run("import", log, "--robot", "go1", "--motion", "bogus", "--out", tmp_path / "x.h5"),
                   "unknown motion 'bogus'")
    assert not (tmp_path / "x.h5").exists()


def test_reproduce_only_an_unknown_part_is_refused_before_any_work(tmp_path):
    out = tmp_path / "run"
    one_line_error(_run("reproduce", "--out", out, "--only", "sweep"), "--only sweep", "sim2real")
    assert not out.exists()


def test_reproduce_a_term_budget_below_one_is_refused_before_any_work(tmp_path):
    out = tmp_path / "run"
    one_line_error(_run("reproduce", "--out", out, "--max-terms", "0"), "--max-terms", "0")
    assert not out.exists()
