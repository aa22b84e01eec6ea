"""The model file: versioned JSON, human-readable, no pickle (``docs/design.md``).

format_version 6 lets a guard hold no terms: a clock (``Guard.clock``), firing once
its ``min_dwell_s`` in the source phase has passed. Files of format 5 and older are
read as before.

format_version 5 replaces the untyped ``info`` object by ``provenance``
(``symrom.model.provenance.Provenance``: data, training, selection, fine-tuning,
extra). Files of format 4 and older are still read, their ``info`` read into the
same record (``Provenance.from_info``).

format_version 4 adds ``guards``: the learned contact switches
(``symrom.model.guards``), one record per transition; a model fitted without
them writes null. Files of format 3, 2 and 1 are still read, without guards.

format_version 3 adds ``estimator``: the configuration of the learner that
fitted the model, each plug-in a ``{"kind": ...}`` record (the encoder and
regressor settings that format 2 kept in ``info``). Files of format 2 and 1
are still read, their records taken from ``info``.

format_version 2 adds, per phase, whether it was trained, its operating point
and typical duration, the regressor's report (terms left out and why, the
sparsity path, the refinement) and, for readers, the stability diagnostics;
and the library as a list of term blocks. Files of format 1 are still read.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

from symrom.atomic import write_text_atomic
from symrom.model.autoencoder import LinearAutoencoder
from symrom.model.guards import Guard
from symrom.model.hybrid import HybridModel, PhaseInfo
from symrom.model.library import Library
from symrom.model.provenance import Provenance

FORMAT_VERSION = 6
READABLE_VERSIONS = (1, 2, 3, 4, 5, 6)
# what format 2 kept in ``info`` and format 3 keeps in ``estimator``
LEGACY_ESTIMATOR_KEYS = ("encoder", "regressor", "decoded_weight")


HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"  # the first bytes of every HDF5 file (a dataset)


class ModelFileError(ValueError):
    """A model file is unreadable or breaks the format; the message says what and where."""


def model_to_dict(model: HybridModel) -> dict:
    ae = model.autoencoder
    stab = {s.phase: s.to_dict() for s in model.stability()}
    return {
        "format_version": FORMAT_VERSION,
        "latent_dim": model.latent_dim,
        "library": model.library.to_dict(),
        "encoder": {"W_e": ae.W_e.tolist(), "B_e": ae.B_e.tolist()},
        "decoder": {"W_d": ae.W_d.tolist(), "B_d": ae.B_d.tolist()},
        "latent_scale": model.latent_scale.tolist(),
        "phases": {name: {"Xi": model.Xi[k].tolist(), "mask": model.mask[k].astype(int).tolist(),
                          "active_terms": int(model.mask[k].sum()),
                          **(model.phase_info[name].to_dict() if name in model.phase_info else {}),
                          **({"stability": stab[name]} if name in stab else {})}
                   for k, name in enumerate(model.phase_names)},
        "phase_names": list(model.phase_names),
        "estimator": model.estimator,
        "guards": None if model.guards is None else [g.to_dict() for g in model.guards],
        "provenance": model.provenance.to_dict(),
    }


def model_hash(model: HybridModel) -> str:
    """SHA-256 of the model's file content (the canonical JSON of ``model_to_dict``)."""
    text = json.dumps(model_to_dict(model), sort_keys=True, allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def _check_finite(model: HybridModel) -> None:
    """``ModelFileError`` naming the first array entry of ``model`` that is not finite."""
    ae = model.autoencoder
    arrays = [("encoder.W_e", ae.W_e), ("encoder.B_e", ae.B_e), ("decoder.W_d", ae.W_d),
              ("decoder.B_d", ae.B_d), ("latent_scale", model.latent_scale)]
    arrays += [(f"phases.{n}.Xi", model.Xi[k]) for k, n in enumerate(model.phase_names)]
    for key, arr in arrays:
        bad = np.argwhere(~np.isfinite(np.asarray(arr, dtype=float)))
        if bad.size:
            at = ", ".join(str(int(i)) for i in bad[0])
            raise ModelFileError(f"{key}[{at}]: {float(np.asarray(arr)[tuple(bad[0])])} is not a finite "
                                 "number (the fit diverged); the model is not saved")


def _non_finite_key(obj, where: str = "") -> str | None:
    """The key path of the first non-finite float in a JSON-ready ``obj``, or None."""
    if isinstance(obj, float):
        return None if np.isfinite(obj) else where or "model"
    items = obj.items() if isinstance(obj, dict) else enumerate(obj) if isinstance(obj, (list, tuple)) else ()
    for k, v in items:
        found = _non_finite_key(v, f"{where}.{k}" if where and isinstance(k, str) else
                                f"{where}[{k}]" if where else str(k))
        if found:
            return found
    return None


def save_model(model: HybridModel, path: str | os.PathLike) -> None:
    """Write ``model`` to ``path`` as JSON, atomically; ``ModelFileError`` naming the key of a
    value JSON cannot hold (NaN, infinity) instead of writing it."""
    _check_finite(model)
    d = model_to_dict(model)
    bad = _non_finite_key(d)
    if bad is not None:
        raise ModelFileError(f"{bad}: not a finite number; the model is not saved")
    write_text_atomic(path, json.dumps(d, indent=1, allow_nan=False))


def write_model_files(model: HybridModel, folder: str | os.PathLike) -> list[Path]:
    """A model folder's files in ``folder`` (which exists): ``model.json`` and
    ``equations.txt`` (the plain-text equations); the one writer of both. Returns the paths."""
    folder = Path(folder)
    save_model(model, folder / "model.json")
    write_text_atomic(folder / "equations.txt", model.equations().text() + "\n")
    return [folder / "model.json", folder / "equations.txt"]


def _array(d: dict, key: str, where: str, shape: tuple[int, ...]) -> np.ndarray:
    if key not in d:
        raise ModelFileError(f"{where}.{key}: missing")
    try:
        arr = np.asarray(d[key], dtype=float)
    except (TypeError, ValueError):
        raise ModelFileError(f"{where}.{key}: not a numeric array") from None
    if arr.shape != shape:
        raise ModelFileError(f"{where}.{key}: shape {arr.shape}, expected {shape}")
    if not np.isfinite(arr).all():
        raise ModelFileError(f"{where}.{key}: non-finite values")
    return arr


def model_from_dict(d: dict) -> HybridModel:
    if not isinstance(d, dict) or "format_version" not in d:
        raise ModelFileError("format_version: missing (not a symrom model file)")
    if d["format_version"] not in READABLE_VERSIONS:
        raise ModelFileError(f"format_version: {d['format_version']} is not supported "
                             f"(this symrom reads {', '.join(map(str, READABLE_VERSIONS))})")
    try:
        lib = Library.from_dict(d["library"])
        l = int(d["latent_dim"])
        names = [str(n) for n in d["phase_names"]]
        phases = d["phases"]
    except (KeyError, TypeError, ValueError) as e:
        raise ModelFileError(f"library/latent_dim/phases: {e}") from None
    if lib.latent_dim != l:
        raise ModelFileError(f"library.latent_dim {lib.latent_dim} != latent_dim {l}")
    p = lib.n_features
    ae = LinearAutoencoder(_array(d.get("encoder", {}), "W_e", "encoder", (l, 18)),
                           _array(d.get("encoder", {}), "B_e", "encoder", (l,)),
                           _array(d.get("decoder", {}), "W_d", "decoder", (18, l)),
                           _array(d.get("decoder", {}), "B_d", "decoder", (18,)))
    Xi, mask, info = [], [], {}
    record = dict(d.get("info", {})) if d["format_version"] < 5 else {}
    if d["format_version"] >= 5 and "provenance" not in d:
        raise ModelFileError("provenance: missing (format 5 records where the model comes from)")
    try:
        provenance = (Provenance.from_dict(d.get("provenance", {})) if d["format_version"] >= 5
                      else Provenance.from_info(record))
    except ValueError as e:
        raise ModelFileError(str(e)) from None
    if d["format_version"] >= 3:
        estimator = d.get("estimator")
        if estimator is None:
            raise ModelFileError("estimator: missing (format 3 records the learner's configuration)")
        if not isinstance(estimator, dict):
            raise ModelFileError(f"estimator: expected an object, got {estimator!r}")
    else:
        estimator = {k: record[k] for k in LEGACY_ESTIMATOR_KEYS if k in record}
        training = record.get("training") or {}
        for key, name in (("contact_phase", "contact_phase"), ("path_thresholds", "path")):
            if name in training:
                estimator[key] = training[name]
    guards = None
    if d["format_version"] >= 4:
        if "guards" not in d:
            raise ModelFileError("guards: missing (format 4 records the contact guards, or null)")
        if d["guards"] is not None:
            if not isinstance(d["guards"], list):
                raise ModelFileError(f"guards: expected a list, got {type(d['guards']).__name__}")
            try:
                guards = [Guard.from_dict(g, f"guards[{i}]") for i, g in enumerate(d["guards"])]
            except (ValueError, AttributeError) as e:
                raise ModelFileError(str(e)) from None
    for n in names:
        if n not in phases:
            raise ModelFileError(f"phases.{n}: missing")
        Xi.append(_array(phases[n], "Xi", f"phases.{n}", (p, l)))
        mask.append(_array(phases[n], "mask", f"phases.{n}", (p, l)).astype(bool))
        if "trained" in phases[n]:
            info[n] = _phase_info(phases[n], f"phases.{n}", l)
    try:
        return HybridModel(ae, lib, names, np.array(Xi), np.array(mask),
                           _array(d, "latent_scale", "model", (2 * l,)), provenance, info, dict(estimator), guards)
    except ValueError as e:
        raise ModelFileError(f"model: {e}") from None


def _phase_info(d: dict, where: str, l: int) -> PhaseInfo:
    op = d.get("operating_point")
    duration = d.get("duration_s")
    if duration is not None and not (isinstance(duration, (int, float)) and duration > 0):
        raise ModelFileError(f"{where}.duration_s: expected a positive number, got {duration!r}")
    return PhaseInfo(trained=bool(d["trained"]), n_rows=int(d.get("n_rows", 0)),
                     operating_point=None if op is None else _array(d, "operating_point", where, (3 * l,)),
                     duration_s=None if duration is None else float(duration),
                     report=dict(d.get("report", {})))


def load_model(path: str | os.PathLike) -> HybridModel:
    """Read and check a model file; raise ``ModelFileError`` with one clear message."""
    path = Path(path)
    if path.is_dir():
        inside = " (it holds model.json: give that file)" if (path / "model.json").is_file() else ""
        raise ModelFileError(f"{path}: a folder, not a model file (model.json){inside}")
    if not path.is_file():
        raise ModelFileError(f"{path}: no such file")
    if path.open("rb").read(len(HDF5_SIGNATURE)) == HDF5_SIGNATURE:
        raise ModelFileError(f"{path}: a dataset file (HDF5), not a model file (model.json)")
    try:
        d = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ModelFileError(f"{path}: not a model file: not valid JSON ({e})") from None
    return model_from_dict(d)
