"""Reading a run directory (made by ``symrom reproduce``) for the report.

Layout: ``summary.json``; ``data/<name>.h5``; ``<exp>/model.json`` and
``<exp>/eval/metrics.json`` for exp in go1_sim, a1_sim, go1_proxy;
``go1_sim/aslip/{metrics,params}.json``; ``sweep/sweep.json`` and optional
``sweep/encoders/W_e_l<k>.json``. Files take precedence over the copies in
``summary.json``; anything missing or unreadable becomes a note, never an error.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from symrom.data.dataset import Dataset
from symrom.model.hybrid import HybridModel

EXPERIMENTS: tuple[str, ...] = ("go1_sim", "a1_sim", "go1_proxy")


@dataclass
class Experiment:
    """One learned-model experiment of the run; paths absolute, dicts as in the files."""

    name: str
    summary: dict
    metrics: dict | None
    model_path: Path | None
    data_path: Path | None
    aslip_metrics: dict | None = None
    aslip_params: dict | None = None


@dataclass
class Run:
    dir: Path
    summary: dict
    experiments: dict[str, Experiment]
    missing: list[str]
    sweep: dict | None
    notes: list[str] = field(default_factory=list)
    _datasets: dict = field(default_factory=dict)
    _models: dict = field(default_factory=dict)

    def model(self, path: Path) -> HybridModel:
        """The model file at ``path``, loaded once (validated)."""
        from symrom.model.persistence import load_model

        key = str(Path(path).resolve())
        if key not in self._models:
            self._models[key] = load_model(path)
        return self._models[key]

    def dataset(self, path: Path) -> Dataset:
        """The dataset at ``path``, read once (validated)."""
        from symrom.data.io import read_dataset

        key = str(Path(path).resolve())
        if key not in self._datasets:
            self._datasets[key] = read_dataset(path)
        return self._datasets[key]

    def dataset_files(self) -> list[Path]:
        """Every dataset of the run: ``data/*.h5`` and the experiments' data files."""
        files = sorted((self.dir / "data").glob("*.h5")) if (self.dir / "data").is_dir() else []
        for e in self.experiments.values():
            if e.data_path is not None and e.data_path.resolve() not in {f.resolve() for f in files}:
                files.append(e.data_path)
        return files


def _json(path: Path, notes: list[str]) -> dict | None:
    if not path.is_file():
        return None
    try:
        d = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError, OSError) as e:
        notes.append(f"{path.name} in {path.parent}: unreadable ({e.__class__.__name__}); ignored")
        return None
    if not isinstance(d, dict):
        notes.append(f"{path}: not a JSON object; ignored")
        return None
    return d


def _existing(run_dir: Path, *candidates) -> Path | None:
    for c in candidates:
        if not c:
            continue
        p = Path(c)
        for q in ((p,) if p.is_absolute() else (run_dir / p, p)):
            if q.is_file():
                return q
    return None


def load_run(run_dir: str | Path) -> Run:
    """Collect what the run directory holds; raise only if ``run_dir`` is not a directory."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise FileNotFoundError(f"{run_dir}: no such run directory")
    notes: list[str] = []
    summary = _json(run_dir / "summary.json", notes)
    if summary is None:
        notes.append("summary.json is missing: equations, versions and commands come from the files alone")
        summary = {}
    s_exps = summary.get("experiments") or {}
    experiments, missing = {}, []
    for name in EXPERIMENTS:
        se = s_exps.get(name) or {}
        d = run_dir / name
        metrics = _json(d / "eval" / "metrics.json", notes) or se.get("metrics")
        model = _existing(run_dir, d / "model.json", se.get("model"))
        if metrics is None and model is None and not se:
            missing.append(name)
            continue
        data = _existing(run_dir, se.get("data"), run_dir / "data" / f"{name}.h5",
                         (metrics or {}).get("data"))
        exp = Experiment(name, se, metrics, model, data)
        if name == "go1_sim":
            exp.aslip_metrics = _json(d / "aslip" / "metrics.json", notes) or se.get("aslip")
            exp.aslip_params = _json(d / "aslip" / "params.json", notes)
        experiments[name] = exp
    sweep = _json(run_dir / "sweep" / "sweep.json", notes) or summary.get("sweep")
    return Run(run_dir, summary, experiments, missing, sweep, notes)
