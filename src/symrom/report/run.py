"""Reading a run directory for the report, driven by its manifest.

``summary.json`` lists the run's experiments in ``manifest`` (``ManifestEntry``:
name, role, files relative to the run directory). The report reads only what
the manifest names; a file that is missing or unreadable becomes a visible
note (``Run.notes``), never an error. Files are read once and cached.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from symrom.data.dataset import Dataset
from symrom.evaluate.records import LEARNED, ManifestEntry, Metrics, RecordError, read_manifest
from symrom.model.hybrid import HybridModel
from symrom.model.provenance import Provenance

# What reading a run's file can raise: missing or unreadable (OSError), or not of its
# layout (ValueError: DatasetError, ModelFileError, RecordError, JSONDecodeError).
READ_ERRORS = (OSError, ValueError)


@dataclass
class Run:
    """A run directory: its summary, its manifest entries and what could not be read."""

    dir: Path
    summary: dict
    entries: list[ManifestEntry]
    notes: list[str] = field(default_factory=list)
    _cache: dict = field(default_factory=dict)
    kind: str = "run"  # "run" (reproduce, demo) or "model folder" (train, evaluate)

    # ------------------------------------------------------------ entries
    def entry(self, name: str | None) -> ManifestEntry | None:
        return next((e for e in self.entries if e.name == name), None)

    def path(self, entry: ManifestEntry, key: str) -> Path | None:
        """The absolute path of file ``key`` of ``entry``, None if not named or not there."""
        rel = entry.files.get(key)
        if rel is None:
            return None
        p = Path(rel) if Path(rel).is_absolute() else self.dir / rel
        if not p.exists():
            self.note(f"{entry.name}: {key} file {rel} is missing")
            return None
        return p

    # ------------------------------------------------------------ files, read once
    def note(self, text: str) -> None:
        if text not in self.notes:
            self.notes.append(text)

    def _read(self, kind: str, path: Path, load) -> Any:
        key = (kind, str(path.resolve()))
        if key not in self._cache:
            try:
                self._cache[key] = load(path)
            except READ_ERRORS as e:
                self.note(f"{path.relative_to(self.dir) if path.is_relative_to(self.dir) else path} is "
                          f"unreadable ({str(e).replace(str(path), path.name)}); what needs it is skipped")
                self._cache[key] = None
        return self._cache[key]

    def metrics(self, entry: ManifestEntry, key: str = "metrics") -> Metrics | None:
        p = self.path(entry, key)
        return None if p is None else self._read("metrics", p, Metrics.read)

    def model(self, entry: ManifestEntry, key: str = "model") -> HybridModel | None:
        from symrom.model.persistence import load_model

        p = self.path(entry, key)
        return None if p is None else self._read("model", p, load_model)

    def dataset_at(self, path: Path) -> Dataset | None:
        from symrom.data.io import read_dataset

        return self._read("dataset", path, read_dataset)

    def dataset(self, entry: ManifestEntry, key: str = "data") -> Dataset | None:
        p = self.path(entry, key)
        return None if p is None else self.dataset_at(p)

    def json(self, entry: ManifestEntry, key: str) -> dict | None:
        """A JSON object file of ``entry``."""
        def load(p: Path) -> dict:
            d = json.loads(p.read_text())
            if not isinstance(d, dict):
                raise RecordError("not a JSON object")
            return d

        p = self.path(entry, key)
        return None if p is None else self._read("json", p, load)

    def dataset_files(self) -> list[Path]:
        """Every dataset of the run: ``data/*.h5`` and the files the manifest names as data."""
        files = sorted((self.dir / "data").glob("*.h5")) if (self.dir / "data").is_dir() else []
        known = {f.resolve() for f in files}
        for e in self.entries:
            rel = e.files.get("data")
            p = None if rel is None else (self.dir / rel)
            if p is not None and p.is_file() and p.resolve() not in known:
                files.append(p)
                known.add(p.resolve())
        return files


class NotARunError(ValueError):
    """A directory that is not a run (it holds no ``summary.json``)."""


def load_run(run_dir: str | Path) -> Run:
    """Collect what the run directory holds; raise only if ``run_dir`` is not a directory
    (``FileNotFoundError``) or neither a run (``summary.json``) nor a model folder
    (``model_folder_run``) (``NotARunError``)."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise FileNotFoundError(f"{run_dir}: no such run directory")
    run = Run(run_dir, {}, [])
    path = run_dir / "summary.json"
    if not path.is_file():
        if (run_dir / "model.json").is_file() or (run_dir / "metrics.json").is_file():
            return model_folder_run(run_dir)
        raise NotARunError(f"{run_dir}: not a run directory (no summary.json: `symrom reproduce --out DIR` "
                           "or `symrom demo` makes one) nor a model folder (model.json: `symrom train`, or "
                           "metrics.json: `symrom evaluate`)")
    try:
        summary = json.loads(path.read_text())
        if not isinstance(summary, dict):
            raise RecordError("not a JSON object")
        run.summary = summary
        if "manifest" not in summary:
            run.note("summary.json has no manifest (a run of an older symrom): run `symrom reproduce` "
                     "on this directory again to add it; every finished step is reused")
        run.entries = read_manifest(summary.get("manifest", []))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecordError) as e:
        run.note(f"summary.json: unreadable ({e}); the report shows no experiments")
    return run


def _recorded_path(recorded: str | None, folder: Path) -> str | None:
    """A path a model or metrics file recorded (as given on the command line, so relative
    to where that command ran, or to ``folder``): the one that exists, absolute."""
    if not recorded:
        return None
    for p in (Path(recorded), folder / recorded):
        if p.is_file():
            return str(p.resolve())
    return None


def _evaluations_of(folder: Path) -> list[Path]:
    """The ``metrics.json`` files in ``folder``'s subfolders, best first: those whose
    ``model`` is ``folder/model.json``, then those of some model file (a baseline's names
    no file), then those in a subfolder ``eval`` (the documented layout)."""
    own = str((folder / "model.json").resolve())

    def rank(p: Path) -> tuple[bool, bool, bool, str]:
        try:
            rec = json.loads(p.read_text())
            model = str(rec.get("model", "")) if isinstance(rec, dict) else ""
        except (OSError, ValueError):
            model = ""
        return (_recorded_path(model, folder) != own, not model.endswith("model.json"),
                p.parent.name != "eval", str(p))

    return sorted(folder.glob("*/metrics.json"), key=rank)


def model_folder_run(folder: str | Path) -> Run:
    """A model folder read as a run of one learned experiment, named for the folder:
    ``model.json`` (``symrom train``), the evaluation's ``metrics.json`` in the folder or
    in one of its subfolders (``symrom evaluate --out DIR/eval``), and the dataset the
    model or the metrics name. A folder of ``symrom evaluate`` alone finds its model
    through the metrics. What is missing becomes a note."""
    folder = Path(folder)
    run = Run(folder, {}, [], kind="model folder")
    files: dict[str, str] = {}
    metrics = folder / "metrics.json"
    if not metrics.is_file():
        metrics = next(iter(_evaluations_of(folder)), metrics)
    recorded: dict = {}
    if metrics.is_file():
        files["metrics"] = str(metrics.relative_to(folder))
        try:
            recorded = json.loads(metrics.read_text())
        except (OSError, ValueError):
            recorded = {}  # reported when the renderers read it
        recorded = recorded if isinstance(recorded, dict) else {}
    model = folder / "model.json"
    if model.is_file():
        files["model"] = "model.json"
    elif (found := _recorded_path(recorded.get("model"), folder)) is not None:
        files["model"] = found
    data = None
    if "model" in files:
        try:
            record = json.loads((folder / files["model"]).read_text())
            path = (Provenance.from_dict(record["provenance"]).data_path if "provenance" in record  # format 5
                    else (record.get("info") or {}).get("data_path"))
            data = _recorded_path(path, folder)
        except (OSError, ValueError, AttributeError, KeyError):
            data = None
    data = data or _recorded_path(recorded.get("data"), folder)
    if data is not None:
        files["data"] = data
    else:
        run.note("the dataset the model was trained or evaluated on was not found: no figure, "
                 "no reconstruction floor and no data summary")
    if "metrics" not in files:
        run.note(f"{folder} holds no evaluation (metrics.json): `symrom evaluate {folder / 'model.json'} DATA "
                 f"--out {folder / 'eval'}` adds Table 2 and a predicted jump")
    run.entries = [ManifestEntry(name=folder.resolve().name, role=LEARNED, title="", files=files)]
    return run
