"""Model selection on validation data: every setting chosen on train/val, never on test.

A grid of candidates is trained on the ``train`` split with the exact solver
and scored by rollouts of the ``val`` split at both horizons (the full jump
and 0.1 s resets). The grid spans

- the encoder: ``all`` 18 components (the paper), the ``base_pose`` (x ...
  yaw), the ``base_position`` (x, y, z), or all components ``standardised``
  by their spread;
- the latent dimension;
- the library blocks (``poly1+trig+inputs`` is the paper's);
- the sparsity: thresholds of the ``explained`` measure, from dense to sparse;
- the rollout-aware refinement, tried on the ``refine_top`` best candidates of
  the exact grid (it costs a thousand times more than an exact fit).

Score of a candidate: at each horizon, the mean over the 18 configuration
components of the validation RMSE divided by the component's spread (its
standard deviation over the validation rows, at least ``floor`` times the
largest spread among the components of the same unit, so a joint that never
moves does not dominate); the score is the mean of the two horizons. A
candidate with any diverged validation jump is rejected. Among the rest, the
sparsest (fewest active terms) whose score is within ``tolerance`` of the
best is chosen; ties go to the better score.

Every candidate and its numbers are kept in the selection table
(``selection.json``). The fitting of a cell (encoder, latent dimension,
library: one encoder and problem shared by its thresholds) reads only the
training rows and the validation jumps: replacing every value of the test
split by NaN changes nothing.
"""

from __future__ import annotations

import json
import multiprocessing
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from symrom.atomic import write_text_atomic
from symrom.data.dataset import Dataset
from symrom.evaluate.metrics import evaluate
from symrom.model.hybrid import HybridModel
from symrom.model.training import TrainConfig, data_hash, train
from symrom.names import BASE_NAMES, Q_NAMES, Q_UNITS
from symrom.rollout.integrate import RolloutOptions

SELECTION_VERSION = 1
ENCODERS: dict[str, tuple[tuple[str, ...] | None, str]] = {
    "all": (None, "none"),
    "base_pose": (BASE_NAMES, "none"),
    "base_position": (("x", "y", "z"), "none"),
    "standardised": (None, "spread"),
}
HORIZONS: tuple[float | None, ...] = (None, 0.1)

SelectProgress = Callable[[int, int, str], None]  # (cells done, cells in total, what finished)


def parse_library(text: str) -> dict[str, Any]:
    """``poly1+trig+inputs`` -> TrainConfig fields (poly_order, trig, inputs)."""
    parts = [p.strip() for p in str(text).split("+") if p.strip()]
    out = {"poly_order": 0, "trig": False, "inputs": False}
    for p in parts:
        if p.startswith("poly") and p[4:].isdigit():
            out["poly_order"] = int(p[4:])
        elif p in ("trig", "inputs"):
            out[p] = True
        else:
            raise ValueError(f"library {text!r}: unknown block {p!r}; use poly<p>, trig and inputs, "
                             f"joined by + (e.g. poly1+trig+inputs)")
    if not any(p.startswith("poly") for p in parts):
        raise ValueError(f"library {text!r}: needs a poly<p> block (the constant)")
    return out


@dataclass
class SelectionConfig:
    """The grid and the rules (module docstring). The fixed settings of every
    candidate: ``measure`` of the thresholds, ``collinearity`` of the audit,
    ``alpha`` ridge, ``decoded_weight`` of the SINDy loss (0: the latent
    accelerations alone; the decoded term asks the latent model to explain
    swing-leg accelerations the latent state does not hold)."""

    encoders: tuple[str, ...] = tuple(ENCODERS)
    latent_dims: tuple[int, ...] = (2, 3, 4)
    libraries: tuple[str, ...] = ("poly1+trig+inputs", "poly1+inputs")
    thresholds: tuple[float, ...] = (1e-4, 1e-3, 3e-3, 1e-2)
    refine_top: int = 2
    tolerance: float = 0.05
    floor: float = 0.05
    measure: str = "explained"
    collinearity: float = 0.995
    alpha: float = 1e-6
    decoded_weight: float = 0.0
    contact_phase: str = "contact"
    workers: int = 1
    substeps: int = 2

    def __post_init__(self) -> None:
        bad = [e for e in self.encoders if e not in ENCODERS]
        if bad:
            raise ValueError(f"unknown encoder choice(s) {bad}; choose from {list(ENCODERS)}")
        for lib in self.libraries:
            parse_library(lib)
        if not self.latent_dims or any(not 1 <= d <= len(Q_NAMES) for d in self.latent_dims):
            raise ValueError(f"latent dimensions must lie within 1..{len(Q_NAMES)}, got {self.latent_dims}")
        if not self.thresholds or any(not t >= 0 for t in self.thresholds):
            raise ValueError(f"thresholds must be >= 0, got {self.thresholds}")
        if not self.tolerance >= 0:
            raise ValueError(f"tolerance must be >= 0, got {self.tolerance}")
        if self.workers < 1 or self.refine_top < 0:
            raise ValueError("workers must be >= 1 and refine_top >= 0")

    def cells(self) -> list[tuple[str, int, str]]:
        """(encoder, latent dim, library) of every cell, skipping encoders too narrow for l."""
        out = []
        for enc in self.encoders:
            comps = ENCODERS[enc][0]
            for l in self.latent_dims:
                if comps is not None and len(comps) < l:
                    continue
                out += [(enc, l, lib) for lib in self.libraries]
        return out

    def train_config(self, encoder: str, latent_dim: int, library: str, threshold: float,
                     refine: bool = False) -> TrainConfig:
        comps, scaling = ENCODERS[encoder]
        return TrainConfig(latent_dim=latent_dim, **parse_library(library), threshold=threshold,
                           measure=self.measure, collinearity=self.collinearity, alpha=self.alpha,
                           decoded_weight=self.decoded_weight, encoder_components=comps,
                           encoder_scaling=scaling, contact_phase=self.contact_phase, refine=refine)


def component_spread(ds: Dataset, floor: float) -> np.ndarray:
    """(18,) standard deviation of each component over the val rows, floored at ``floor``
    times the largest among the components of the same unit."""
    std = ds.q[ds.rows_of("val")].std(axis=0)
    units = np.array([Q_UNITS[n] for n in Q_NAMES])
    out = std.copy()
    for u in set(units):
        same = units == u
        out[same] = np.maximum(std[same], floor * std[same].max())
    return np.maximum(out, 1e-12)


def score_model(model: HybridModel, ds: Dataset, spread: np.ndarray, substeps: int) -> dict[str, Any]:
    """Validation rollouts at both horizons: per horizon the normalised score, the
    diverged jumps and the RMSE of every component; ``score`` (None if any diverged)."""
    metrics, _ = evaluate(model, ds, "val", HORIZONS, RolloutOptions("rk4", substeps=substeps))
    out: dict[str, Any] = {"horizons": {}}
    scores = []
    for key, h in metrics["horizons"].items():
        comps = h["components"]
        rmse = [comps[n]["rmse"] for n in Q_NAMES] if comps else None
        s = float(np.mean(np.asarray(rmse) / spread)) if rmse is not None and not h["diverged_jumps"] else None
        out["horizons"][key] = {"score": s, "diverged_jumps": h["diverged_jumps"],
                                "rmse": None if rmse is None else dict(zip(Q_NAMES, rmse))}
        scores.append(s)
    out["score"] = None if any(s is None for s in scores) else float(np.mean(scores))
    return out


def _row(cfg: SelectionConfig, encoder: str, l: int, library: str, threshold: float, refine: bool,
         model: HybridModel, scored: dict, seconds: float) -> dict[str, Any]:
    return {"encoder": encoder, "latent_dim": l, "library": library, "threshold": threshold, "refine": refine,
            "active_terms": int(model.mask.sum()), "active_per_phase": model.active_terms(),
            "fast_unstable_phases": [s.phase for s in model.stability() if s.fast_unstable],
            "seconds": round(seconds, 3), **scored}


def run_cell(ds: Dataset, cfg: SelectionConfig, encoder: str, l: int, library: str) -> list[dict[str, Any]]:
    """Train and score every threshold of one (encoder, latent dim, library) cell."""
    spread = component_spread(ds, cfg.floor)
    rows = []
    for t in cfg.thresholds:
        t0 = time.perf_counter()
        model = train(ds, cfg.train_config(encoder, l, library, t))
        rows.append(_row(cfg, encoder, l, library, t, False, model, score_model(model, ds, spread, cfg.substeps),
                         time.perf_counter() - t0))
    return rows


def run_refined(ds: Dataset, cfg: SelectionConfig, row: dict) -> tuple[dict[str, Any], HybridModel]:
    """The refined version of a candidate row, scored."""
    t0 = time.perf_counter()
    model = train(ds, cfg.train_config(row["encoder"], row["latent_dim"], row["library"], row["threshold"], True))
    scored = score_model(model, ds, component_spread(ds, cfg.floor), cfg.substeps)
    return _row(cfg, row["encoder"], row["latent_dim"], row["library"], row["threshold"], True, model, scored,
                time.perf_counter() - t0), model


def choose(rows: list[dict], tolerance: float) -> int | None:
    """Index of the chosen row: the sparsest with a score within ``tolerance`` of the best."""
    ok = [i for i, r in enumerate(rows) if r["score"] is not None]
    if not ok:
        return None
    best = min(rows[i]["score"] for i in ok)
    near = [i for i in ok if rows[i]["score"] <= (1 + tolerance) * best]
    return min(near, key=lambda i: (rows[i]["active_terms"], rows[i]["score"]))


_WORKER: dict[str, Any] = {}


def _init_worker(ds: Dataset, cfg: SelectionConfig) -> None:
    _WORKER["ds"], _WORKER["cfg"] = ds, cfg


def _worker_cell(cell: tuple[str, int, str]) -> list[dict[str, Any]]:
    return run_cell(_WORKER["ds"], _WORKER["cfg"], *cell)


@dataclass
class Selection:
    """The table (one row per candidate), the index of the chosen row and its model."""

    rows: list[dict[str, Any]]
    chosen: int | None
    model: HybridModel | None
    config: SelectionConfig
    data_sha256: str = ""
    seconds: float = 0.0
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {"version": SELECTION_VERSION, "config": asdict(self.config), "data_sha256": self.data_sha256,
                "rule": f"score = mean over horizons (full, 0.1 s) of mean_c val RMSE_c / spread_c; "
                        f"candidates with a diverged val jump rejected; the sparsest within "
                        f"{self.config.tolerance:.0%} of the best score chosen",
                "chosen": self.chosen, "seconds": round(self.seconds, 2), "notes": self.notes,
                "rows": self.rows}


def check_splits(ds: Dataset) -> None:
    """ValueError unless ``ds`` has the train and val jumps a selection needs."""
    if ds.jumps_in("train").size == 0 or ds.jumps_in("val").size == 0:
        raise ValueError("selection needs 'train' and 'val' jumps (the test split is never read)")


def select(ds: Dataset, cfg: SelectionConfig = SelectionConfig(),
           progress: SelectProgress | None = None) -> Selection:
    """Run the grid on ``ds`` (train and val splits only) and return the selection."""
    check_splits(ds)
    t0 = time.perf_counter()
    say = progress or (lambda done, total, what: None)
    cells = cfg.cells()
    total = len(cells) + cfg.refine_top
    rows: list[dict] = []
    if cfg.workers == 1 or len(cells) == 1:
        for i, cell in enumerate(cells):
            rows += run_cell(ds, cfg, *cell)
            say(i + 1, total, f"{cell[0]} l={cell[1]} {cell[2]}")
    else:
        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=min(cfg.workers, len(cells)), mp_context=ctx,
                                 initializer=_init_worker, initargs=(ds, cfg)) as pool:
            futures = {pool.submit(_worker_cell, c): c for c in cells}
            for i, fut in enumerate(as_completed(futures)):
                rows += fut.result()
                c = futures[fut]
                say(i + 1, total, f"{c[0]} l={c[1]} {c[2]}")
    order = {c: i for i, c in enumerate(cells)}
    rows.sort(key=lambda r: (order[(r["encoder"], r["latent_dim"], r["library"])], r["threshold"]))
    # Refinement on the best exact candidates; those that diverge only at the full
    # horizon are the ones it may save, so rank by the 0.1 s score too.
    ranked = sorted((r for r in rows if r["horizons"]["0.1"]["score"] is not None),
                    key=lambda r: (r["score"] is None, r["score"] if r["score"] is not None
                                   else r["horizons"]["0.1"]["score"]))
    refined_models = {}
    for k, row in enumerate(ranked[:cfg.refine_top]):
        new, model = run_refined(ds, cfg, row)
        rows.append(new)
        refined_models[len(rows) - 1] = model
        say(len(cells) + k + 1, total, f"refined {row['encoder']} l={row['latent_dim']} {row['library']}")
    chosen = choose(rows, cfg.tolerance)
    notes = [] if chosen is not None else ["every candidate diverged on a validation jump: none chosen"]
    model = None
    if chosen is not None:
        r = rows[chosen]
        model = refined_models.get(chosen) or train(
            ds, cfg.train_config(r["encoder"], r["latent_dim"], r["library"], r["threshold"], r["refine"]))
        model.info["selection"] = {k: r[k] for k in ("encoder", "latent_dim", "library", "threshold", "refine",
                                                     "score", "active_terms")}
    return Selection(rows, chosen, model, cfg, data_hash(ds), time.perf_counter() - t0, notes)


def write_selection(sel: Selection, out: str | Path) -> Path:
    """``selection.json`` in directory ``out`` (written atomically); its path."""
    path = Path(out) / "selection.json"
    write_text_atomic(path, json.dumps(sel.to_dict(), indent=1, allow_nan=False) + "\n")
    return path


def selection_config(**overrides: Any) -> SelectionConfig:
    """The default grid with ``overrides`` applied (names as in ``SelectionConfig``)."""
    return replace(SelectionConfig(), **overrides)
