"""Latent-dimension sweep: accuracy versus complexity (the paper's trade-off analysis).

For every latent dimension l and seed s a model is trained and three numbers
are kept (one "cell"):

- ``E_dec``: final reconstruction error, the paper's L_recon ||q - q_recon||^2
  (squared 2-norm over the 18 components, rad^2 and m^2 mixed as in the paper)
  averaged over the training rows, with the
  bootstrap the resampled rows, repeats counted
  (``symrom.learn.training.reconstruction_error``);
- ``active_terms``: |Xi|, nonzero coefficients summed over all phases;
  (a cell's model is fitted without contact guards: every number here follows the logged
  phases, and the guards were most of a cell's time);
- ``rmse_test`` (optional): accuracy of the model, the mean over the 12 Table-2
  components of the test-split full-horizon RMSE (RK4 rollouts), ``None`` if
  every test jump diverged or there is no test split.

Per dimension the combined loss is computed from the means over seeds,
    L_mod(l) = 2 mean_s(E_dec) + 2 lambda log(mean_s |Xi|),
(lambda = 0.001; |Xi| < 1 is counted as 1 so an empty model scores log 1 = 0
rather than -inf), and ``best_latent_dim`` = argmin_l L_mod.

Seeds: with the ``exact`` solver training is deterministic, so seed s draws a
bootstrap resample of the training jumps (with replacement, the same draw for
every l) and the spread over seeds is a real error bar; with ``adam`` the seed
sets the initialisation on the unchanged training split.

Cells run as tasks of an execution back end (``symrom.execution``: local
processes, or a Ray cluster). A task returns its cell; the driver writes it to
``OUT/cells/l{l:02d}_s{s}.json`` as soon as it is done, with how it ran
(``execution``: back end, worker, attempts lost to a dying worker), and reuses
it on a rerun when its key (data hash and every setting that changes a cell)
matches, so an interrupted sweep resumes. Cells depend only on (data,
settings, l, s), so ``sweep.json`` depends neither on the back end nor on the
number of workers.
"""

from __future__ import annotations

import hashlib
import json
import re
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from symrom.atomic import write_text_atomic
from symrom.data.dataset import Dataset
from symrom.execution import Backend, LocalBackend
from symrom.experiments.grid import Store, run_grid
from symrom.learn.training import SOLVERS, AdamConfig, TrainConfig, data_hash, reconstruction_error
from symrom.names import N_Q, TABLE2_COMPONENTS

CELL_VERSION = 1
DEFAULT_LAMBDA = 0.001

# (cells done, cells in total, the finished cell's summary: latent_dim, seed, reused)
SweepProgress = Callable[[int, int, dict[str, Any]], None]


@dataclass
class SweepConfig:
    """latent_dims: dimensions to train; seeds: a count n (seeds 0..n-1) or explicit
    seeds; poly_order: library order p; solver: ``exact`` or ``adam``; lam: the
    L_mod weight lambda; workers: local processes (1 = in this process) when
    ``run_sweep`` is given no back end;
    threshold: sparsity threshold; rmse_test: also roll out the test split;
    adam: settings of the ``adam`` solver."""

    latent_dims: tuple[int, ...] = tuple(range(1, N_Q + 1))
    seeds: int | tuple[int, ...] = 5
    poly_order: int = 1
    solver: str = "exact"
    lam: float = DEFAULT_LAMBDA
    workers: int = 1
    threshold: float = 0.01
    rmse_test: bool = True
    adam: AdamConfig = field(default_factory=AdamConfig)

    def __post_init__(self) -> None:
        self.latent_dims = tuple(int(d) for d in self.latent_dims)
        if not self.latent_dims or any(not 1 <= d <= N_Q for d in self.latent_dims):
            raise ValueError(f"latent dimensions must be within 1..{N_Q}, got {list(self.latent_dims)}")
        if len(set(self.latent_dims)) != len(self.latent_dims):
            raise ValueError(f"latent dimensions repeat: {list(self.latent_dims)}")
        if isinstance(self.seeds, (int, np.integer)):
            if self.seeds < 1:
                raise ValueError(f"the number of seeds must be >= 1, got {self.seeds}")
            self.seeds = tuple(range(int(self.seeds)))
        self.seeds = tuple(int(s) for s in self.seeds)
        if not self.seeds or len(set(self.seeds)) != len(self.seeds):
            raise ValueError(f"seeds must be distinct and non-empty, got {list(self.seeds)}")
        if self.solver not in SOLVERS:
            raise ValueError(f"unknown solver {self.solver!r}; choose from {SOLVERS}")
        if self.poly_order < 0:
            raise ValueError(f"poly_order must be >= 0, got {self.poly_order}")
        if not (np.isfinite(self.lam) and self.lam >= 0):
            raise ValueError(f"lambda must be a non-negative number, got {self.lam}")
        if self.workers < 1:
            raise ValueError(f"workers must be >= 1, got {self.workers}")
        if isinstance(self.adam, dict):
            self.adam = AdamConfig(**self.adam)

    @property
    def bootstrap(self) -> bool:
        """Seeds resample the training jumps (exact solver) rather than the initialisation."""
        return self.solver == "exact"


def parse_latent_dims(text: str) -> tuple[int, ...]:
    """``"1-18"``, ``"1,2,4"``, ``"2-6"`` or mixes like ``"1-3,6"`` -> sorted distinct dims.

    Raises ValueError with one clear message on bad syntax or out-of-range values.
    """
    forms = "use a range like 1-18, a list like 1,2,4, or both (1-3,6)"
    dims: set[int] = set()
    for tok in str(text).replace(" ", "").split(","):
        m = re.fullmatch(r"(\d+)(?:-(\d+))?", tok)
        if not m:
            raise ValueError(f"latent dimensions {text!r}: cannot read {tok!r}; {forms}")
        lo, hi = int(m[1]), int(m[2] or m[1])
        if lo > hi:
            raise ValueError(f"latent dimensions {text!r}: range {tok!r} runs backwards")
        if lo < 1 or hi > N_Q:
            raise ValueError(f"latent dimensions {text!r}: must lie within 1..{N_Q}")
        dims.update(range(lo, hi + 1))
    return tuple(sorted(dims))


def bootstrap_jumps(ds: Dataset, seed: int) -> np.ndarray:
    """Train-split jump indices drawn with replacement (as many as there are), sorted.

    The draw depends on ``seed`` only, so every latent dimension sees the same sample.
    """
    train_jumps = ds.jumps_in("train")
    if train_jumps.size == 0:
        raise ValueError("no training rows (the dataset has no 'train' jumps)")
    rng = np.random.default_rng(seed)
    return np.sort(rng.choice(train_jumps, size=train_jumps.size, replace=True))


def l_mod(e_dec: np.ndarray | float, active_terms: np.ndarray | float, lam: float = DEFAULT_LAMBDA) -> np.ndarray:
    """L_mod = 2 E_dec + 2 lam log(|Xi|), |Xi| clamped to >= 1; elementwise."""
    return 2.0 * np.asarray(e_dec, float) + 2.0 * lam * np.log(np.maximum(np.asarray(active_terms, float), 1.0))


def cell_key(config: SweepConfig, data_sha256: str, latent_dim: int, seed: int) -> str:
    """Hash of everything a cell's numbers depend on (lambda and workers do not)."""
    spec = {"version": CELL_VERSION, "data": data_sha256, "latent_dim": latent_dim, "seed": seed,
            "poly_order": config.poly_order, "solver": config.solver, "threshold": config.threshold,
            "bootstrap": config.bootstrap, "rmse_test": config.rmse_test,
            "adam": asdict(config.adam) if config.solver == "adam" else None}
    return hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()


def run_cell(ds: Dataset, config: SweepConfig, latent_dim: int, seed: int) -> dict[str, Any]:
    """Train one (latent_dim, seed) model and measure it; a JSON-ready dict."""
    from symrom.evaluate.metrics import evaluate_model
    from symrom.rollout.integrate import RolloutOptions

    t0 = time.perf_counter()
    tc = TrainConfig(latent_dim=latent_dim, poly_order=config.poly_order, solver=config.solver,
                     threshold=config.threshold, seed=seed, adam=config.adam)
    if config.bootstrap:
        train_ds = ds.select_jumps(bootstrap_jumps(ds, seed))  # repeated jumps appear repeatedly
        rows = np.ones(train_ds.n_samples, dtype=bool)
    else:
        train_ds, rows = ds, ds.rows_of("train")
    # a cell's numbers follow the logged phases: no guard is ever used
    model = replace(tc.estimator(), contact_guards=False).fit(train_ds, rows).model
    per_phase = model.active_terms()
    cell: dict[str, Any] = {"latent_dim": latent_dim, "seed": seed,
                            "E_dec": reconstruction_error(model, train_ds, rows),
                            "active_terms": int(sum(per_phase.values())),
                            "active_terms_per_phase": per_phase,
                            "rmse_test": None, "test_diverged_jumps": None}
    if config.rmse_test and ds.jumps_in("test").size:
        metrics, _ = evaluate_model(model, ds, "test", resets=(None,), options=RolloutOptions(method="rk4"))
        full = metrics.full
        cell["test_diverged_jumps"] = full.diverged_jumps
        if full.components:
            cell["rmse_test"] = float(np.mean([full.components[c].rmse for c in TABLE2_COMPONENTS]))
    cell["seconds"] = round(time.perf_counter() - t0, 3)
    return cell


def _cell_path(out: Path, latent_dim: int, seed: int) -> Path:
    return out / "cells" / f"l{latent_dim:02d}_s{seed}.json"


def summarise(cells: dict[tuple[int, int], dict[str, Any]], config: SweepConfig,
              data_sha256: str = "") -> dict[str, Any]:
    """The sweep result (layout of ``sweep.json``) from all cells ``{(l, s): cell}``.

    Per-cell arrays are (dims x seeds); ``L_mod`` is per dim from the means over seeds.
    """
    dims, seeds = list(config.latent_dims), list(config.seeds)
    grid = lambda k: [[cells[(d, s)][k] for s in seeds] for d in dims]  # noqa: E731
    e_dec, active = np.array(grid("E_dec"), float), np.array(grid("active_terms"), float)
    lm = l_mod(e_dec.mean(axis=1), active.mean(axis=1), config.lam)
    rmse = grid("rmse_test")
    rmse_mean = [float(np.mean([v for v in row if v is not None])) if any(v is not None for v in row)
                 else None for row in rmse]
    return {"latent_dims": dims, "seeds": seeds,
            "E_dec": e_dec.tolist(), "active_terms": active.astype(int).tolist(),
            "L_mod": lm.tolist(), "best_latent_dim": int(dims[int(np.argmin(lm))]),
            "lambda": config.lam, "solver": config.solver, "poly_order": config.poly_order,
            "E_dec_mean": e_dec.mean(axis=1).tolist(), "E_dec_std": e_dec.std(axis=1).tolist(),
            "active_terms_mean": active.mean(axis=1).tolist(),
            "active_terms_std": active.std(axis=1).tolist(),
            "rmse_test": rmse, "rmse_test_mean": rmse_mean,
            "seed_meaning": "bootstrap resamples of the training jumps" if config.bootstrap
            else "initialisation seeds",
            "L_mod_from": "means over seeds of E_dec and |Xi|",
            "threshold": config.threshold, "data_sha256": data_sha256}


def run_sweep(ds: Dataset, config: SweepConfig, out: str | Path,
              progress: SweepProgress | None = None, backend: Backend | None = None) -> dict[str, Any]:
    """Run (or resume) the sweep into directory ``out``; write and return ``sweep.json``'s dict.

    Cells already in ``out/cells`` with a matching key are reused; the others run on
    ``backend`` (default: ``config.workers`` local processes) and are stored as they finish.
    """
    out = Path(out)
    (out / "cells").mkdir(parents=True, exist_ok=True)
    sha = data_hash(ds)
    store = Store(path=lambda c: _cell_path(out, *c), key=lambda c: cell_key(config, sha, *c),
                  record=lambda c, cell, key, execution: {**cell, "key": key, "execution": execution},
                  value=lambda stored: stored)
    tell = progress or (lambda done, n, info: None)

    def told(done: int, total: int, c: tuple[int, int], task) -> None:
        info = {"latent_dim": c[0], "seed": c[1], "reused": task is None}
        tell(done, total, info if task is None else {**info, "retries": len(task.retries)})

    cells = [(d, s) for d in config.latent_dims for s in config.seeds]
    # Large dimensions first: they take longest, so the workers stay busy to the end.
    # The workers fork from the process's fork server, which has imported this module (or, if an
    # earlier pool started it, they import it on their first cell), instead of starting Python.
    grid = run_grid(cells, run_cell, (ds, config), backend or LocalBackend(config.workers), "sweep cell", store,
                    order=lambda c: (-c[0], c[1]), progress=told, preload=(__name__,))
    result = summarise(grid.results, config, sha)
    write_text_atomic(out / "sweep.json", json.dumps(result, indent=1) + "\n")
    return result


def sweep_lines(result: dict, lam: float) -> list[str]:
    """A sweep's result (``sweep.json``'s dict) in words: one line per latent dimension (E_dec,
    |Xi|, L_mod), then the best dimension by L_mod."""
    lines = [f"l={d:2d}  E_dec {e:.3e}  |Xi| {a:7.1f}  L_mod {lm:.4e}" for d, e, a, lm in
             zip(result["latent_dims"], result["E_dec_mean"], result["active_terms_mean"], result["L_mod"])]
    return lines + [f"best latent dimension: {result['best_latent_dim']} (lambda {lam:g})"]
