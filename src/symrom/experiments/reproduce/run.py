"""The run: every experiment in order into one directory, its manifest and ``summary.json``,
and the summary in words."""

from __future__ import annotations

import json
import os
import platform
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from symrom import __version__
from symrom.atomic import write_text_atomic
from symrom.baselines import BASELINES
from symrom.data.io import read_dataset
from symrom.evaluate.paper import PAPER_TABLE2
from symrom.evaluate.records import BASELINE, FINE_TUNED, LEARNED, SELECTION, SOLVER, SWEEP, ManifestEntry, Metrics
from symrom.execution import HELPER_TIMEOUT, blas_kernels, limit_threads, wait_helper
from symrom.experiments.reproduce.config import PARTS, ReproduceConfig, Say
from symrom.experiments.reproduce.sim import references_done, run_learned, run_references, selected
from symrom.experiments.reproduce.sim2real import SIM2REAL, SIM2REAL_SOURCES, SIM2REAL_TARGETS, run_sim2real
from symrom.experiments.reproduce.solvers import run_solvers
from symrom.experiments.reproduce.steps import config_facts, done, ensure_dataset, selected_config
from symrom.experiments.reproduce.sweep import run_sweep_step
from symrom.experiments.warm import start_warm_helper
from symrom.model.persistence import load_model


def manifest(run: Path, cfg: ReproduceConfig, summary: dict) -> list[ManifestEntry]:
    """The run's experiments with their roles and files (paths relative to ``run``), for the report."""
    def rel(*parts: str) -> str:
        return str(Path(*parts))

    exps, out = summary["experiments"], []
    for exp in cfg.experiments:
        if exp.name not in exps:  # a run of one part only
            continue
        data = rel("data", f"{exp.data}.h5")
        entry = exps[exp.name]
        out.append(ManifestEntry(exp.name, LEARNED, paper=exp.name if exp.name in PAPER_TABLE2 else None,
                                 files={"model": rel(exp.name, "model.json"),
                                        "metrics": rel(exp.name, "eval", "metrics.json"),
                                        "data": data}, facts={"config": entry["config"]}))
        out.append(ManifestEntry(f"{exp.name}/selection", SELECTION, f"{exp.name}: selection on the validation split",
                                 of=exp.name, files={"table": rel(exp.name, "selection", "selection.json")}))
        d = rel(exp.name, "paper_defaults")
        out.append(ManifestEntry(f"{exp.name}/paper_defaults", LEARNED, f"{exp.name} with the paper's defaults",
                                 files={"model": rel(d, "model.json"), "metrics": rel(d, "eval", "metrics.json"),
                                        "data": data}, of=exp.name,
                                 facts={"config": config_facts(exp.paper_config(cfg.seed))}))
        for name in entry.get("baselines", {}):
            d = rel(exp.name, name)
            out.append(ManifestEntry(f"{exp.name}/{name}", BASELINE, BASELINES[name], of=exp.name,
                                     paper="aslip" if name.startswith("aslip") and exp.name == "go1_sim" else None,
                                     files={"metrics": rel(d, "metrics.json"), "params": rel(d, "params.json"),
                                            "data": data}))
    go1 = exps.get("go1_sim", {})
    for solver, s in go1.get("solvers", {}).items():
        d = rel("go1_sim", "solvers", solver)
        out.append(ManifestEntry(f"go1_sim/solvers/{solver}", SOLVER, solver, of="go1_sim",
                                 files={"model": rel(d, "model.json"), "metrics": rel(d, "eval", "metrics.json")},
                                 facts={"wall_time_s": s["wall_time_s"]}))
    if "go1_proxy" in exps:
        src = exps["go1_proxy"]["finetune"]["source"]
        out.append(ManifestEntry("go1_proxy", FINE_TUNED, f"proxy Go1, adapted from the {src} model",
                                 paper="go1_proxy", files={
                                     "model": rel("go1_proxy", "model.json"),
                                     "metrics": rel("go1_proxy", "eval", "metrics.json"),
                                     "data": exps["go1_proxy"]["data"],
                                     "source_model": rel("sources", src, "model.json"),
                                     "before": rel("go1_proxy", "sources_eval", src, "metrics.json"),
                                     "choice": rel("go1_proxy", "finetune_choice.json")},
                                 facts={"finetune": exps["go1_proxy"]["finetune"]}))
    if "sweep" in summary:
        out.append(ManifestEntry("sweep", SWEEP, "latent-dimension sweep", of="go1_sim",
                                 files={"result": rel("sweep", "sweep.json"), "encoders": rel("sweep", "encoders")}))
    return out



def _versions() -> dict:
    import numpy
    import scipy

    v = {"symrom": __version__, "python": platform.python_version(), "numpy": numpy.__version__,
         "scipy": scipy.__version__}
    from importlib.metadata import PackageNotFoundError, version

    try:
        v["pybullet"] = version("pybullet")
    except PackageNotFoundError:  # optional in a run that reuses datasets
        pass
    v["blas"] = "; ".join(blas_kernels())  # its kernel's rounding is in the simulated data's bits
    return v



BESIDE_NICE = 5  # the steps only the run's end needs yield the cores to its critical path


def _quiet(msg: str, transient: bool = False) -> None:
    pass


def _beside_main(fn, args: tuple, nice: int) -> None:
    if nice:
        os.nice(nice)
    limit_threads(1)
    try:
        fn(*args, _quiet)
    except Exception:  # the run's own process does the step again and reports what went wrong
        raise SystemExit(1) from None


class Beside:
    """A step of the run started beside the rest in a process of its own when the run has more
    than one worker (spawned, a daemon, so an interrupted run does not wait for it). There the
    step runs on one worker and one thread (``limit_threads``), with ``nice`` added to its
    niceness; its numbers do not depend on the workers or the niceness, and BLAS's threads move
    only their last bits.
    ``result`` waits for it, then calls the step in the run's own process, which reads back what
    the other process wrote (every step resumes from its files) and does whatever it did not
    finish.

    fn(*args, cfg, say) is the step; local_only: run it beside only on the local back end (a
    step that spreads work over the back end), else in the run's own process at ``result``;
    needed: False when there is nothing to do (a resumed run), which ``result`` then finds."""

    def __init__(self, what: str, fn, args: tuple, cfg: ReproduceConfig, say: Say, nice: int = 0,
                 local_only: bool = True, needed: bool = True) -> None:
        self.what, self.fn, self.args, self.cfg, self.say, self.process = what, fn, args, cfg, say, None
        if needed and cfg.workers > 1 and (cfg.backend == "local" or not local_only):
            from symrom.execution import process_context

            ctx = process_context()
            say(f"{what}: beside the rest of the run")
            self.process = ctx.Process(
                target=_beside_main, args=(fn, (*args, replace(cfg, workers=1)), nice), daemon=True)
            self.process.start()

    def result(self):
        if self.process is not None:
            self.say(f"{self.what}: waiting for it", transient=True)
            self.process.join()
        return self.fn(*self.args, self.cfg, self.say)

    def stop(self) -> None:
        if self.process is not None and self.process.is_alive():
            self.process.terminate()
            self.process.join()


def solvers_beside(run: Path, data: Path, settings, cfg: ReproduceConfig, say: Say) -> Beside:
    """The solver comparison (``run_solvers``) beside the rest of the run: the adam solver runs
    on one thread, so its results do not depend on where it runs."""
    return Beside("solvers: exact and adam on go1_sim", run_solvers, (run, data, settings), cfg, say,
                  nice=BESIDE_NICE, local_only=False)


def ensure_datasets(run: Path, specs: list, cfg: ReproduceConfig, say: Say) -> dict[str, Path]:
    """``ensure_dataset`` of each of ``specs``, in order: name -> file."""
    return {spec.name: ensure_dataset(run, spec, cfg, say) for spec in specs}


def sim2real_part(run: Path, specs: list, settings: dict, cfg: ReproduceConfig, say: Say) -> tuple[dict, dict]:
    """``run_sim2real`` on the targets whose datasets (and their sources') are ``specs``, made first,
    with the SIM experiments' ``settings`` (experiment -> its selected configuration)."""
    return run_sim2real(run, ensure_datasets(run, specs, cfg, say), settings, cfg, say)


def reproduce(run: Path, cfg: ReproduceConfig, command: str = "", say: Say | None = None,
              only: str | None = None) -> dict:
    """Run every experiment into ``run``; write and return ``summary.json``'s content.

    only: ``sim2real`` runs just the sim-to-real part (with the SIM Go1 and SIM A1 selections its
    settings come from; the datasets it needs), resumable as the rest; the summary then holds
    that part.
    """
    if only is not None and only not in PARTS:
        raise ValueError(f"only={only!r}: not a part of the run; one of: {', '.join(PARTS)}")
    say = say or (lambda msg, transient=False: None)
    t0 = time.perf_counter()
    run.mkdir(parents=True, exist_ok=True)
    settings_of = {t.settings for t in SIM2REAL}  # the SIM experiments whose settings sim-to-real uses
    needed = {e.data for e in cfg.experiments if e.name in settings_of} | set(SIM2REAL_SOURCES.values()) | set(
        SIM2REAL_TARGETS)
    specs = [s for s in cfg.datasets if only is None or s.name in needed]
    exps = [e for e in cfg.experiments if only is None or e.name in settings_of]
    # Each SIM experiment's data is made in this process when it starts. Once an experiment's
    # settings are chosen, its sim-to-real part (its targets' and sources' data, then sim-to-real)
    # runs beside the rest; the last experiment's part runs here at the end, its data made
    # beside from the start. The sweep (SIM Go1's data alone) and the solvers run beside too.
    parts: dict[str, list] = {}  # SIM experiment -> the datasets of its sim-to-real part
    for t in SIM2REAL:
        names = {t.name, *(d for _, d in t.sources)}
        parts.setdefault(t.settings, []).extend(
            s for s in specs if s.name in names and s not in parts[t.settings])
    last = exps[-1].name if exps else None
    data: dict[str, Path] = {}
    beside: list[Beside] = []
    summary: dict = {"experiments": {}}
    chosen: dict = {}  # SIM experiment -> its selected configuration, read once it is chosen
    running: dict[str, Beside] = {}  # SIM experiment -> its sim-to-real part beside the run
    entries, tables, solvers, sweep = {}, {}, None, None

    def sim_dataset(name: str) -> Path:
        if name not in data:
            data[name] = ensure_dataset(run, next(s for s in specs if s.name == name), cfg, say)
        return data[name]

    # with more than one worker, other processes of the run share the cores
    threads = limit_threads(1) if cfg.workers > 1 and cfg.backend == "local" else None
    # On a cold cache the learning's kernels compile beside the first simulation, once, rather
    # than in every selection worker at once.
    warming = start_warm_helper() if exps and cfg.workers > 1 and cfg.backend == "local" else None
    try:
        if exps:
            sim_dataset(exps[0].data)
        late = parts.get(last, [])
        early = Beside("datasets: " + ", ".join(s.name for s in late), ensure_datasets, (run, late), cfg, say,
                       needed=bool(late) and not all(done(run / "data" / f"{s.name}.h5") for s in late))
        beside.append(early)
        if only is None:
            sweep = Beside("sweep", run_sweep_step, (run, data["go1_sim"]), cfg, say, nice=BESIDE_NICE)
            beside.append(sweep)
        wait_helper(warming, HELPER_TIMEOUT)
        for exp in exps:
            if only is None:
                # the paper-default model and the baselines beside the selection, on its idle moments
                refs = Beside(f"{exp.name}: paper defaults and baselines", run_references,
                              (run, exp, sim_dataset(exp.data)), cfg, say, nice=BESIDE_NICE,
                              needed=not references_done(run, exp))
                beside.append(refs)
                summary["experiments"][exp.name] = run_learned(run, exp, sim_dataset(exp.data), cfg, say, refs)
            else:
                say(f"{exp.name}: selecting the settings on the validation split (the sim-to-real settings)")
                selected(run, exp, read_dataset(sim_dataset(exp.data)), cfg, say)
            chosen[exp.name] = selected_config(load_model(run / exp.name / "model.json"))
            if exp.name == "go1_sim" and cfg.compare_solvers and only is None:  # its settings are known
                solvers = solvers_beside(run, data["go1_sim"], chosen["go1_sim"], cfg, say)
                beside.append(solvers)
            if exp.name != last and parts.get(exp.name):
                running[exp.name] = Beside(f"sim-to-real from {exp.name}'s settings", sim2real_part,
                                           (run, parts[exp.name], {exp.name: chosen[exp.name]}), cfg, say)
                beside.append(running[exp.name])
        early.result()
        if last is not None and parts.get(last):
            e, t = sim2real_part(run, parts[last], {last: chosen[last]}, cfg, say)
            entries.update(e)
            tables.update(t)
        for part in running.values():
            e, t = part.result()
            entries.update(e)
            tables.update(t)
        data = ensure_datasets(run, specs, cfg, say)
        if tables:
            order = [t.name for t in SIM2REAL]
            entries = dict(sorted(entries.items(), key=lambda kv: order.index(kv[0])))
            tables = dict(sorted(tables.items(), key=lambda kv: order.index(kv[0])))
            if "go1_proxy" in entries:  # the paper's Table 2 row
                summary["experiments"]["go1_proxy"] = entries["go1_proxy"]
            summary["sim2real"] = {"sources": {k: v for k, v in SIM2REAL_SOURCES.items() if v in data},
                                   "targets": tables}
        if sweep is not None:
            summary["sweep"] = sweep.result()
        if solvers is not None:
            summary["experiments"]["go1_sim"]["solvers"] = solvers.result()
    finally:
        for b in beside:
            b.stop()
        if threads is not None:
            threads.restore_original_limits()
    summary["manifest"] = [e.to_dict() for e in manifest(run, cfg, summary)]
    summary["run"] = {"command": command, "versions": _versions(), "seeds": {"seed": cfg.seed},
                      "config": json.loads(json.dumps(asdict(cfg), default=str)), "only": only,
                      "wall_time_s": time.perf_counter() - t0}
    write_text_atomic(run / "summary.json",
                      json.dumps(summary, indent=1, allow_nan=False,
                                 default=lambda o: o.tolist() if isinstance(o, np.ndarray) else str(o)))
    return summary


def sweep_line(sweep: dict, chosen: dict[str, int] | None = None) -> str:
    """The sweep's best latent dimension in one line, told apart from the selected models' ``chosen``
    (experiment -> its l, chosen on the validation jumps)."""
    dims = ", ".join(str(d) for d in sweep["latent_dims"])
    line = (f"sweep: best latent dimension by L_mod (reconstruction error against the number of terms, "
            f"over l = {dims}): {sweep['best_latent_dim']}")
    if chosen:
        line += ("; not the selected model's: " + ", ".join(f"{k} has l = {v}" for k, v in chosen.items())
                 + ", chosen on the validation jumps")
    return line


def summary_lines(summary: dict) -> list[str]:
    """A run's summary in words: per experiment its latent dimension, library terms, active terms and
    diverged test jumps; per sim-to-real target its source as logged, repaired and fine-tuned
    (``sim2real_line``); then the sweep's best latent dimension, told apart from the models'."""
    lines = []
    for name, exp in summary["experiments"].items():
        metrics = Metrics.from_dict(exp["metrics"])
        unchecked = exp.get("config", {}).get("checks") == []  # data too small to judge a model's physics by
        lines.append(f"{name}: l={exp['latent_dim']}, {exp['n_candidates']} library terms, active terms "
                     f"{exp['active_terms']}, diverged {metrics.full.diverged_jumps}/{metrics.n_jumps}"
                     + ("; selected on val without the selection's checks" if unchecked else ""))
    for name, t in summary.get("sim2real", {}).get("targets", {}).items():
        lines.append(sim2real_line(name, t))
    if "sweep" in summary:
        lines.append(sweep_line(summary["sweep"], {k: e["latent_dim"] for k, e in summary["experiments"].items()
                                                  if k in ("go1_sim",)}))
    return lines


def sim2real_line(name: str, table: dict) -> str:
    """One target's sim-to-real in one line: the full-horizon x / z RMSE of the source on its test
    jumps as logged and as repaired, and repaired + fine-tuned, beside the target-alone model."""
    def xz(key: str) -> str:
        e = table.get(key)
        if not e or "refused" in e or e.get("x_rmse") is None:
            return "-" if not e or "refused" not in e else "refused"
        return f"{e['x_rmse']:.3f} / {e['z_rmse']:.3f} m" + (f" ({e['diverged_jumps']} diverged)"
                                                           if e["diverged_jumps"] else "")

    met = [k for k in ("source_z", "fine_tuned_z", "not_above_source", "flight_gravity", "vs_target_alone")
           if table.get("checks", {}).get(k)]
    return (f"{name}: x / z RMSE as logged {xz('logged')}, repaired {xz('source')}, repaired + fine-tuned "
            f"{xz('fine_tuned')}, target alone {xz('target_alone')}; {len(met)} of 5 targets met")
