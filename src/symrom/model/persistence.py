"""The model file: versioned JSON, human-readable, no pickle (DESIGN.md, format_version 1)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from symrom.atomic import write_text_atomic
from symrom.model.autoencoder import LinearAutoencoder
from symrom.model.hybrid import HybridModel
from symrom.model.library import CandidateLibrary

FORMAT_VERSION = 1


class ModelFileError(ValueError):
    """A model file is unreadable or breaks the format; the message says what and where."""


def model_to_dict(model: HybridModel) -> dict:
    ae = model.autoencoder
    return {
        "format_version": FORMAT_VERSION,
        "latent_dim": model.latent_dim,
        "library": model.library.to_dict(),
        "encoder": {"W_e": ae.W_e.tolist(), "B_e": ae.B_e.tolist()},
        "decoder": {"W_d": ae.W_d.tolist(), "B_d": ae.B_d.tolist()},
        "latent_scale": model.latent_scale.tolist(),
        "phases": {name: {"Xi": model.Xi[k].tolist(), "mask": model.mask[k].astype(int).tolist(),
                          "active_terms": int(model.mask[k].sum())}
                   for k, name in enumerate(model.phase_names)},
        "phase_names": list(model.phase_names),
        "info": model.info,
    }


def save_model(model: HybridModel, path: str | os.PathLike) -> None:
    """Write ``model`` to ``path`` as JSON, atomically."""
    write_text_atomic(path, json.dumps(model_to_dict(model), indent=1, allow_nan=False))


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
    if d["format_version"] != FORMAT_VERSION:
        raise ModelFileError(f"format_version: {d['format_version']} is not supported "
                             f"(this symrom reads {FORMAT_VERSION})")
    try:
        lib = CandidateLibrary.from_dict(d["library"])
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
    Xi, mask = [], []
    for n in names:
        if n not in phases:
            raise ModelFileError(f"phases.{n}: missing")
        Xi.append(_array(phases[n], "Xi", f"phases.{n}", (p, l)))
        mask.append(_array(phases[n], "mask", f"phases.{n}", (p, l)).astype(bool))
    return HybridModel(ae, lib, names, np.array(Xi), np.array(mask),
                       _array(d, "latent_scale", "model", (2 * l,)), dict(d.get("info", {})))


def load_model(path: str | os.PathLike) -> HybridModel:
    """Read and check a model file; raise ``ModelFileError`` with one clear message."""
    path = Path(path)
    if not path.is_file():
        raise ModelFileError(f"{path}: no such file")
    try:
        d = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ModelFileError(f"{path}: not valid JSON ({e})") from None
    return model_from_dict(d)
