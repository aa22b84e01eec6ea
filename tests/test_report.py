"""The report: a run directory built from planted data -> HTML page and Markdown twin."""

from __future__ import annotations

import json
import re
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from symrom.cli import app
from symrom.data.io import write_dataset
from symrom.evaluate.metrics import component_stats, evaluate
from symrom.evaluate.paper import PAPER_TABLE2, implied_rmse
from symrom.evaluate.tables import fmt_value
from symrom.model.persistence import save_model
from symrom.model.training import TrainConfig, reconstruction_error, train
from symrom.names import BASE_POS, TABLE2_COMPONENTS
from symrom.report import figures
from symrom.report.document import render_html
from symrom.report.html import build_report
from symrom.report.run import load_run
from symrom.report.sections import table2_section
from symrom.rollout.integrate import RolloutOptions
from symrom.testing import make_planted_dataset

SECTION_IDS = ("table2", "predictions", "aslip", "tradeoff", "equations", "solvers", "data", "run")
SECTION_TITLES = ("Table 2", "aSLIP", "accuracy vs complexity", "Learned equations",
                  "Data summary", "Commands, versions and seeds")


def _aslip_metrics(ds, run: Path) -> dict:
    """aSLIP metrics via the real module; a trivial stand-in (CoM held at its start) only
    if the module is absent."""
    try:
        from symrom.baselines.aslip import evaluate_aslip, fit_aslip
    except ImportError:
        errs = []
        for a, b in ds.jump_bounds()[ds.jumps_in("test")]:
            com = ds.q[a:b, BASE_POS]
            errs.append(com[:1] - com)
        comps = component_stats(np.concatenate(errs), ("x", "y", "z"))
        return {"model": "stand-in", "data": "", "split": "test", "n_jumps": int(ds.jumps_in("test").size),
                "horizons": {"full": {"diverged_jumps": 0, "components": comps}}}
    from dataclasses import asdict

    params = fit_aslip(ds, ds.rows_of("train"), 12.0)
    (run / "go1_sim" / "aslip").mkdir(parents=True, exist_ok=True)
    (run / "go1_sim" / "aslip" / "params.json").write_text(json.dumps(asdict(params)))
    return evaluate_aslip(params, ds, "test", method="rk4")


def _experiment(run: Path, name: str, ds) -> dict:
    write_dataset(ds, run / "data" / f"{name}.h5")
    model = train(ds, TrainConfig(latent_dim=2, poly_order=1))
    (run / name / "eval").mkdir(parents=True)
    save_model(model, run / name / "model.json")
    metrics, _ = evaluate(model, ds, "test", options=RolloutOptions(method="rk4"),
                          model_name=f"{name}/model.json", data_name=f"data/{name}.h5")
    (run / name / "eval" / "metrics.json").write_text(json.dumps(metrics))
    return {"latent_dim": 2, "poly_order": 1, "n_candidates": model.library.n_features,
            "active_terms": model.active_terms(),
            "equations": {k: [str(e) for e in v] for k, v in model.equations(3).items()},
            "metrics": metrics, "data": f"data/{name}.h5", "model": f"{name}/model.json"}


def _sweep(ds, dims=(1, 2, 3), seeds=(0, 1), lam=1e-3) -> dict:
    """A real (small) sweep: train each (dim, seed), E_dec on the val split."""
    E, A = [], []
    for l in dims:
        E.append([]), A.append([])
        for s in seeds:
            m = train(ds, TrainConfig(latent_dim=l, poly_order=1, seed=s))
            E[-1].append(reconstruction_error(m, ds, ds.rows_of("val")))
            A[-1].append(int(m.mask.sum()))
    L = [2 * np.mean(e) + 2 * lam * np.log(max(np.mean(a), 1)) for e, a in zip(E, A)]
    return {"latent_dims": list(dims), "seeds": list(seeds), "E_dec": E, "active_terms": A,
            "L_mod": L, "best_latent_dim": int(dims[int(np.argmin(L))]), "lambda": lam}


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    run = tmp_path_factory.mktemp("run")
    base, _ = make_planted_dataset(n_jumps=10, n_samples=240, embedding="block", seed=5)
    ds = replace(base, robot="go1", foot_pos=np.zeros((base.n_samples, 4, 3)))  # feet at the origin
    exps = {}
    for name, seed in (("go1_sim", 5), ("a1_sim", 6), ("go1_proxy", 7)):
        d = ds if seed == 5 else replace(make_planted_dataset(n_jumps=8, n_samples=240, seed=seed)[0],
                                         robot="a1" if name == "a1_sim" else "go1")
        exps[name] = _experiment(run, name, d)
    exps["go1_proxy"]["before_finetune"] = exps["go1_proxy"]["metrics"]
    aslip = _aslip_metrics(ds, run)
    (run / "go1_sim" / "aslip").mkdir(parents=True, exist_ok=True)
    (run / "go1_sim" / "aslip" / "metrics.json").write_text(json.dumps(aslip))
    exps["go1_sim"]["aslip"] = aslip
    exps["go1_sim"]["solvers"] = {"exact": {"wall_time_s": 0.1, "active_terms": exps["go1_sim"]["active_terms"],
                                            "metrics": exps["go1_sim"]["metrics"]}}
    sweep = _sweep(ds)
    (run / "sweep").mkdir()
    (run / "sweep" / "sweep.json").write_text(json.dumps(sweep))
    summary = {"experiments": exps, "sweep": sweep,
               "run": {"command": "symrom reproduce --out RUN --quick",
                       "versions": {"python": "3.11", "numpy": np.__version__, "symrom": "0.1.0"},
                       "seeds": {"seed": 0}, "wall_time_s": 1.5}}
    (run / "summary.json").write_text(json.dumps(summary))
    return run


@pytest.fixture(scope="module")
def built(run_dir, tmp_path_factory) -> tuple[str, str, Path]:
    out = tmp_path_factory.mktemp("out") / "report.html"
    html, md = build_report(run_dir, out, force=False)
    return html.read_text(), md.read_text(), out


def _external_links(text: str) -> list[str]:
    return re.findall(r"""(?:src|href)\s*=\s*["']?\s*(?:https?:)?//|url\(\s*["']?\s*(?:https?:)?//|@import""",
                      text, flags=re.I)


def test_html_has_every_section_and_no_external_resource(built):
    html, _, _ = built
    for sid in SECTION_IDS:
        assert f'<section id="{sid}">' in html
    for title in SECTION_TITLES:
        assert title in html
    assert html.count('src="data:image/png;base64,') >= 6  # 3 jumps, aSLIP, 2 heatmaps, trade-off
    assert not _external_links(html) and "http" not in html
    assert "<script" not in html and "<link" not in html
    assert "not in this run" not in html  # all three experiments present
    assert "go1_proxy before fine-tuning" in html
    assert html.count("reconstruction floor RMSE") == 3  # one row per experiment


def test_markdown_twin_has_the_same_sections_and_figures(built):
    html, md, out = built
    assert out.with_suffix(".md").is_file()
    for title in re.findall(r"<h2>(.*?)</h2>", html):
        assert f"## {title}" in md
    pngs = re.findall(r"!\[[^\]]*\]\((report_files/[^)]+\.png)\)", md)
    assert len(pngs) == html.count('src="data:image/png;base64,')
    for p in pngs:
        assert (out.parent / p).is_file()


def test_table2_numbers_equal_metrics_json(built, run_dir):
    html, md, _ = built
    for name in ("go1_sim", "a1_sim", "go1_proxy"):
        metrics = json.loads((run_dir / name / "eval" / "metrics.json").read_text())
        for key, h in metrics["horizons"].items():
            for c in TABLE2_COMPONENTS:
                s = h["components"][c]
                for text in (html, md):
                    assert f"{fmt_value(s['mean'])}±{fmt_value(s['std'])}" in text
                    assert fmt_value(s["rmse"]) in text
            paper = PAPER_TABLE2[name][key]
            assert f"{fmt_value(paper['x'][0])}±{fmt_value(paper['x'][1])}" in html
            assert fmt_value(implied_rmse(*paper["z"])) in html


def test_go1_only_run_builds_with_notes(run_dir, tmp_path):
    only = tmp_path / "only"
    shutil.copytree(run_dir, only, ignore=shutil.ignore_patterns("a1_sim*", "go1_proxy*", "sweep"))
    summary = json.loads((only / "summary.json").read_text())
    summary["experiments"] = {"go1_sim": summary["experiments"]["go1_sim"]}
    del summary["run"], summary["sweep"]
    (only / "summary.json").write_text(json.dumps(summary))
    html_path, md_path = build_report(only, tmp_path / "r.html")
    html = html_path.read_text()
    assert "a1_sim: not in this run" in html and "go1_proxy: not in this run" in html
    assert "Not in this run, skipped: a1_sim, go1_proxy." in html
    assert "commands, versions and seeds unknown" in html and "No sweep in this run" in html
    assert html.count('src="data:image/png;base64,') == 4  # jump, aSLIP, 2 heatmaps
    assert (tmp_path / "r_files").is_dir() and md_path == tmp_path / "r.md"


def test_diverged_jumps_are_shown(run_dir, tmp_path):
    only = tmp_path / "div"
    shutil.copytree(run_dir, only, ignore=shutil.ignore_patterns("data", "sweep"))
    mpath = only / "go1_sim" / "eval" / "metrics.json"
    m = json.loads(mpath.read_text())
    m["horizons"]["full"] = {"diverged_jumps": m["n_jumps"], "components": {}}
    mpath.write_text(json.dumps(m))
    html = render_html("t", [], [table2_section(load_run(only))])
    assert f"all {m['n_jumps']} jumps diverged" in html
    assert f"Full: {m['n_jumps']} of {m['n_jumps']}" in html
    assert '<p class="note">Diverged test jumps' in html


def test_cli_report_force_and_errors(tmp_path):
    run = tmp_path / "run"  # a run with nothing but its summary: quick to report
    run.mkdir()
    (run / "summary.json").write_text(json.dumps({"run": {"command": "symrom reproduce --out run"}}))
    runner = CliRunner()
    r = runner.invoke(app, ["report", str(run)])
    assert r.exit_code == 0, r.output
    assert str(run / "report.html") in r.output and (run / "report.md").is_file()
    html = (run / "report.html").read_text()
    assert "go1_sim: not in this run" in html and "No sweep in this run" in html
    r = runner.invoke(app, ["report", str(run)])
    assert r.exit_code == 1 and "--force" in r.output and "Traceback" not in r.output
    r = runner.invoke(app, ["report", str(run), "--out", str(tmp_path / "x.html"), "--force"])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["report", str(tmp_path / "nope")])
    assert r.exit_code == 1 and "no such run directory" in r.output


def test_figures_from_arrays(tmp_path):
    t = np.linspace(0, 0.5, 50)
    com = np.c_[t, 0 * t, 0.3 + 0.1 * np.sin(6 * t)]
    phase = (t > 0.2).astype(int)
    p = figures.aslip_figure(t, com, com + 0.01, None, phase, ["contact", "flight"], tmp_path / "a.png")
    assert p.read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(ValueError, match="columns"):
        figures.encoder_heatmap(np.ones((2, 5)), tmp_path / "h.png")
    sweep = {"latent_dims": [1, 2], "seeds": [0, 1], "E_dec": [[0.1, None], [0.05, 0.06]],
             "active_terms": [[5, 6], [9, 9]], "lambda": 1e-3}
    s = figures.sweep_stats(sweep)
    assert s["E_mean"][0] == pytest.approx(0.1) and figures.best_dim(sweep) == 2
    assert figures.tradeoff_figure(sweep, tmp_path / "t.png").is_file()
