"""Every validation error of ``read_dataset``, the write round trip, and atomic writes."""

from __future__ import annotations

import os

import h5py
import numpy as np
import pytest

from symrom.data.dataset import DatasetError, jump_bounds
from symrom.data.io import read_dataset, write_dataset
from symrom.testing import make_planted_dataset

N_PER_JUMP = 40


@pytest.fixture(scope="module")
def dataset():
    ds, _ = make_planted_dataset(n_jumps=4, n_samples=N_PER_JUMP, seed=5)
    # Feet in the world frame, so the optional key is exercised too.
    ds.foot_pos = np.random.default_rng(0).normal(size=(ds.n_samples, 4, 3))
    return ds


@pytest.fixture
def good(tmp_path, dataset):
    path = tmp_path / "good.h5"
    write_dataset(dataset, path)
    return path


def _edit(path, fn):
    with h5py.File(path, "r+") as f:
        fn(f)
    return path


def _replace(f, key, arr):
    del f[key]
    f.create_dataset(key, data=arr)


def _row(jump: int, offset: int) -> int:
    return jump * N_PER_JUMP + offset


def _error(path) -> str:
    with pytest.raises(DatasetError) as e:
        read_dataset(path)
    msg = str(e.value)
    assert "\n" not in msg
    return msg


def test_round_trip_preserves_everything(good, dataset):
    ds = read_dataset(good)
    for key in ("jump", "t", "q", "dq", "ddq", "tau", "contact", "u", "phase", "foot_pos"):
        np.testing.assert_array_equal(getattr(ds, key), getattr(dataset, key), err_msg=key)
    assert list(ds.split) == list(dataset.split)
    assert (ds.robot, ds.motion, ds.source) == (dataset.robot, dataset.motion, dataset.source)
    assert ds.phase_names == dataset.phase_names and ds.dt == dataset.dt
    assert ds.generator == dataset.generator and ds.generator["equations"]
    with h5py.File(good) as f:
        assert f["jump"].dtype == np.int32 and f["phase"].dtype == np.int8
        assert f["contact"].dtype == np.uint8 and int(f.attrs["schema_version"]) == 1


def test_nan_names_key_jump_and_row(good):
    r = _row(2, 7)

    def put_nan(f):
        q = f["q"][()]
        q[r, 4] = np.nan
        _replace(f, "q", q)

    msg = _error(_edit(good, put_nan))
    assert "'q'" in msg and "jump 2" in msg and f"row {r}" in msg and "non-finite" in msg


def test_wrong_shape(good):
    msg = _error(_edit(good, lambda f: _replace(f, "dq", f["dq"][()][:, :17])))
    assert "'dq'" in msg and "(160, 17)" in msg and "(160, 18)" in msg


def test_missing_key(good):
    msg = _error(_edit(good, lambda f: f.__delitem__("tau")))
    assert "'tau'" in msg and "missing" in msg


def test_time_backwards(good):
    r = _row(1, 12)

    def back(f):
        t = f["t"][()]
        t[r] = t[r - 1] - 0.001
        _replace(f, "t", t)

    msg = _error(_edit(good, back))
    assert "'t'" in msg and "jump 1" in msg and f"row {r}" in msg


def test_contact_flag_3(good):
    r = _row(3, 2)

    def flag(f):
        c = f["contact"][()]
        c[r, 2] = 3
        _replace(f, "contact", c)

    msg = _error(_edit(good, flag))
    assert "'contact'" in msg and "flag 3" in msg and "jump 3" in msg and f"row {r}" in msg


def test_unknown_phase_index(good):
    r = _row(0, 30)

    def phase(f):
        p = f["phase"][()]
        p[r] = 5
        _replace(f, "phase", p)

    msg = _error(_edit(good, phase))
    assert "'phase'" in msg and "index 5" in msg and "jump 0" in msg and f"row {r}" in msg


def test_unknown_schema_version(good):
    def bump(f):
        f.attrs["schema_version"] = 2

    msg = _error(_edit(good, bump))
    assert "schema_version" in msg and "2" in msg


def test_split_of_wrong_length(good):
    msg = _error(_edit(good, lambda f: _replace(
        f, "split", np.array(["train"] * 3, dtype=h5py.string_dtype()))))
    assert "'split'" in msg and "(3,)" in msg and "(4,)" in msg


def test_unknown_split_name(good):
    msg = _error(_edit(good, lambda f: _replace(
        f, "split", np.array(["train", "dev", "val", "test"], dtype=h5py.string_dtype()))))
    assert "'split'" in msg and "'dev'" in msg and "jump 1" in msg


def test_truncated_file(good):
    data = good.read_bytes()
    good.write_bytes(data[: len(data) // 2])
    msg = _error(good)
    assert str(good) in msg and "HDF5" in msg


def test_non_hdf5_file(tmp_path):
    path = tmp_path / "notes.h5"
    path.write_text("jump,t\n0,0.0\n")
    msg = _error(path)
    assert str(path) in msg and "HDF5" in msg


def test_no_such_file(tmp_path):
    assert "no such file" in _error(tmp_path / "absent.h5")


def _same_bytes_and_no_leftovers(path, before, directory):
    assert path.read_bytes() == before
    assert sorted(os.listdir(directory)) == [path.name]


def test_invalid_dataset_is_not_written(tmp_path, dataset):
    bad = dataset.select_jumps([0, 1])
    bad.q = bad.q.copy()
    bad.q[3, 0] = np.inf
    path = tmp_path / "new.h5"
    with pytest.raises(DatasetError, match="'q'"):
        write_dataset(bad, path)
    assert not path.exists() and os.listdir(tmp_path) == []
    write_dataset(dataset, path)
    before = path.read_bytes()
    with pytest.raises(DatasetError):
        write_dataset(bad, path)
    _same_bytes_and_no_leftovers(path, before, tmp_path)


def test_failure_mid_write_leaves_no_file(tmp_path, dataset, monkeypatch):
    path = tmp_path / "out.h5"
    real = h5py.Group.create_dataset

    def failing(self, name, *args, **kwargs):
        if name == "ddq":
            raise OSError("disk full")
        return real(self, name, *args, **kwargs)

    monkeypatch.setattr(h5py.Group, "create_dataset", failing)
    with pytest.raises(OSError, match="disk full"):
        write_dataset(dataset, path)
    assert os.listdir(tmp_path) == []
    monkeypatch.setattr(h5py.Group, "create_dataset", real)
    write_dataset(dataset.select_jumps([0]), path)
    before = path.read_bytes()
    monkeypatch.setattr(h5py.Group, "create_dataset", failing)
    with pytest.raises(OSError, match="disk full"):
        write_dataset(dataset, path)
    _same_bytes_and_no_leftovers(path, before, tmp_path)
    monkeypatch.setattr(h5py.Group, "create_dataset", real)
    assert read_dataset(path).n_jumps == 1


def test_jump_bounds_contiguous_blocks():
    np.testing.assert_array_equal(jump_bounds(np.array([0, 0, 1, 1, 1, 2])),
                                  [[0, 2], [2, 5], [5, 6]])
