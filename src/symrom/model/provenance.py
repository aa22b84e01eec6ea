"""``Provenance``: where a model comes from, as an immutable typed value.

A fitted model carries one (``HybridModel.provenance``); its file keeps it as the
``provenance`` object (model file format 5). Four parts, each written by the one step that
knows it:

- ``data`` (``DataRecord``): the data it was fitted on: robot, motion, source, period,
  joint layout, the hash of the arrays, the file and how many rows and jumps trained it
  (``SymbolicROM.fit``; the file by ``train_into``, ``select_into``, ``finetune_into``);
- ``training`` (``TrainingRecord``): how: the flat settings it was made from (a
  ``TrainConfig``'s fields; ``symrom.learn.training.TrainConfig.from_provenance`` reads them
  back), what the encoder was fitted on, the training latents' mean and spread, the phases
  without training rows, the wall time;
- ``selection`` (``SelectionRecord``): the validation selection's choice, if it was chosen
  by one (``symrom.experiments.select``);
- ``finetune`` (``FineTuneRecord``): the fine-tuning that adapted it, if any
  (``symrom.learn.finetune``, checked by ``symrom.experiments.finetune``).

Every part is a frozen dataclass; nested records (settings, the regressor's and the
calibration's records) are read-only mappings and tuples. ``with_`` methods return a new
value. ``from_info`` reads the untyped ``info`` object of model files of format 1-4, keys it
does not know kept in ``extra``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from types import MappingProxyType
from typing import Any


def freeze(obj: Any) -> Any:
    """A JSON-ready value made read-only: dicts as read-only mappings, lists as tuples."""
    if isinstance(obj, Mapping):
        return MappingProxyType({k: freeze(v) for k, v in obj.items()})
    if isinstance(obj, (list, tuple)):
        return tuple(freeze(v) for v in obj)
    return obj


def thaw(obj: Any) -> Any:
    """``freeze`` undone: plain dicts and lists, ready for JSON."""
    if isinstance(obj, Mapping):
        return {k: thaw(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [thaw(v) for v in obj]
    return obj


class _Record:
    """What the parts share: ``to_dict`` (JSON-ready, every field) and ``from_dict`` (unknown
    keys refused with the key named)."""

    def to_dict(self) -> dict[str, Any]:
        return {f.name: thaw(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None, where: str = ""):
        if d is None:
            return None
        if not isinstance(d, Mapping):
            raise ValueError(f"{where}: expected an object, got {type(d).__name__}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(f"{where}.{unknown[0]}: not a key of {cls.__name__}")
        return cls(**{k: freeze(v) for k, v in d.items()})


@dataclass(frozen=True)
class DataRecord(_Record):
    """The data a model was fitted on: robot (its key: a built-in name or a description file),
    motion, source (``sim``, ``proxy``, ``hardware`` ...), sample period ``dt`` (s), joint
    layout ``q_names``, ``sha256`` of the arrays (``symrom.learn.estimator.data_hash``), the
    file it was read from (``path``; None when not from a file), the training rows and
    jumps, and what those jumps did (``envelope``: ``symrom.data.envelope.jump_envelope``, the
    part of a planner's reach the data vouch for). None: not recorded."""

    robot: str | None = None
    motion: str | None = None
    source: str | None = None
    dt: float | None = None
    q_names: tuple[str, ...] | None = None
    sha256: str | None = None
    path: str | None = None
    train_rows: int | None = None
    train_jumps: int | None = None
    envelope: Mapping[str, Any] | None = None


@dataclass(frozen=True)
class TrainingRecord(_Record):
    """How a model was trained: ``settings``, the flat settings it was made from (a
    ``TrainConfig``'s fields; None when fitted by a ``SymbolicROM`` built by hand, whose
    plug-ins the model file's ``estimator`` holds anyway); ``encoder_rows``: what step (a)
    was fitted on, in words; ``latent_mean``, ``latent_spread`` (l,): the training latents'
    mean and standard deviation; ``untrained_phases``: phases without training rows;
    ``wall_time_s``: how long training took, s (None: not measured)."""

    settings: Mapping[str, Any] | None = None
    encoder_rows: str | None = None
    latent_mean: tuple[float, ...] | None = None
    latent_spread: tuple[float, ...] | None = None
    untrained_phases: tuple[str, ...] = ()
    wall_time_s: float | None = None

    @property
    def solver(self) -> str | None:
        return None if self.settings is None else self.settings.get("solver")

    @property
    def seed(self) -> int | None:
        return None if self.settings is None else self.settings.get("seed")


@dataclass(frozen=True)
class SelectionRecord(_Record):
    """The validation selection's choice: the candidate's encoder, latent dimension, library,
    threshold and refinement, its val score and active terms (``symrom.experiments.select``)."""

    encoder: str
    latent_dim: int
    library: str
    threshold: float
    refine: bool
    score: float
    active_terms: int


@dataclass(frozen=True)
class FineTuneRecord(_Record):
    """A fine-tuning (``symrom.learn.finetune``): its ``config`` (a ``FineTuneConfig``'s fields),
    the regressor's record, the new data (``data_sha256``, ``source``, ``path``, ``n_rows`` and
    ``rows_per_phase``), the source model's data hash and file (``base_data_sha256``,
    ``source_model``), which phases were refit, kept and refined on rollouts, the decoder's
    refit, the calibration's record, the decoded flight acceleration (``flight_gravity``) and
    the val check that accepted it (``check``; None before it is checked)."""

    config: Mapping[str, Any]
    regressor: Mapping[str, Any] | None = None
    data_sha256: str | None = None
    source: str | None = None
    n_rows: int | None = None
    base_data_sha256: str | None = None
    phases_refit: tuple[str, ...] = ()
    rows_per_phase: Mapping[str, int] = field(default_factory=lambda: MappingProxyType({}))
    phases_kept: tuple[str, ...] = ()
    phases_rolled_out: tuple[str, ...] = ()
    decoder: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    calibration: Mapping[str, Any] | None = None
    flight_gravity: Mapping[str, Any] | None = None
    check: Mapping[str, Any] | None = None
    source_model: str | None = None
    path: str | None = None


# info keys of model files of format 1-4, by the part that now holds them
_DATA_KEYS = {"robot": "robot", "motion": "motion", "source": "source", "dt": "dt", "q_names": "q_names",
              "data_sha256": "sha256", "data_path": "path", "n_train_rows": "train_rows",
              "n_train_jumps": "train_jumps", "envelope": "envelope"}
_TRAINING_KEYS = {"training": "settings", "encoder_rows": "encoder_rows", "latent_mean": "latent_mean",
                  "latent_spread": "latent_spread", "untrained_phases": "untrained_phases",
                  "wall_time_s": "wall_time_s"}
_REDUNDANT = ("solver", "seed")  # format 1-4 kept them beside ``training``, which holds them


@dataclass(frozen=True)
class Provenance:
    """Where a model comes from (module docstring): ``data``, ``training``, ``selection`` (None:
    not selected), ``finetune`` (None: not fine-tuned) and ``extra``: what an older file
    recorded that no part names (read-only)."""

    data: DataRecord = field(default_factory=DataRecord)
    training: TrainingRecord = field(default_factory=TrainingRecord)
    selection: SelectionRecord | None = None
    finetune: FineTuneRecord | None = None
    extra: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))

    # ------------------------------------------------------------ new values
    def with_data_path(self, path: str) -> Provenance:
        """The data's file (the fine-tuning's, for a fine-tuned model)."""
        if self.finetune is not None:
            return replace(self, finetune=replace(self.finetune, path=str(path)))
        return replace(self, data=replace(self.data, path=str(path)))

    def with_settings(self, settings: Mapping[str, Any] | None) -> Provenance:
        return replace(self, training=replace(self.training, settings=freeze(settings)))

    def with_wall_time(self, seconds: float) -> Provenance:
        return replace(self, training=replace(self.training, wall_time_s=float(seconds)))

    def with_selection(self, selection: SelectionRecord) -> Provenance:
        return replace(self, selection=selection)

    def with_finetune(self, finetune: FineTuneRecord | None = None, **changes: Any) -> Provenance:
        """``finetune`` recorded, or the present record with ``changes``."""
        if finetune is None:
            finetune = replace(self.finetune, **{k: freeze(v) for k, v in changes.items()})
        return replace(self, finetune=finetune)

    @property
    def data_path(self) -> str | None:
        """The file of the data the model last learned from: the fine-tuning's, else the training's."""
        if self.finetune is not None and self.finetune.path is not None:
            return self.finetune.path
        return self.data.path

    # ------------------------------------------------------------ the file
    def to_dict(self) -> dict[str, Any]:
        """The model file's ``provenance`` object (JSON-ready)."""
        return {"data": self.data.to_dict(), "training": self.training.to_dict(),
                "selection": None if self.selection is None else self.selection.to_dict(),
                "finetune": None if self.finetune is None else self.finetune.to_dict(),
                "extra": thaw(self.extra)}

    @classmethod
    def from_dict(cls, d: Any, where: str = "provenance") -> Provenance:
        """A model file's ``provenance`` object; ``ValueError`` naming the key that breaks it."""
        if not isinstance(d, Mapping):
            raise ValueError(f"{where}: expected an object, got {type(d).__name__}")
        unknown = sorted(set(d) - {"data", "training", "selection", "finetune", "extra"})
        if unknown:
            raise ValueError(f"{where}.{unknown[0]}: not a part of the provenance")
        try:
            return cls(DataRecord.from_dict(d.get("data") or {}, f"{where}.data"),
                       TrainingRecord.from_dict(d.get("training") or {}, f"{where}.training"),
                       SelectionRecord.from_dict(d.get("selection"), f"{where}.selection"),
                       FineTuneRecord.from_dict(d.get("finetune"), f"{where}.finetune"),
                       freeze(d.get("extra") or {}))
        except TypeError as e:  # a required key missing
            raise ValueError(f"{where}: {e}") from None

    def to_info(self) -> dict[str, Any]:
        """The ``info`` object a model file of format 1-4 held for this provenance (the inverse of
        ``from_info``): what a tool that reads the old files expects."""
        info = {old: thaw(getattr(self.data, new)) for old, new in _DATA_KEYS.items()
                if getattr(self.data, new) is not None}
        info |= {old: thaw(getattr(self.training, new)) for old, new in _TRAINING_KEYS.items()
                 if getattr(self.training, new) not in (None, ())}
        if self.training.settings is not None:
            info |= {k: self.training.settings[k] for k in _REDUNDANT if k in self.training.settings}
        if self.selection is not None:
            info["selection"] = self.selection.to_dict()
        if self.finetune is not None:
            ft = self.finetune.to_dict()
            if ft.pop("path", None) is not None:
                info["data_path"] = self.finetune.path
            info["finetune"] = {k: v for k, v in ft.items() if v is not None}
        return info | thaw(self.extra)

    @classmethod
    def from_info(cls, info: Mapping[str, Any], where: str = "info") -> Provenance:
        """The ``info`` object of a model file of format 1-4 (untyped: what training, the
        selection, the fine-tuning and the command line wrote there)."""
        info = dict(info or {})
        data = {new: info.pop(old) for old, new in _DATA_KEYS.items() if old in info}
        training = {new: info.pop(old) for old, new in _TRAINING_KEYS.items() if old in info}
        for key in _REDUNDANT:
            if key in info and (training.get("settings") or {}).get(key) == info[key]:
                info.pop(key)
        selection, finetune = info.pop("selection", None), info.pop("finetune", None)
        if isinstance(finetune, Mapping) and "source_model" in finetune and "path" in data:
            # format 1-4 kept one data_path; ``symrom finetune`` (which records the source model)
            # set it to the fine-tuning data's
            finetune = {**finetune, "path": data.pop("path")}
        sel = None
        if isinstance(selection, Mapping):
            try:
                sel = SelectionRecord.from_dict(selection, f"{where}.selection")
            except (ValueError, TypeError):
                info["selection"] = selection
        ft = None
        if isinstance(finetune, Mapping):
            try:
                ft = FineTuneRecord.from_dict(finetune, f"{where}.finetune")
            except (ValueError, TypeError):
                info["finetune"] = finetune
        try:
            return cls(DataRecord.from_dict(data, f"{where}.data"),
                       TrainingRecord.from_dict(training, f"{where}.training"), sel, ft, freeze(info))
        except (ValueError, TypeError) as e:
            raise ValueError(f"{where}: {e}") from None
