"""Typed records of a run: metrics (``metrics.json``) and the manifest of ``summary.json``.

``Metrics.from_dict`` reads the metrics layout of docs/design.md and fails
with one ``RecordError`` naming the key; fields it does not know are kept and
written back by ``to_dict``. It reads every version: per horizon an optional
``diverged`` list (``{"jump": int, "t": float}``, the time in s at which a
diverged rollout left its bound), components that are a subset of the 18 (a
baseline reports only ``x, y, z``) and, from ``format_version`` 2 on (files
without it are version 1), ``samples`` and ``scored_samples``: a diverged
jump's samples up to its divergence are scored (version 1 left it out).
From version 3 on a horizon also lists the jumps that drifted (``drifted``:
``{"jump", "t", "component", "value", "limit"}``, the first time a predicted
base coordinate left the physically possible, see ``evaluate.metrics``);
files before it did not check (``drifted_jumps`` None).

``ManifestEntry`` is one experiment of a run: its name, its role (what kind of
result it is, which decides how the report shows it) and its files.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

# metrics.json: 1 without the key (diverged jumps left out), 2 scores them, 3 adds drift
METRICS_VERSIONS = (1, 2, 3)


class RecordError(ValueError):
    """A metrics or manifest record breaks its layout; the message names the key."""


def _key(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


def _get(d: Any, key: str, where: str, kind: type | tuple[type, ...], default: Any = ...) -> Any:
    """``d[key]`` checked to be of ``kind`` (ints pass as floats); ``where`` is d's own key."""
    if not isinstance(d, dict):
        raise RecordError(f"{where or 'record'}: expected an object, got {type(d).__name__}")
    if key not in d:
        if default is ...:
            raise RecordError(f"{_key(where, key)}: missing")
        return default
    v = d[key]
    if kind is float and isinstance(v, int) and not isinstance(v, bool):
        v = float(v)
    if not isinstance(v, kind) or (isinstance(v, bool) and kind is not bool):
        raise RecordError(f"{_key(where, key)}: expected {getattr(kind, '__name__', 'a string or null')}, got {v!r}")
    return v


def _rest(d: dict, known: tuple[str, ...]) -> dict:
    return {k: v for k, v in d.items() if k not in known}


# ------------------------------------------------------------------ metrics
@dataclass(frozen=True)
class ComponentStats:
    """Signed error predicted - true of one component over a split: mean, std, MAE, RMSE
    (units of the component)."""

    mean: float
    std: float
    mae: float
    rmse: float

    @classmethod
    def from_dict(cls, d: Any, where: str) -> ComponentStats:
        return cls(*(_get(d, k, where, float) for k in ("mean", "std", "mae", "rmse")))

    def to_dict(self) -> dict[str, float]:
        return {"mean": self.mean, "std": self.std, "mae": self.mae, "rmse": self.rmse}


@dataclass(frozen=True)
class Divergence:
    """A rollout of jump ``jump`` left its bound ``t`` s after the jump's first sample."""

    jump: int
    t: float


@dataclass(frozen=True)
class Drift:
    """A rollout of jump ``jump`` left the physically possible ``t`` s after the jump's first
    sample: its predicted ``component`` (``x``, ``y`` or ``z``) was ``value`` m, past
    ``limit`` m (below the ground by more than a leg length, or beyond the jump's range)."""

    jump: int
    t: float
    component: str
    value: float
    limit: float

    @classmethod
    def from_dict(cls, d: Any, where: str) -> Drift:
        return cls(_get(d, "jump", where, int), _get(d, "t", where, float), _get(d, "component", where, str),
                   _get(d, "value", where, float), _get(d, "limit", where, float))

    def to_dict(self) -> dict:
        return {"jump": self.jump, "t": self.t, "component": self.component, "value": self.value,
                "limit": self.limit}

    def text(self) -> str:
        """e.g. 'jump 4 at 0.512 s (z -0.91 m past -0.43 m)'."""
        return f"jump {self.jump} at {self.t:.3f} s ({self.component} {self.value:.2f} m past {self.limit:.2f} m)"


@dataclass(frozen=True)
class Horizon:
    """One horizon's results: the jumps that diverged (each scored up to its divergence from
    version 2 on, left out before), the split's samples and how many were scored (None in
    version 1 files), the per-component stats (empty when nothing could be scored) and
    the jumps that drifted (still scored; ``drifted_jumps`` None before version 3)."""

    diverged_jumps: int
    components: dict[str, ComponentStats]
    diverged: tuple[Divergence, ...] = ()
    samples: int | None = None
    scored_samples: int | None = None
    drifted_jumps: int | None = None
    drifted: tuple[Drift, ...] = ()
    extra: dict = field(default_factory=dict)

    _KEYS = ("diverged_jumps", "components", "diverged", "samples", "scored_samples", "drifted_jumps", "drifted")

    @classmethod
    def from_dict(cls, d: Any, where: str) -> Horizon:
        comps = _get(d, "components", where, dict)
        div = _get(d, "diverged", where, list, [])
        return cls(diverged_jumps=_get(d, "diverged_jumps", where, int),
                   components={c: ComponentStats.from_dict(s, _key(where, f"components.{c}"))
                               for c, s in comps.items()},
                   diverged=tuple(Divergence(_get(x, "jump", _key(where, f"diverged[{i}]"), int),
                                             _get(x, "t", _key(where, f"diverged[{i}]"), float))
                                  for i, x in enumerate(div)),
                   samples=_get(d, "samples", where, (int, type(None)), None),
                   scored_samples=_get(d, "scored_samples", where, (int, type(None)), None),
                   drifted_jumps=_get(d, "drifted_jumps", where, (int, type(None)), None),
                   drifted=tuple(Drift.from_dict(x, _key(where, f"drifted[{i}]"))
                                 for i, x in enumerate(_get(d, "drifted", where, list, []))),
                   extra=_rest(d, cls._KEYS))

    def to_dict(self) -> dict:
        d: dict[str, Any] = {"diverged_jumps": self.diverged_jumps,
                             "diverged": [{"jump": x.jump, "t": x.t} for x in self.diverged]}
        if self.drifted_jumps is not None:
            d["drifted_jumps"] = self.drifted_jumps
            d["drifted"] = [x.to_dict() for x in self.drifted]
        if self.samples is not None:
            d["samples"] = self.samples
        if self.scored_samples is not None:
            d["scored_samples"] = self.scored_samples
        d["components"] = {c: s.to_dict() for c, s in self.components.items()}
        return d | self.extra

    def divergence_text(self) -> str:
        """When each diverged jump left its bound, e.g. 'jump 4 at 1.438 s' ('' if none)."""
        return ", ".join(f"jump {x.jump} at {x.t:.3f} s" for x in self.diverged)

    def drift_text(self) -> str:
        """When and how each drifted jump left the physically possible ('' if none)."""
        return ", ".join(x.text() for x in self.drifted)

    @property
    def scored_fraction(self) -> float | None:
        """The share of the split's samples the statistics cover (None if not recorded)."""
        if not self.samples or self.scored_samples is None:
            return None
        return self.scored_samples / self.samples

    def stat(self, component: str, name: str) -> float | None:
        """One statistic (``mean``, ``std``, ``mae``, ``rmse``) of a component, None if absent."""
        s = self.components.get(component)
        return None if s is None else getattr(s, name)


@dataclass(frozen=True)
class Metrics:
    """The contents of a ``metrics.json`` (docs/design.md, "Metrics file"): what
    ``symrom.evaluate.metrics.evaluate_model`` returns.

    horizons: ``full`` and reset periods in s as text (``0.1``), in file order; drift_limits:
    what a rollout may not do unflagged (``DriftLimits.to_dict``; version 3 on); phases: the
    phase sequence rolled out (``logged`` or ``predicted``); switching: with predicted
    phases, the switching-time errors per transition (``symrom.evaluate.switching``).
    ``to_dict`` gives the file's object, in the file's key order.
    """

    n_jumps: int
    horizons: dict[str, Horizon]
    split: str = "test"
    model: str = ""
    data: str = ""
    integrator: str | None = None
    format_version: int = 1
    drift_limits: dict | None = None
    phases: str | None = None
    switching: dict | None = None
    extra: dict = field(default_factory=dict)

    _KEYS = ("n_jumps", "horizons", "split", "model", "data", "integrator", "format_version", "drift_limits",
             "phases", "switching")

    @classmethod
    def from_dict(cls, d: Any, where: str = "metrics") -> Metrics:
        hs = _get(d, "horizons", where, dict)
        version = _get(d, "format_version", where, int, 1)
        if version not in METRICS_VERSIONS:
            raise RecordError(f"{_key(where, 'format_version')}: {version} is not supported "
                              f"(this symrom reads {', '.join(map(str, METRICS_VERSIONS))})")
        return cls(format_version=version, n_jumps=_get(d, "n_jumps", where, int),
                   horizons={k: Horizon.from_dict(h, _key(where, f"horizons.{k}")) for k, h in hs.items()},
                   split=_get(d, "split", where, str, "test"), model=_get(d, "model", where, str, ""),
                   data=_get(d, "data", where, str, ""),
                   integrator=_get(d, "integrator", where, (str, type(None)), None),
                   drift_limits=_get(d, "drift_limits", where, (dict, type(None)), None),
                   phases=_get(d, "phases", where, (str, type(None)), None),
                   switching=_get(d, "switching", where, (dict, type(None)), None), extra=_rest(d, cls._KEYS))

    @classmethod
    def read(cls, path: str | os.PathLike) -> Metrics:
        """A metrics file; ``RecordError`` naming the file and the key if it is not one."""
        try:
            d = json.loads(Path(path).read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
            raise RecordError(f"{path}: unreadable ({e.__class__.__name__})") from None
        try:
            return cls.from_dict(d, "")
        except RecordError as e:
            raise RecordError(f"{path}: key {e}") from None

    def to_dict(self) -> dict:
        d: dict[str, Any] = {"format_version": self.format_version} if self.format_version > 1 else {}
        d |= {"model": self.model, "data": self.data, "split": self.split, "n_jumps": self.n_jumps}
        if self.integrator is not None:
            d["integrator"] = self.integrator
        if self.drift_limits is not None:
            d["drift_limits"] = self.drift_limits
        if self.phases is not None:
            d["phases"] = self.phases
        d["horizons"] = {k: h.to_dict() for k, h in self.horizons.items()}
        if self.switching is not None:
            d["switching"] = self.switching
        return d | self.extra

    @property
    def full(self) -> Horizon:
        """The full-horizon results."""
        return self.horizons["full"]

    def rmse(self, component: str, horizon: str = "full") -> float | None:
        """The RMSE of ``component`` at ``horizon`` (None if nothing was scored)."""
        return self.horizons[horizon].stat(component, "rmse")

    def warnings(self) -> list[str]:
        """One line per horizon with drifted jumps (which, when, the limit passed) and one per
        horizon with diverged jumps (which, when, what was scored)."""
        out = []
        for key, h in self.horizons.items():
            if h.drifted_jumps:
                out.append(f"{h.drifted_jumps} of {self.n_jumps} jumps drifted at horizon {key} ({h.drift_text()}): "
                           "the predicted base left the physically possible (below the ground by more than a leg "
                           "length, or beyond the jump's range); they are scored")
            if h.diverged_jumps:
                share = (f" ({100 * h.scored_samples / h.samples:.1f} % of the split's samples)"
                         if h.samples and h.scored_samples is not None else "")
                out.append(f"{h.diverged_jumps} of {self.n_jumps} jumps diverged at horizon {key} "
                           f"({h.divergence_text()}); each is scored up to its divergence{share}")
        return out

    @property
    def any_diverged(self) -> bool:
        return any(h.diverged_jumps for h in self.horizons.values())

    @property
    def any_drifted(self) -> bool:
        return any(h.drifted_jumps for h in self.horizons.values())

    @property
    def scores_diverged(self) -> bool:
        """Whether a diverged jump's samples up to its divergence are in the stats (version 2 on)."""
        return self.format_version >= 2

    def diverged_text(self, label=lambda key: key) -> str:
        """One line naming the diverged jumps per horizon and when each diverged, e.g.
        'full: 1 of 6 (jump 4 at 1.438 s), 0.1: 0 of 6'."""
        return ", ".join(f"{label(k)}: {h.diverged_jumps} of {self.n_jumps}"
                         + (f" ({h.divergence_text()})" if h.diverged else "") for k, h in self.horizons.items())


# ------------------------------------------------------------------ manifest
# Roles of the experiments a run may hold; the report has a renderer per role.
LEARNED = "learned"  # a model trained on a dataset and evaluated on its test split
BASELINE = "baseline"  # a reference model (aSLIP ...) evaluated on the same jumps as ``of``
FINE_TUNED = "fine_tuned"  # a learned model adapted to new data; ``files.before``: the source model's metrics
SWEEP = "sweep"  # the latent-dimension trade-off; ``files.result``: sweep.json
SOLVER = "solver"  # one solver's training of the ``of`` experiment, for the solver comparison
SELECTION = "selection"  # the validation selection of the ``of`` experiment; ``files.table``: selection.json


@dataclass(frozen=True)
class ManifestEntry:
    """One experiment of a run (an item of ``summary.json``'s ``manifest``).

    name: unique in the run (``go1_sim``, ``go1_sim/aslip``); role: what kind of
    result it is (``LEARNED`` ... or a role added later); title: for people;
    files: named paths relative to the run directory (``metrics``, ``model``,
    ``data``, ``params`` ...); of: the experiment it belongs to or is compared
    with; paper: the key of the paper's published numbers it is compared with;
    facts: small JSON-ready facts (training options, wall time ...).
    """

    name: str
    role: str
    title: str = ""
    files: dict[str, str] = field(default_factory=dict)
    of: str | None = None
    paper: str | None = None
    facts: dict = field(default_factory=dict)

    @classmethod
    def from_dict(cls, d: Any, where: str = "manifest") -> ManifestEntry:
        files = _get(d, "files", where, dict, {})
        for k, v in files.items():
            if not isinstance(v, str):
                raise RecordError(f"{where}.files.{k}: expected a path, got {v!r}")
        return cls(name=_get(d, "name", where, str), role=_get(d, "role", where, str),
                   title=_get(d, "title", where, str, ""), files=dict(files),
                   of=_get(d, "of", where, (str, type(None)), None),
                   paper=_get(d, "paper", where, (str, type(None)), None),
                   facts=_get(d, "facts", where, dict, {}))

    def to_dict(self) -> dict:
        d: dict[str, Any] = {"name": self.name, "role": self.role, "title": self.title or self.name,
                             "files": dict(self.files)}
        for k in ("of", "paper"):
            if getattr(self, k) is not None:
                d[k] = getattr(self, k)
        if self.facts:
            d["facts"] = self.facts
        return d


def read_manifest(items: Any, where: str = "summary.json: manifest") -> list[ManifestEntry]:
    """The manifest list of a ``summary.json``; names must be unique."""
    if not isinstance(items, list):
        raise RecordError(f"{where}: expected a list")
    entries = [ManifestEntry.from_dict(x, f"{where}[{i}]") for i, x in enumerate(items)]
    seen: set[str] = set()
    for e in entries:
        if e.name in seen:
            raise RecordError(f"{where}: name {e.name!r} appears twice")
        seen.add(e.name)
    return entries
