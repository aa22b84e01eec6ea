"""HDF5 read/write of the dataset file (schema_version 1)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from symrom.atomic import write_with
from symrom.data.dataset import OPTIONAL_KEYS, ROW_KEYS, SCHEMA_VERSION, Dataset, DatasetError, validate

_DTYPES = {"jump": np.int32, "phase": np.int8, "contact": np.uint8}


def write_dataset(ds: Dataset, path: str | os.PathLike) -> None:
    """Validate ``ds`` and write it to ``path`` atomically (HDF5)."""
    import h5py

    validate(ds)

    def _write(tmp: Path) -> None:
        with h5py.File(tmp, "w") as f:
            f.attrs["schema_version"] = SCHEMA_VERSION
            f.attrs["robot"] = ds.robot
            f.attrs["motion"] = ds.motion
            f.attrs["source"] = ds.source
            f.attrs["dt"] = float(ds.dt)
            f.attrs["phase_names"] = list(ds.phase_names)
            f.attrs["generator"] = ds.generator_json()
            for key in ROW_KEYS:
                arr = getattr(ds, key)
                if arr is None:
                    continue
                f.create_dataset(key, data=np.asarray(arr, dtype=_DTYPES.get(key, np.float64)),
                                 compression="gzip", compression_opts=4, shuffle=True)
            f.create_dataset("split", data=np.asarray(ds.split, dtype=object),
                             dtype=h5py.string_dtype())

    write_with(path, _write)


def _attr_str(f, name: str) -> str:
    if name not in f.attrs:
        raise DatasetError(f"attr {name!r}: missing")
    v = f.attrs[name]
    return v.decode() if isinstance(v, bytes) else str(v)


DATASET_SUFFIXES = (".h5", ".hdf5")


def check_dataset_path(path: str | os.PathLike, parameter: str = "out") -> Path:
    """``path`` as a dataset file's path: ``DatasetError`` naming ``parameter`` unless it ends in
    ``.h5`` or ``.hdf5`` (a dataset is HDF5, whatever else its name would say)."""
    path = Path(path)
    if path.suffix.lower() not in DATASET_SUFFIXES:
        raise DatasetError(f"{parameter}={path}: a dataset file is HDF5: name it {path.stem}.h5")
    return path


def read_dataset(path: str | os.PathLike) -> Dataset:
    """Read and validate a dataset file; raise ``DatasetError`` with one clear message."""
    import h5py

    path = Path(path)
    if path.is_dir():
        raise DatasetError(f"{path}: a folder, not a dataset file (HDF5, e.g. data/go1.h5)")
    if not path.is_file():
        raise DatasetError(f"{path}: no such file")
    head = path.open("rb").read(8)
    if head.lstrip()[:1] in (b"{", b"["):
        raise DatasetError(f"{path}: a JSON file, not a dataset file (HDF5); a model file goes where "
                           "MODEL.json is asked")
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise DatasetError(f"{path}: not a readable HDF5 file ({e.__class__.__name__})") from None
    try:
        with f:
            if "schema_version" not in f.attrs:
                raise DatasetError("attr 'schema_version': missing")
            version = int(f.attrs["schema_version"])
            if version != SCHEMA_VERSION:
                raise DatasetError(f"attr 'schema_version': {version} is not supported "
                                   f"(this symrom reads {SCHEMA_VERSION})")
            arrays = {}
            for key in (*ROW_KEYS, "split"):
                if key not in f:
                    if key in OPTIONAL_KEYS:
                        continue
                    raise DatasetError(f"key {key!r}: missing")
                try:
                    arrays[key] = f[key][()]
                except (OSError, KeyError) as e:
                    raise DatasetError(f"key {key!r}: unreadable ({e})") from None
            arrays["split"] = np.array([s.decode() if isinstance(s, bytes) else str(s)
                                        for s in np.atleast_1d(arrays["split"])], dtype=object)
            phase_names = [p.decode() if isinstance(p, bytes) else str(p)
                           for p in np.atleast_1d(f.attrs.get("phase_names", []))]
            try:
                generator = json.loads(_attr_str(f, "generator")) if "generator" in f.attrs else {}
            except json.JSONDecodeError:
                raise DatasetError("attr 'generator': not valid JSON") from None
            try:
                dt = float(f.attrs["dt"]) if "dt" in f.attrs else float("nan")
            except (TypeError, ValueError):
                raise DatasetError("attr 'dt': not a number") from None
            ds = Dataset(robot=_attr_str(f, "robot"), motion=_attr_str(f, "motion"),
                         source=_attr_str(f, "source"), phase_names=phase_names, dt=dt,
                         generator=generator, **arrays)
    except OSError as e:
        raise DatasetError(f"{path}: corrupt or truncated HDF5 file ({e})") from None
    validate(ds)
    return ds
