"""The one configuration vocabulary of the learner's plug-ins.

Every plug-in (an encoder, a regressor; the library's term blocks have theirs
in ``symrom.model.library``) is its own configuration: a dataclass with a
``kind`` name, ``to_dict()`` (JSON-ready, ``{"kind": ..., settings...}``) and
``from_dict``. This registry maps kinds back to classes, so a model file's
record restores the exact plug-ins, or is refused with one line naming the
key. Records of model files before format 3 named the class (``"name":
"STLSQ"``) instead of the kind; they are read too.
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any

from symrom.learn.adam import Adam, AdamConfig
from symrom.learn.encoders import AdamAutoencoder, PCAEncoder
from symrom.learn.regressors.base import Regressor
from symrom.learn.regressors.prior import FineTune
from symrom.learn.regressors.refine import Refine
from symrom.learn.regressors.stlsq import STLSQ

ENCODERS: dict[str, type] = {c.kind: c for c in (PCAEncoder, AdamAutoencoder)}
REGRESSORS: dict[str, type] = {c.kind: c for c in (STLSQ, FineTune, Refine, Adam)}
_LEGACY = {c.__name__: c.kind for c in (*ENCODERS.values(), *REGRESSORS.values())}  # format 2's "name"


class PluginConfigError(ValueError):
    """A plug-in record that names no known kind or holds a setting its kind does not have."""


def _settings(cls: type, d: dict, where: str) -> dict[str, Any]:
    """The init settings of ``cls`` in record ``d`` (its kind key left out); refuses unknown keys."""
    known = {f.name for f in fields(cls) if f.init and f.repr}
    body = {k: v for k, v in d.items() if k not in ("kind", "name")}
    unknown = sorted(set(body) - known)
    if unknown:
        raise PluginConfigError(f"{where}: {cls.kind!r} has no setting {', '.join(map(repr, unknown))} "
                                f"(its settings: {', '.join(sorted(known))})")
    return body


def _kind(d: Any, table: dict[str, type], where: str) -> type:
    if not isinstance(d, dict):
        raise PluginConfigError(f"{where}: expected a record {{'kind': ...}}, got {d!r}")
    kind = d.get("kind", _LEGACY.get(d.get("name", "")))
    if kind not in table:
        raise PluginConfigError(f"{where}: unknown kind {d.get('kind', d.get('name'))!r} "
                                f"(known: {', '.join(table)})")
    return table[kind]


def encoder_from_dict(d: dict, where: str = "encoder") -> PCAEncoder | AdamAutoencoder:
    """The encoder a ``to_dict`` record describes; ``PluginConfigError`` naming ``where``."""
    cls = _kind(d, ENCODERS, where)
    body = _settings(cls, d, where)
    if "components" in body and body["components"] is not None:
        body["components"] = tuple(body["components"])
    if "config" in body:
        body["config"] = AdamConfig(**body["config"])
    try:
        return cls(**body)
    except (TypeError, ValueError) as e:
        raise PluginConfigError(f"{where}: {e}") from None


def regressor_from_dict(d: dict, where: str = "regressor") -> Regressor:
    """The regressor a ``to_dict`` record describes (nested ones too); ``PluginConfigError``."""
    cls = _kind(d, REGRESSORS, where)
    body = _settings(cls, d, where)
    if cls is Refine:
        body.setdefault("acceleration_weight", 0.0)  # a record from before the terms: rollouts alone
        body.setdefault("momentum_weight", 0.0)
        if body.get("max_terms") is not None:
            body.setdefault("after_pruning", "schedule")  # a record from before the setting
        if "initial" in body:
            body["initial"] = regressor_from_dict(body["initial"], f"{where}.initial")
        if "windows" in body:
            body["windows"] = tuple(body["windows"])
        for key in ("hold", "keep", "polish", "polish_windows"):
            if key in body:
                body[key] = tuple(body[key])
    if cls is Adam and "config" in body:
        body["config"] = AdamConfig(**body["config"])
    try:
        return cls(**body)
    except (TypeError, ValueError) as e:
        raise PluginConfigError(f"{where}: {e}") from None
