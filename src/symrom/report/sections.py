"""The report's sections, built from a loaded run (``report.run.Run``).

Each builder returns a ``Section`` of document blocks; figures are written as
PNG files into ``fig_dir``. Anything missing becomes a visible note.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from symrom.names import BASE_POS, Q_UNITS, TABLE2_COMPONENTS
from symrom.evaluate.paper import (PAPER_ASLIP, PAPER_BEST_DIMS, PAPER_LABELS, PAPER_LAMBDA,
                                   implied_rmse, paper_row)
from symrom.evaluate.tables import fmt_value as fmt
from symrom.report import figures
from symrom.report.document import Figure, Para, Pre, Section, Table
from symrom.report.run import EXPERIMENTS, Experiment, Run

HORIZON_LABELS = {"full": "Full", "0.1": "0.1 s"}
DASH = "—"


def horizon_label(key: str) -> str:
    return HORIZON_LABELS.get(key, f"{key} s")


def ms(stats: dict | None) -> str:
    """``mean±std`` of a component's stats as in the paper (two significant digits)."""
    return f"{fmt(stats['mean'])}±{fmt(stats['std'])}" if stats else DASH


def diverged_text(metrics: dict) -> str:
    """One line naming the diverged jumps per horizon, e.g. 'full 0 of 6, 0.1 s 1 of 6'."""
    n = metrics.get("n_jumps", "?")
    return ", ".join(f"{horizon_label(k)}: {h.get('diverged_jumps', 0)} of {n}"
                     for k, h in metrics.get("horizons", {}).items())


def any_diverged(metrics: dict) -> bool:
    """Whether any horizon of a metrics dict lost a jump to divergence."""
    return any(h.get("diverged_jumps", 0) for h in metrics.get("horizons", {}).values())


def _exp_title(name: str) -> str:
    return f"{name} — paper row: {PAPER_LABELS.get(name, name)}"


# --------------------------------------------------------------------------- Table 2
def table2_rows(name: str, metrics: dict,
                components: tuple[str, ...] = TABLE2_COMPONENTS) -> tuple[list[list[str]], dict]:
    """Rows of the Table 2 comparison (paper beside ours) and per horizon the count
    of components where our RMSE <= the paper's implied RMSE."""
    rows, wins = [], {}
    horizons = metrics.get("horizons", {})
    for key in list(dict.fromkeys(["full", "0.1", *horizons])):
        ours = horizons.get(key)
        paper = paper_row(name, key)
        if ours is None and paper is None:
            continue
        lab = horizon_label(key)
        comps = (ours or {}).get("components") or {}
        if paper:
            rows.append([lab, "paper mean±std"] + [f"{fmt(paper[c][0])}±{fmt(paper[c][1])}" for c in components])
        if ours is None:
            rows.append([lab, "ours"] + ["not evaluated"] + [""] * (len(components) - 1))
            continue
        if not comps:
            rows.append([lab, "ours"] + [f"all {ours.get('diverged_jumps', '?')} jumps diverged"]
                        + [""] * (len(components) - 1))
            continue
        div = ours.get("diverged_jumps", 0)
        tag = f"ours mean±std ({div} diverged)" if div else "ours mean±std"
        rows.append([lab, tag] + [ms(comps.get(c)) for c in components])
        if paper:
            rows.append([lab, "paper RMSE √(mean²+std²)"]
                        + [fmt(implied_rmse(*paper[c])) for c in components])
        rows.append([lab, "ours RMSE"] + [fmt(comps[c]["rmse"]) if c in comps else DASH for c in components])
        if paper:
            marks = ["✓" if c in comps and comps[c]["rmse"] <= implied_rmse(*paper[c]) else "✗"
                     for c in components]
            wins[key] = marks.count("✓")
            rows.append([lab, "ours ≤ paper RMSE"] + marks)
    return rows, wins


def table2_section(run: Run) -> Section:
    sec = Section("table2", "Table 2 — prediction errors, paper vs ours")
    sec.add(Para("Signed error predicted − true over all samples of the test split (joint angles "
                 "and orientation in rad, CoM position in m), full-horizon rollouts and rollouts "
                 "reset to the true latent state every 0.1 s. The paper's mean±std gives an implied "
                 "RMSE √(mean²+std²); ✓ marks a component where our RMSE is not larger. Diverged "
                 "jumps are excluded from the statistics and counted."))
    header = ["horizon", "row"] + [f"{c} [{Q_UNITS[c]}]" for c in TABLE2_COMPONENTS]
    for name in EXPERIMENTS:
        exp = run.experiments.get(name)
        sec.add(_exp_title(name))
        if exp is None:
            sec.add(Para(f"{name}: not in this run (no {name}/eval/metrics.json or summary entry); skipped.",
                         note=True))
            continue
        if exp.metrics is None:
            sec.add(Para(f"{name}: no metrics (eval/metrics.json missing); skipped.", note=True))
            continue
        try:
            rows, wins = table2_rows(name, exp.metrics)
        except (KeyError, TypeError, ValueError) as e:  # a malformed metrics file
            sec.add(Para(f"{name}: metrics.json does not have the expected layout ({e!r}); skipped.",
                         note=True))
            continue
        floor = _floor(run, exp)
        if floor is not None:
            rows.append(["any", "reconstruction floor RMSE"] + [fmt(floor[c]) for c in TABLE2_COMPONENTS])
        split, n = exp.metrics.get("split", "test"), exp.metrics.get("n_jumps", "?")
        cfg = exp.summary.get("config")
        if isinstance(cfg, dict):
            comps = cfg.get("encoder_components")
            sec.add(Para("Training options: encoder reads "
                         + (", ".join(comps) if comps else "all 18 components")
                         + f"; decoded-acceleration weight {cfg.get('decoded_weight', 1.0):g}"
                         + f"; standardised ridge alpha {cfg.get('alpha', 0.0):g}."))
        sec.add(Table(header, rows, caption=f"{name}, {split} jumps: {n}"))
        sec.add(Para(f"Diverged test jumps — {diverged_text(exp.metrics)}.",
                     note=any_diverged(exp.metrics)))
        if wins:
            sec.add(Para("Ours ≤ paper RMSE in " + ", ".join(
                f"{w} of {len(TABLE2_COMPONENTS)} components ({horizon_label(k)})" for k, w in wins.items()) + "."))
        if floor is not None:
            blocked = [c for c in TABLE2_COMPONENTS
                       if (p := paper_row(name, "0.1")) and floor[c] > implied_rmse(*p[c])]
            if blocked:
                sec.add(Para("The reconstruction floor (decode∘encode of the true configurations, the error "
                             "of a rollout with exact latent dynamics) is above the paper's 0.1 s RMSE for "
                             + ", ".join(blocked) + ": with this encoder no latent model can reach the "
                             "paper's value there.", note=True))
        pd = exp.summary.get("paper_defaults")
        if isinstance(pd, dict) and isinstance(pd.get("metrics"), dict) and pd["metrics"].get("horizons"):
            prow, _ = table2_rows(name, pd["metrics"])
            sec.add(Table(header, [r for r in prow if r[1].startswith("ours")],
                          caption=f"{name} with the paper's defaults (encoder over all 18 components, "
                                  f"decoded-acceleration weight 1, no ridge)"))
            sec.add(Para(f"Paper defaults, diverged test jumps — {diverged_text(pd['metrics'])}.",
                         note=any_diverged(pd["metrics"])))
        before = exp.summary.get("before_finetune")
        if isinstance(before, dict) and before.get("horizons"):
            brows, _ = table2_rows(name, before)
            sec.add(Table(header, [r for r in brows if r[1].startswith("ours")],
                          caption=f"{name} before fine-tuning (the simulation model on the same test jumps)"))
    return sec


def _floor(run: Run, exp: Experiment) -> dict[str, float] | None:
    """The experiment's reconstruction floor on its evaluation split, if model and data load."""
    from symrom.evaluate.metrics import reconstruction_floor

    if exp.model_path is None or exp.data_path is None:
        return None
    try:
        return reconstruction_floor(run.model(exp.model_path), run.dataset(exp.data_path),
                                    exp.metrics.get("split", "test"))
    except Exception:  # noqa: BLE001 - a diagnostic row; the table stands without it
        return None


# --------------------------------------------------------------------------- rollouts of one jump
class JumpCache:
    """Rollouts of the first test jump of each experiment, computed once for the figures."""

    def __init__(self, run: Run):
        self.run = run
        self._cache: dict[str, tuple] = {}

    def get(self, exp: Experiment):
        """(dataset, jump index, {"full": Rollout, "0.1": Rollout}, model) of ``exp``."""
        if exp.name not in self._cache:
            from symrom.rollout.integrate import RolloutOptions, rollout

            if exp.model_path is None or exp.data_path is None:
                raise FileNotFoundError("model.json or the dataset file is missing")
            model = self.run.model(exp.model_path)
            ds = self.run.dataset(exp.data_path)
            split = (exp.metrics or {}).get("split", "test")
            jumps = ds.jumps_in(split)
            if jumps.size == 0:
                raise ValueError(f"the dataset has no {split!r} jumps")
            j = int(jumps[0])
            method = (exp.metrics or {}).get("integrator", "lsoda")
            ros = {key: rollout(model, ds, [j], RolloutOptions(method=method, reset=reset))
                   for key, reset in (("full", None), ("0.1", 0.1))}
            self._cache[exp.name] = (ds, j, ros, model)
        return self._cache[exp.name]


def _present_experiments(run: Run, sec: Section):
    """(name, experiment) of each experiment in the run; a note in ``sec`` for each missing one."""
    for name in EXPERIMENTS:
        exp = run.experiments.get(name)
        if exp is None:
            sec.add(Para(f"{name}: not in this run; skipped.", note=True))
        else:
            yield name, exp


def predictions_section(run: Run, jumps: JumpCache, fig_dir: Path) -> Section:
    sec = Section("predictions", "Predictions of a test jump")
    sec.add(Para("Truth (black) and the learned model's prediction of the front-left and rear-right "
                 "joint angles and the CoM pose, full horizon (dashed) and with 0.1 s resets; shaded "
                 "spans mark the phases other than the first."))
    for name, exp in _present_experiments(run, sec):
        try:
            ds, j, ros, _ = jumps.get(exp)
            path = figures.jump_figure(ds, ros, j, fig_dir / f"jump_{name}.png",
                                       title=f"{name}: {ds.robot} {ds.motion}, test jump {j}")
        except Exception as e:  # noqa: BLE001 - one figure must not sink the report
            sec.add(Para(f"{name}: prediction figure unavailable ({e}).", note=True))
            continue
        div = [f"{horizon_label(k)} diverged at t = {ds.t[ds.jump_bounds()[j][0] + r.diverged_at[0]]:.3f} s"
               for k, r in ros.items() if r.diverged[0]]
        sec.add(Figure(path, f"{name}: test jump {j}, truth vs prediction"))
        if div:
            sec.add(Para(f"{name}, jump {j}: " + "; ".join(div) + " (the curve stops there).", note=True))
    return sec


# --------------------------------------------------------------------------- aSLIP
def aslip_rows(ours: dict, aslip: dict) -> list[list[str]]:
    """Full-horizon CoM MAE (m) in x and z: ours, aSLIP, their ratio, the paper's three."""
    rows = []
    o = ours.get("horizons", {}).get("full", {}).get("components", {})
    a = aslip.get("horizons", {}).get("full", {}).get("components", {})
    for c in ("x", "z"):
        om, am = (o.get(c) or {}).get("mae"), (a.get(c) or {}).get("mae")
        p = PAPER_ASLIP[c]
        ratio = f"{am / om:.3g}" if om and am is not None else DASH
        rows.append([c, fmt(om) if om is not None else DASH, fmt(am) if am is not None else DASH, ratio,
                     fmt(p["learned"]), fmt(p["aslip"]), f"{p['aslip'] / p['learned']:.3g}",
                     "✓" if om is not None and am is not None and om <= am else "✗"])
    return rows


def aslip_section(run: Run, jumps: JumpCache, fig_dir: Path) -> Section:
    sec = Section("aslip", "Learned model vs aSLIP baseline (Go1)")
    exp = run.experiments.get("go1_sim")
    if exp is None:
        return sec.add(Para("go1_sim is not in this run: no aSLIP comparison.", note=True))
    sec.add(Para("Full-horizon mean absolute error of the CoM position over the test split (m). "
                 "The paper reports 1.6e-2 m (learned) vs 5.7e-2 m (aSLIP) in x and 4.0e-2 m vs "
                 "9.5e-2 m in z."))
    if exp.aslip_metrics is None or exp.metrics is None:
        sec.add(Para("aSLIP or learned-model metrics missing (go1_sim/aslip/metrics.json, "
                     "go1_sim/eval/metrics.json); table skipped.", note=True))
    else:
        header = ["CoM", "ours MAE [m]", "aSLIP MAE [m]", "aSLIP / ours", "paper learned [m]",
                  "paper aSLIP [m]", "paper aSLIP / learned", "ours ≤ aSLIP"]
        try:
            sec.add(Table(header, aslip_rows(exp.metrics, exp.aslip_metrics), caption="Full horizon, test split"))
        except (KeyError, TypeError, ValueError, AttributeError) as e:
            sec.add(Para(f"aSLIP table unavailable: unexpected metrics layout ({e!r}).", note=True))
        sec.add(Para(f"Diverged test jumps — learned: {diverged_text(exp.metrics)}; "
                     f"aSLIP: {diverged_text(exp.aslip_metrics)}."))
    if exp.aslip_params:
        units = {"k_s": "N/m", "l_0": "m", "m": "kg"}
        sec.add(Table(["parameter", "value"],
                      [[f"{k} [{units[k]}]" if k in units else k, f"{v:.4g}"]
                       for k, v in exp.aslip_params.items() if isinstance(v, (int, float))],
                      caption=f"aSLIP parameters ({exp.aslip_params.get('source', 'fitted on the train split')})"))
    try:
        ds, j, ros, _ = jumps.get(exp)
        a, b = ds.jump_bounds()[j]
        method = (exp.aslip_metrics or {}).get("integrator", "lsoda")
        pred = figures.aslip_jump_com(ds, j, exp.aslip_params, method) if exp.aslip_params else None
        learned = ros["full"].q_pred[0][:, BASE_POS]
        path = figures.aslip_figure(ds.t[a:b], ds.q[a:b, BASE_POS], learned, pred, ds.phase[a:b],
                                    ds.phase_names, fig_dir / "aslip_go1_sim.png",
                                    title=f"go1_sim test jump {j}: CoM position, learned vs aSLIP")
        sec.add(Figure(path, f"CoM x and z of go1_sim test jump {j}: truth, learned model, aSLIP"))
        if pred is None:
            sec.add(Para("aSLIP prediction unavailable (no params.json); the figure shows the learned "
                         "model only.", note=True))
    except Exception as e:  # noqa: BLE001
        sec.add(Para(f"aSLIP comparison figure unavailable ({e}).", note=True))
    return sec


# --------------------------------------------------------------------------- latent space, trade-off
def encoder_weights(run: Run, l: int) -> tuple[np.ndarray, str] | None:
    """W_e (l, 18) for the heatmap and where it came from: sweep/encoders, a run model
    of that dimension, or step (a) of the exact solver on the go1_sim training data."""
    p = run.dir / "sweep" / "encoders" / f"W_e_l{l}.json"
    if p.is_file():
        W = np.asarray(json.loads(p.read_text())["W_e"], dtype=float)
        if W.shape == (l, 18):
            return W, f"sweep/encoders/{p.name}"
    exp = run.experiments.get("go1_sim")
    if exp is None:
        return None
    if exp.model_path is not None:
        m = run.model(exp.model_path)
        if m.latent_dim == l:
            return m.autoencoder.W_e, "go1_sim/model.json"
    if exp.data_path is None:
        return None
    from symrom.model.training import contact_rows, principal_encoder

    ds = run.dataset(exp.data_path)
    rows = contact_rows(ds, ds.rows_of("train"), "contact")
    return principal_encoder(ds.q[rows], l), "exact solver step (a) on go1_sim training data"


def sweep_rows(sweep: dict) -> list[list[str]]:
    s = figures.sweep_stats(sweep)
    best = figures.best_dim(sweep)
    return [[f"{d}{' (best)' if d == best else ''}", f"{fmt(s['E_mean'][i])}±{fmt(s['E_std'][i])}",
             f"{s['A_mean'][i]:.1f}±{s['A_std'][i]:.1f}", fmt(s["L_mod"][i])]
            for i, d in enumerate(s["dims"])]


def tradeoff_section(run: Run, fig_dir: Path) -> Section:
    sec = Section("tradeoff", "Latent dimension: encoder weights and accuracy vs complexity")
    sec.add("Encoder weights")
    for l in (2, 18):
        try:
            got = encoder_weights(run, l)
            if got is None:
                sec.add(Para(f"W_e for l = {l}: no go1_sim data or encoder in this run; heatmap skipped.",
                             note=True))
                continue
            W, source = got
            path = figures.encoder_heatmap(W, fig_dir / f"encoder_l{l}.png",
                                           title=rf"$W_e^T$, Go1, l = {l}")
            sec.add(Figure(path, f"Heatmap of W_e^T (rows: the 18 configuration components, columns: "
                                 f"latent 1..{l}); source: {source}"))
        except Exception as e:  # noqa: BLE001
            sec.add(Para(f"encoder heatmap l = {l} unavailable ({e}).", note=True))
    exp = run.experiments.get("go1_sim")
    comps = (exp.summary.get("config") or {}).get("encoder_components") if exp else None
    if comps and exp.model_path is not None:
        try:
            W = run.model(exp.model_path).autoencoder.W_e
            path = figures.encoder_heatmap(W, fig_dir / "encoder_go1_sim.png",
                                           title=rf"$W_e^T$, go1_sim model, l = {W.shape[0]}")
            sec.add(Figure(path, "Heatmap of W_e^T of the go1_sim experiment's model, whose encoder reads "
                                 + ", ".join(comps) + " (the heatmaps above are the paper's default encoder)"))
        except Exception as e:  # noqa: BLE001
            sec.add(Para(f"go1_sim encoder heatmap unavailable ({e}).", note=True))
    sec.add("Accuracy vs complexity")
    sweep = run.sweep
    if not sweep:
        return sec.add(Para("No sweep in this run (sweep/sweep.json); trade-off skipped.", note=True))
    try:
        lam = sweep.get("lambda", PAPER_LAMBDA)
        best = figures.best_dim(sweep)
        path = figures.tradeoff_figure(sweep, fig_dir / "tradeoff.png")
        sec.add(Figure(path, "E_dec and |Xi| (mean ± std over seeds) and L_mod per latent dimension"))
        sec.add(Para(f"L_mod = 2 E_dec + 2 λ log|Xi| with λ = {lam:g}; best latent dimension: {best} "
                     f"(the paper finds {PAPER_BEST_DIMS[0]}–{PAPER_BEST_DIMS[1]}). "
                     f"Seeds: {sweep.get('seeds', '?')}."))
        sec.add(Table(["latent dim l", "E_dec (mean±std)", "|Xi| (mean±std)", "L_mod"], sweep_rows(sweep),
                      caption="Trade-off per latent dimension"))
    except Exception as e:  # noqa: BLE001
        sec.add(Para(f"trade-off unavailable ({e}).", note=True))
    return sec


# --------------------------------------------------------------------------- equations, solvers
def _equations(run: Run, exp: Experiment) -> dict[str, list[str]] | None:
    eqs = exp.summary.get("equations")
    if eqs:
        return {k: [str(e) for e in v] for k, v in eqs.items()}
    if exp.model_path is None:
        return None
    return {k: [str(e) for e in v] for k, v in run.model(exp.model_path).equations(3).items()}


def equations_section(run: Run) -> Section:
    sec = Section("equations", "Learned equations per phase")
    sec.add(Para("Latent accelerations ddxi_j as sparse combinations of the library Θ(ξ, dξ, ν) "
                 "(xi: latent position, dxi: latent velocity, nu: latent input)."))
    for name, exp in _present_experiments(run, sec):
        try:
            eqs = _equations(run, exp)
        except Exception as e:  # noqa: BLE001
            eqs = None
            sec.add(Para(f"{name}: model file unreadable ({e}).", note=True))
        if not eqs:
            sec.add(Para(f"{name}: no equations (summary entry and model.json missing).", note=True))
            continue
        s = exp.summary
        active = s.get("active_terms") or {}
        meta = ", ".join(f"{k} {v}" for k, v in (("l =", s.get("latent_dim")), ("p =", s.get("poly_order")),
                                                   ("candidates:", s.get("n_candidates"))) if v is not None)
        terms = ", ".join(f"{k} {v}" for k, v in active.items())
        text = "\n".join(f"[{phase}]\n" + "\n".join(f"  ddxi{j} = {e}" for j, e in enumerate(rhs, 1))
                         for phase, rhs in eqs.items())
        sec.add(Pre(text, caption=f"{name}: {meta}" + (f"; active terms: {terms}" if terms else "")))
    return sec


def solvers_section(run: Run) -> Section | None:
    exp = run.experiments.get("go1_sim")
    solvers = (exp.summary.get("solvers") if exp else None) or {}
    if not solvers:
        return None
    sec = Section("solvers", "Solvers on SIM Go1 (exact vs adam)")
    rows = []
    for name, s in solvers.items():
        m = s.get("metrics") or {}
        full = m.get("horizons", {}).get("full", {})
        comps = full.get("components", {})
        rows.append([name, f"{s.get('wall_time_s', float('nan')):.3g}",
                     ", ".join(f"{k} {v}" for k, v in (s.get("active_terms") or {}).items()),
                     fmt(comps["x"]["mae"]) if "x" in comps else DASH,
                     fmt(comps["z"]["mae"]) if "z" in comps else DASH,
                     f"{full.get('diverged_jumps', '?')} of {m.get('n_jumps', '?')}"])
    return sec.add(Table(["solver", "training wall time [s]", "active terms", "full CoM x MAE [m]",
                          "full CoM z MAE [m]", "diverged (full)"], rows))


# --------------------------------------------------------------------------- data, reproduction
def dataset_row(path: Path, ds) -> list[str]:
    """File, robot, motion, source, dt, jumps per split, samples per jump and, per phase,
    the mean time per jump and its number of segments."""
    bounds = ds.jump_bounds()
    per_phase = []
    for k, name in enumerate(ds.phase_names):
        tot, segs = [], []
        for a, b in bounds:
            m = ds.phase[a:b] == k
            tot.append(m.sum() * ds.dt)
            segs.append(int(np.sum(np.diff(np.r_[0, m.astype(int)]) == 1)))
        per_phase.append(f"{name} {np.mean(tot):.3f} s ({np.mean(segs):.3g} seg.)")
    splits = " / ".join(str(int((ds.split == s).sum())) for s in ("train", "val", "test"))
    return [path.name, ds.robot, ds.motion, ds.source, f"{ds.dt:g}", f"{ds.n_jumps} ({splits})",
            f"{np.mean(bounds[:, 1] - bounds[:, 0]):.0f}", "; ".join(per_phase)]


def data_section(run: Run) -> Section:
    sec = Section("data", "Data summary")
    files = run.dataset_files()
    if not files:
        return sec.add(Para("No dataset files in this run (data/*.h5).", note=True))
    rows = []
    for p in files:
        try:
            rows.append(dataset_row(p, run.dataset(p)))
        except Exception as e:  # noqa: BLE001
            sec.add(Para(f"{p.name}: unreadable ({e}).", note=True))
    return sec.add(Table(["file", "robot", "motion", "source", "dt [s]", "jumps (train / val / test)",
                          "samples per jump", "phases: mean time per jump (segments)"], rows))


def run_section(run: Run) -> Section:
    sec = Section("run", "Commands, versions and seeds")
    r = run.summary.get("run") or {}
    if not r:
        return sec.add(Para("summary.json has no 'run' entry: commands, versions and seeds unknown.", note=True))
    sec.add(Pre(str(r.get("command") or "(command not recorded)"), caption="Command that produced this run"))
    versions = r.get("versions") or {}
    want = ["python", "numpy", "scipy", "pybullet", "symrom"]
    vrows = [[k, str(versions[k]) if k in versions else "not recorded"] for k in want]
    vrows += [[k, str(v)] for k, v in versions.items() if k not in want]
    sec.add(Table(["package", "version"], vrows, caption="Versions"))
    sec.add(Pre(json.dumps(r.get("seeds", {}), indent=1, sort_keys=True), caption="Seeds"))
    if r.get("wall_time_s") is not None:
        sec.add(Para(f"Wall time of the run: {float(r['wall_time_s']):.1f} s."))
    if r.get("config"):
        sec.add(Pre(json.dumps(r["config"], indent=1, sort_keys=True, default=str), caption="Configuration"))
    return sec
