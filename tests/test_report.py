"""The report: a run directory built from planted data -> HTML page and Markdown twin."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from symrom.cli import app
from symrom.data.io import write_dataset
from symrom.evaluate.metrics import evaluate_model
from symrom.evaluate.paper import PAPER_TABLE2, implied_rmse
from symrom.evaluate.records import BASELINE, FINE_TUNED, LEARNED, SOLVER, SWEEP, ManifestEntry, Metrics, RecordError
from symrom.evaluate.tables import fmt_value
from symrom.learn.training import TrainConfig, reconstruction_error, train
from symrom.model.persistence import save_model
from symrom.names import TABLE2_COMPONENTS
from symrom.report import figures
from symrom.report.context import Context
from symrom.report.document import Section, render_html
from symrom.report.html import build_report
from symrom.report.roles import build_sections
from symrom.report.run import load_run
from symrom.rollout.integrate import RolloutOptions
from symrom.testing import make_planted_dataset

SECTION_IDS = ("headline", "table2", "predictions", "baselines", "tradeoff", "equations", "solvers",
               "experiments", "data", "run")
SECTION_TITLES = ("Table 2", "baselines", "accuracy vs complexity", "Learned equations",
                  "Data summary", "Commands, versions and seeds")


def _aslip_metrics(ds, run: Path):
    """aSLIP metrics and parameters via the real module."""
    from dataclasses import asdict

    from symrom.baselines.aslip import ASlip, fit_aslip

    params = fit_aslip(ds, ds.rows_of("train"), 12.0)
    (run / "go1_sim" / "aslip").mkdir(parents=True, exist_ok=True)
    (run / "go1_sim" / "aslip" / "params.json").write_text(json.dumps(asdict(params)))
    return evaluate_model(ASlip(params), ds, "test", options=RolloutOptions(method="rk4"), model_name="aslip")[0]


def _experiment(run: Path, name: str, ds) -> dict:
    """Train and evaluate on ``ds``; the files, as a manifest entry's ``files``."""
    write_dataset(ds, run / "data" / f"{name}.h5")
    model = train(ds, TrainConfig(latent_dim=2, poly_order=1))
    (run / name / "eval").mkdir(parents=True)
    save_model(model, run / name / "model.json")
    metrics, _ = evaluate_model(model, ds, "test", options=RolloutOptions(method="rk4"),
                          model_name=f"{name}/model.json", data_name=f"data/{name}.h5")
    (run / name / "eval" / "metrics.json").write_text(json.dumps(metrics.to_dict()))
    return {"model": f"{name}/model.json", "metrics": f"{name}/eval/metrics.json", "data": f"data/{name}.h5"}


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


def _summary(run_dir: Path, entries: list[ManifestEntry], **extra) -> None:
    (run_dir / "summary.json").write_text(json.dumps({"manifest": [e.to_dict() for e in entries], **extra}))


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    run = tmp_path_factory.mktemp("run")
    base, _ = make_planted_dataset(n_jumps=10, n_samples=240, embedding="block", seed=5)
    ds = replace(base, robot="go1", foot_pos=np.zeros((base.n_samples, 4, 3)))  # feet at the origin
    files = {}
    for name, seed in (("go1_sim", 5), ("a1_sim", 6), ("go1_proxy", 7)):
        d = ds if seed == 5 else replace(make_planted_dataset(n_jumps=8, n_samples=240, seed=seed)[0],
                                         robot="a1" if name == "a1_sim" else "go1")
        files[name] = _experiment(run, name, d)
    aslip = _aslip_metrics(ds, run)
    (run / "go1_sim" / "aslip" / "metrics.json").write_text(json.dumps(aslip.to_dict()))
    sweep = _sweep(ds)
    (run / "sweep").mkdir()
    (run / "sweep" / "sweep.json").write_text(json.dumps(sweep))
    entries = [
        ManifestEntry("go1_sim", LEARNED, files=files["go1_sim"], paper="go1_sim",
                      facts={"config": {"encoder_components": ["x", "y", "z"], "decoded_weight": 0.0}}),
        ManifestEntry("a1_sim", LEARNED, files=files["a1_sim"], paper="a1_sim"),
        ManifestEntry("go1_proxy", FINE_TUNED, files={**files["go1_proxy"], "before": files["go1_proxy"]["metrics"]},
                      paper="go1_proxy"),
        ManifestEntry("go1_sim/aslip", BASELINE, "aSLIP", of="go1_sim", paper="aslip",
                      files={"metrics": "go1_sim/aslip/metrics.json", "params": "go1_sim/aslip/params.json"}),
        ManifestEntry("go1_sim/solvers/exact", SOLVER, "exact", of="go1_sim",
                      files={"model": files["go1_sim"]["model"], "metrics": files["go1_sim"]["metrics"]},
                      facts={"wall_time_s": 0.1}),
        ManifestEntry("sweep", SWEEP, of="go1_sim", files={"result": "sweep/sweep.json"}),
    ]
    _summary(run, entries, run={"command": "symrom reproduce --out RUN --quick",
                                "versions": {"python": "3.11", "numpy": np.__version__, "symrom": "0.1.0"},
                                "seeds": {"seed": 0}, "wall_time_s": 1.5})
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
    # 3 jumps, 3 horizon figures (error per component beside the floor), aSLIP, 3 heatmaps, trade-off
    assert html.count('src="data:image/png;base64,') == 11
    assert not _external_links(html) and "http" not in html
    assert "<script" not in html and "<link" not in html
    assert "go1_proxy before fine-tuning" in html and "unreadable" not in html
    assert html.count("reconstruction floor RMSE") == 6  # joints and base pose of three models
    assert '<section id="other">' not in html  # every role has its renderer


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


def test_tables_and_equations_fit_the_page(built):
    _, md, _ = built
    table2 = md[md.index("## Table 2"):md.index("## Predictions")]
    widths = [line.count("|") - 1 for line in table2.splitlines() if line.startswith("| horizon")]
    assert widths and max(widths) <= 8  # horizon, row and six components
    code = md[md.index("## Learned equations"):md.index("## Solvers")]
    assert max(len(line) for line in code.splitlines() if line.startswith("  ")) <= 100


def test_a_run_holding_one_experiment_renders(run_dir, tmp_path):
    only = tmp_path / "only"
    shutil.copytree(run_dir, only, ignore=shutil.ignore_patterns("a1_sim*", "go1_proxy*", "sweep"))
    _summary(only, [ManifestEntry("go1_sim", LEARNED, files={
        "model": "go1_sim/model.json", "metrics": "go1_sim/eval/metrics.json", "data": "data/go1_sim.h5"})])
    html_path, md_path = build_report(only, tmp_path / "r.html")
    html = html_path.read_text()
    ids = re.findall(r'<section id="([a-z0-9]+)">', html)
    assert ids == ["headline", "table2", "predictions", "equations", "experiments", "data", "run"]
    assert "commands, versions and seeds unknown" in html and "paper row" not in html
    assert html.count('src="data:image/png;base64,') == 2  # its test jump, its errors beside the floor
    assert (tmp_path / "r_files").is_dir() and md_path == tmp_path / "r.md"


def test_a_new_experiment_of_a_known_role_appears_and_an_unknown_role_falls_back(run_dir, tmp_path):
    run = tmp_path / "more"
    # Without the data the sections are the same, less the figures drawn from it.
    shutil.copytree(run_dir, run, ignore=shutil.ignore_patterns("sweep", "a1_sim*", "go1_proxy*", "data"))
    files = {"model": "go1_sim/model.json", "metrics": "go1_sim/eval/metrics.json", "data": "data/go1_sim.h5"}
    _summary(run, [ManifestEntry("go1_sim", LEARNED, files=files),
                   ManifestEntry("go1_sim/retrained", LEARNED, "a second training", files=files, of="go1_sim"),
                   ManifestEntry("go1_sim/ablation", "ablation", files={"metrics": files["metrics"]}),
                   ManifestEntry("notes", "diary", files={})])
    html = render_html("t", [], build_sections(load_run(run), Context(load_run(run), tmp_path)))
    assert "go1_sim/retrained — a second training" in html
    assert html.count("go1_sim/retrained, test jumps") == 2  # its joints and base-pose tables
    assert '<section id="other">' in html and "go1_sim/ablation (ablation)" in html
    assert "go1_sim/ablation: RMSE per component" in html and "No renderer for role &#x27;diary&#x27;" in html


def test_missing_files_and_a_missing_manifest_become_notes(run_dir, tmp_path):
    run = tmp_path / "broken"
    shutil.copytree(run_dir, run, ignore=shutil.ignore_patterns("sweep", "go1_*"))
    # The two broken entries alone: their notes do not need the other experiments' figures drawn.
    _summary(run, [ManifestEntry("a1_sim", LEARNED, paper="a1_sim", files={
                       "model": "a1_sim/model.json", "metrics": "a1_sim/eval/metrics.json", "data": "data/a1_sim.h5"}),
                   ManifestEntry("sweep", SWEEP, files={"result": "sweep/sweep.json"})])
    (run / "a1_sim" / "eval" / "metrics.json").write_text('{"n_jumps": 2, "horizons": {"full": {}}}')
    html = build_report(run, tmp_path / "b.html")[0].read_text()
    assert ("a1_sim/eval/metrics.json is unreadable (metrics.json: key horizons.full.components: missing)"
            in html)
    assert "sweep: result file sweep/sweep.json is missing" in html
    (run / "summary.json").write_text(json.dumps({"experiments": {}}))
    html = build_report(run, tmp_path / "c.html")[0].read_text()
    assert "has no manifest" in html and "This run lists no experiments." in html


def test_diverged_jumps_are_shown(run_dir, tmp_path):
    only = tmp_path / "div"
    shutil.copytree(run_dir, only, ignore=shutil.ignore_patterns("data", "sweep", "a1_sim*", "go1_proxy*"))
    # go1_sim alone, whose metrics are changed: the other experiments' figures would add nothing.
    _summary(only, [ManifestEntry("go1_sim", LEARNED, paper="go1_sim", files={
        "model": "go1_sim/model.json", "metrics": "go1_sim/eval/metrics.json", "data": "data/go1_sim.h5"})])
    mpath = only / "go1_sim" / "eval" / "metrics.json"
    m = json.loads(mpath.read_text())
    m["horizons"]["full"] = {"diverged_jumps": m["n_jumps"], "components": {}}
    mpath.write_text(json.dumps(m))
    run = load_run(only)
    html = render_html("t", [], build_sections(run, Context(run, tmp_path)))
    assert f"all {m['n_jumps']} jumps diverged" in html
    assert f"Full: {m['n_jumps']} of {m['n_jumps']}" in html
    assert '<p class="note">Diverged test jumps' in html
    # One jump diverged late: scored up to it (format 2), and when it diverged is shown.
    m = json.loads(mpath.read_text())
    m["horizons"]["full"] = dict(m["horizons"]["0.1"], diverged_jumps=1, diverged=[{"jump": 4, "t": 1.438}])
    mpath.write_text(json.dumps(m))
    run = load_run(only)
    html = render_html("t", [], build_sections(run, Context(run, tmp_path)))
    assert "ours mean±std (1 diverged, scored up to it)" in html
    assert f"Full: 1 of {m['n_jumps']} (jump 4 at 1.438 s)" in html and "scored up to the time it diverged" in html
    m.pop("format_version")  # a file of version 1: diverged jumps were left out
    mpath.write_text(json.dumps(m))
    run = load_run(only)
    html = render_html("t", [], build_sections(run, Context(run, tmp_path)))
    assert "ours mean±std (1 diverged, left out)" in html and "left out of the statistics" in html


def test_metrics_records_read_what_later_versions_add():
    d = {"model": "m", "data": "d", "split": "test", "n_jumps": 2, "integrator": "rk4", "selected": True,
         "horizons": {"full": {"diverged_jumps": 1, "diverged": [{"jump": 4, "t": 0.312}],
                               "components": {c: {"mean": 0.1, "std": 0.2, "mae": 0.15, "rmse": 0.3}
                                              for c in ("x", "y", "z")}}}}
    m = Metrics.from_dict(d)
    full = m.horizons["full"]
    assert full.diverged[0].jump == 4 and full.diverged[0].t == 0.312 and set(full.components) == {"x", "y", "z"}
    assert full.stat("z", "rmse") == 0.3 and full.stat("fl_hx", "rmse") is None and m.any_diverged
    assert m.to_dict() == d and m.extra == {"selected": True}
    bad = json.loads(json.dumps(d))
    bad["horizons"]["full"]["components"]["y"]["rmse"] = "x"
    with pytest.raises(RecordError, match=r"^metrics\.horizons\.full\.components\.y\.rmse: expected float"):
        Metrics.from_dict(bad)
    with pytest.raises(RecordError, match=r"diverged\[0\]\.t: missing"):
        Metrics.from_dict({"n_jumps": 1, "horizons": {"full": {"diverged_jumps": 1, "components": {},
                                                               "diverged": [{"jump": 0}]}}})


def test_cli_report_force_and_errors(tmp_path):
    run = tmp_path / "run"  # a run with nothing but its summary: quick to report
    run.mkdir()
    (run / "summary.json").write_text(json.dumps({"run": {"command": "symrom reproduce --out run"}}))
    runner = CliRunner()
    r = runner.invoke(app, ["report", str(run)])
    assert r.exit_code == 0, r.output
    assert str(run / "report.html") in r.output and (run / "report.md").is_file()
    html = (run / "report.html").read_text()
    assert "has no manifest" in html and "This run lists no experiments." in html
    r = runner.invoke(app, ["report", str(run)])
    assert r.exit_code == 1 and "--force" in r.output and "Traceback" not in r.output
    r = runner.invoke(app, ["report", str(run), "--out", str(tmp_path / "x.html"), "--force"])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["report", str(tmp_path / "nope")])
    assert r.exit_code == 1 and "no such run directory" in r.output


def test_report_refuses_a_folder_that_is_not_a_run(tmp_path):
    from conftest import one_line_error

    folder = tmp_path / "photos"
    folder.mkdir()
    (folder / "cat.txt").write_text("not a run")
    one_line_error(CliRunner().invoke(app, ["report", str(folder)]), str(folder), "not a run directory",
                   "summary.json")
    assert sorted(p.name for p in folder.iterdir()) == ["cat.txt"]


def test_figures_from_arrays(tmp_path):
    t = np.linspace(0, 0.5, 50)
    com = np.c_[t, 0 * t, 0.3 + 0.1 * np.sin(6 * t)]
    phase = (t > 0.2).astype(int)
    p = figures.com_figure(t, com, com + 0.01, {}, phase, ["contact", "flight"], tmp_path / "a.png")
    assert p.read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(ValueError, match="columns"):
        figures.encoder_heatmap(np.ones((2, 5)), tmp_path / "h.png")
    sweep = {"latent_dims": [1, 2], "seeds": [0, 1], "E_dec": [[0.1, None], [0.05, 0.06]],
             "active_terms": [[5, 6], [9, 9]], "lambda": 1e-3}
    s = figures.sweep_stats(sweep)
    assert s["E_mean"][0] == pytest.approx(0.1) and figures.best_dim(sweep) == 2
    assert figures.tradeoff_figure(sweep, tmp_path / "t.png").is_file()


# ---------------------------------------------------------------- readable at 1400 px
def test_page_structure_is_readable(built):
    """Every table scrolls inside its own box, numbers right and text left, no unlabelled
    column, the run's files are links that resolve, Table 2's words agree with its note."""
    html, _, out = built
    assert html.count("<table") == html.count('<div class="scroll"><table')
    assert ".scroll{overflow-x:auto" in html
    assert "<th></th>" not in html and '<th class="num"></th>' not in html
    # Table 2: the "row" column is text (left), the component columns numbers (right).
    head = re.search(r"<thead><tr><th>horizon</th><th>row</th>(.*?)</tr></thead>", html).group(1)
    assert head.startswith('<th class="num">fl_hx [rad]</th>')
    assert "<td>ours RMSE</td>" in html and re.search(r'<td class="num">\d\.\de-\d</td>', html)
    # The experiments' files are links, relative to the report, to files that exist.
    hrefs = re.findall(r'<a href="([^"#][^"]*)">', html)
    assert len(hrefs) >= 10
    for h in hrefs:
        assert (out.parent / h).exists(), h
    table2 = html[html.index('<section id="table2">'):]
    table2 = table2[:table2.index("</section>")]
    assert "excluded" not in table2 and "scored up to the time it diverged, and counted" in table2


def test_configuration_is_a_collapsed_table_not_json(tmp_path):
    from symrom.report.common import run_blocks
    from symrom.report.document import Table
    from symrom.report.run import Run

    config = {"seed": 0, "datasets": [{"name": "go1_sim", "jumps": 156}, {"name": "a1_sim", "jumps": 150}],
              "selection": {"thresholds": [0.001, 0.01], "refine_top": 3}}
    run = Run(tmp_path, {"run": {"command": "symrom demo", "config": config}}, [])
    blocks = run_blocks(run)
    table = next(b for b in blocks if isinstance(b, Table) and b.caption.startswith("Configuration"))
    assert table.collapsed and ["datasets[1].jumps", "150"] in table.rows
    assert ["selection.thresholds", "0.001, 0.01"] in table.rows
    page = render_html("t", [], [Section("run", "run").add(*blocks)])
    assert "<details><summary>Configuration of the run (7 rows)</summary>" in page
    assert '"refine_top"' not in page  # no JSON dump


def _figure_of(monkeypatch, fn, *args, **kwargs):
    """The matplotlib figure ``fn`` draws (captured where it is saved)."""
    seen = {}
    real = figures._save

    def keep(fig, path):
        seen["fig"] = fig
        return real(fig, path)

    monkeypatch.setattr(figures, "_save", keep)
    fn(*args, **kwargs)
    return seen["fig"]


def test_tradeoff_figure_has_one_y_axis_per_panel_and_honest_units(run_dir, tmp_path, monkeypatch):
    sweep = json.loads((run_dir / "sweep" / "sweep.json").read_text())
    fig = _figure_of(monkeypatch, figures.tradeoff_figure, sweep, tmp_path / "t.png")
    boxes = [tuple(np.round(ax.get_position().bounds, 3)) for ax in fig.axes]
    assert len(boxes) == 3 and len(set(boxes)) == 3  # three panels, no twin axes
    labels = " ".join(ax.get_ylabel() for ax in fig.axes)
    assert "rad$^2$/m$^2$" not in labels and "rad$^2$ + m$^2$" in labels


def test_full_horizon_line_is_drawn_on_top_of_the_reset_line(run_dir, tmp_path, monkeypatch):
    from symrom.data.io import read_dataset
    from symrom.evaluate import plots
    from symrom.model.persistence import load_model
    from symrom.rollout.integrate import rollout

    ds = read_dataset(run_dir / "data" / "go1_sim.h5")
    model = load_model(run_dir / "go1_sim" / "model.json")
    j = int(ds.jumps_in("test")[0])
    ros = {k: rollout(model, ds, [j], RolloutOptions(method="rk4", reset=r)) for k, r in (("full", None), ("0.1", 0.1))}
    seen = {}
    real = plots.write_with

    def keep(path, writer):  # the lines as they are drawn; the kept figure is cleared after
        seen["lines"] = plots._Panels.of(plots.JOINT_PANELS + plots.BASE_PANELS).axes[0, 0].get_lines()
        return real(path, writer)

    monkeypatch.setattr(plots, "write_with", keep)
    plots.plot_jump(ds, ros, j, tmp_path / "j.png")
    lines = {ln.get_label(): ln for ln in seen["lines"]}
    full, reset = lines["predicted, full horizon"], lines["predicted, 0.1 s resets"]
    assert full.get_zorder() > reset.get_zorder() and full.get_linestyle() == "--"
    assert reset.get_linewidth() > full.get_linewidth()  # the reset line shows around the dashes


def test_horizon_figure_draws_the_reconstruction_floor(built):
    html, md, _ = built
    assert "RMSE of each Table 2 component at each horizon beside the reconstruction floor" in html
    assert re.search(r"!\[go1_sim: RMSE of each Table 2 component[^\]]*\]\(report_files/horizons_go1_sim\.png\)", md)


CHROMIUM = next((p for p in (shutil.which("chromium"), shutil.which("chromium-browser"), "/usr/bin/chromium")
                 if p and Path(p).is_file()), None)
# As root on a machine without a network: no sandbox, no GPU, none of Chromium's own connections.
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                  "--disable-component-update", "--no-first-run", "--disable-sync")
WINDOW = (1400, 1000)  # px: the first screen

# Written into the page's body on load: page width and height, tables wider than a box that does not
# scroll, the headline section's top and bottom and its first table's bottom, figures that did not
# load or overflow the window, and the sections' ids in order.
PROBE = """<script>window.addEventListener('load',()=>{const d=document.documentElement;let clipped=0;
for(const t of document.querySelectorAll('table')){const box=t.parentElement;
if(t.scrollWidth>box.clientWidth+1&&getComputedStyle(box).overflowX!=='auto')clipped++;}
const head=document.getElementById('headline');const r=head?head.getBoundingClientRect():{top:-1,bottom:-1};
const t=head?head.querySelector('table').getBoundingClientRect():{top:-1,bottom:-1};
let broken=0,wide=0;const imgs=document.querySelectorAll('img');
for(const i of imgs){if(!i.complete||i.naturalWidth===0)broken++;if(i.getBoundingClientRect().right>innerWidth)wide++;}
const ids=[...document.querySelectorAll('section')].map(s=>s.id).join(' ');
document.body.setAttribute('data-probe',[d.scrollWidth,d.scrollHeight,clipped,Math.round(r.top),
Math.round(r.bottom),Math.round(t.top),Math.round(t.bottom),imgs.length,broken,wide].join(',')+';'+ids);});</script>"""


def _chromium(*args, tmp_path: Path) -> subprocess.CompletedProcess:
    return subprocess.run([CHROMIUM, *CHROMIUM_FLAGS, f"--user-data-dir={tmp_path / 'profile'}",
                           f"--window-size={WINDOW[0]},{WINDOW[1]}", *args], capture_output=True, text=True,
                          timeout=180)


@pytest.mark.skipif(CHROMIUM is None, reason="no headless Chromium on this machine")
def test_report_first_screen_in_a_real_browser(built, tmp_path):
    """Headless Chromium at 1400 x 1000 px: the headline (its Table 2 counts) is in the first screen,
    the page never scrolls sideways (wide tables scroll in their own box), every figure loads and
    fits the window; and the screenshot shows it: the headline's table is painted where the page
    lays it out, below the title, above the fold."""
    from PIL import Image

    html, _, out = built
    probe = tmp_path / "probe.html"
    probe.write_text(html.replace("</body>", PROBE + "</body>"))
    dom = _chromium("--dump-dom", probe.as_uri(), tmp_path=tmp_path).stdout
    numbers, ids = re.search(r'data-probe="([-\d,]+);([a-z0-9 ]+)"', dom).groups()
    (width, height, clipped, head_top, head_bottom, table_top, table_bottom, figures_n, broken,
     wide) = map(int, numbers.split(","))
    assert width <= WINDOW[0] and clipped == 0, (width, clipped)
    assert ids.split()[0] == "headline" and ids.split()[-3:] == ["experiments", "data", "run"], ids
    assert 0 < head_top < table_top < table_bottom <= WINDOW[1], (head_top, table_bottom)  # above the fold
    assert figures_n == html.count('src="data:image/png;base64,') and broken == 0 and wide == 0
    assert height > 3 * WINDOW[1]  # the details follow below
    shot = tmp_path / "report.png"
    _chromium(f"--screenshot={shot}", out.as_uri(), tmp_path=tmp_path)
    image = np.asarray(Image.open(shot).convert("L"), dtype=float)
    assert image.shape == (WINDOW[1], WINDOW[0])
    ink = (image < 128).mean(axis=1)  # per screen row: the share of dark pixels (text)
    lines = (image < 235).mean(axis=1)  # and of pixels that are not white (the tables' grey borders)
    assert ink[:head_top].max() > 0.05  # the title and the run's line are painted
    headline = html[html.index('<section id="headline">'):]
    rows = headline[:headline.index("</table>")].count("<tr>")  # the header and one row per experiment
    box = lines[table_top:table_bottom + 1]
    borders = int(np.sum((box[1:] > 0.5) & (box[:-1] <= 0.5))) + int(box[0] > 0.5)  # rules across the table
    assert borders >= rows + 1, (borders, rows)  # its grid is drawn where the page lays it out
    assert (ink[table_top:table_bottom] > 0.005).mean() > 0.4  # and its cells hold text


# ---------------------------------------------------------------- the headline
def _section(html: str, sid: str) -> str:
    s = html[html.index(f'<section id="{sid}">'):]
    return s[:s.index("</section>")]


def test_headline_comes_first_with_table2_counts_terms_and_baseline_ratios(built, run_dir):
    html, md, _ = built
    assert re.findall(r'<section id="([a-z0-9]+)">', html)[0] == "headline"
    assert md.index("## Headline") < md.index("## Table 2")
    head = _section(html, "headline")
    for name in ("go1_sim", "a1_sim", "go1_proxy"):
        metrics = json.loads((run_dir / name / "eval" / "metrics.json").read_text())
        want = [sum(metrics["horizons"][h]["components"][c]["rmse"] <= implied_rmse(*PAPER_TABLE2[name][h][c])
                    for c in TABLE2_COMPONENTS) for h in ("full", "0.1")]
        row = re.search(rf"<tr><td>{name}</td>(.*?)</tr>", head).group(1)
        assert [int(n) for n in re.findall(r">(\d+) of 12<", row)] == want, name
        model = json.loads((run_dir / name / "model.json").read_text())
        terms = sum(int(np.sum(p["mask"])) for p in model["phases"].values())
        assert f">{terms} (" in row
    learned = json.loads((run_dir / "go1_sim" / "eval" / "metrics.json").read_text())["horizons"]["full"]
    aslip = json.loads((run_dir / "go1_sim" / "aslip" / "metrics.json").read_text())["horizons"]["full"]
    ratio = aslip["components"]["x"]["mae"] / learned["components"]["x"]["mae"]
    assert (f"{ratio:.3g}×" if ratio < 1000 else f"{ratio:.0f}×") in head
    assert "x 3.56×, z 2.38×" in head  # the paper's aSLIP / learned, beside


def test_headline_counts_the_sim2real_targets_met(tmp_path):
    from symrom.report.document import Table
    from symrom.report.headline import headline_blocks, table2_counts
    from symrom.report.run import Run

    checks = {"source_z": True, "fine_tuned_z": True, "not_above_source": True, "flight_gravity": False,
              "vs_target_alone": None, "scratch_ratio_x": 0.5}
    run = Run(tmp_path, {"sim2real": {"targets": {"go1_proxy": {"engine": "pybullet", "checks": checks},
                                                  "go1_proxy_mujoco": {"engine": "mujoco", "checks": {
                                                      k: True for k in checks if k != "scratch_ratio_x"}}}}}, [])
    table = next(b for b in headline_blocks(run) if isinstance(b, Table))
    assert table.rows == [["go1_proxy", "pybullet", "3 of 5", "flight gravity; not checked: vs target alone"],
                          ["go1_proxy_mujoco", "mujoco", "5 of 5", "none"]]
    # Table 2's count: components at the paper's implied RMSE count, a diverged one (no RMSE) does not.
    ref = {h: {c: implied_rmse(*PAPER_TABLE2["a1_sim"][h][c]) for c in TABLE2_COMPONENTS} for h in ("full", "0.1")}
    comps = {h: {c: {"mean": 0.0, "std": 0.0, "mae": 0.0, "rmse": ref[h][c] * (1.0 if k < 7 else 1.5)}
                 for k, c in enumerate(TABLE2_COMPONENTS)} for h in ref}
    del comps["0.1"]["fl_hx"]
    m = Metrics.from_dict({"n_jumps": 2, "horizons": {h: {"diverged_jumps": 0, "components": comps[h]} for h in ref}})
    assert table2_counts("a1_sim", m) == {"full": 7, "0.1": 6}
    assert table2_counts("nope", m) == {"full": None, "0.1": None}


def test_horizon_figure_draws_the_papers_rmse(built, tmp_path, monkeypatch):
    html, _, _ = built
    assert html.count("and the paper&#x27;s implied RMSE (a bar in the horizon&#x27;s colour)") == 2 * 3  # alt, caption
    rmse = {"Full": {c: 0.1 for c in TABLE2_COMPONENTS}, "0.1 s": {c: 0.01 for c in TABLE2_COMPONENTS}}
    paper = {label: {c: implied_rmse(*PAPER_TABLE2["go1_sim"][h][c]) for c in TABLE2_COMPONENTS}
             for label, h in (("Full", "full"), ("0.1 s", "0.1"))}
    fig = _figure_of(monkeypatch, figures.horizon_figure, rmse, None, tmp_path / "h.png", paper=paper)
    seen = 0
    for ax, (_, comps) in zip(fig.axes, figures.HORIZON_PANELS):
        lines = {ln.get_label(): ln for ln in ax.get_lines()}
        for label in paper:
            np.testing.assert_allclose(lines[f"paper, {label}"].get_ydata(), [paper[label][c] for c in comps])
            # in the colour of our points at that horizon
            assert lines[f"paper, {label}"].get_color() == lines[f"ours, {label}"].get_color()
            seen += 1
    assert seen == 6
    fig = _figure_of(monkeypatch, figures.horizon_figure, rmse, None, tmp_path / "h2.png")
    assert not [ln for ax in fig.axes for ln in ax.get_lines() if ln.get_label().startswith("paper")]


def test_horizon_panels_over_many_decades_drop_minor_ticks_and_narrow_ones_keep_their_labels(tmp_path,
                                                                                              monkeypatch):
    from matplotlib.ticker import NullLocator

    # with the floor at half of each: joint angles over 5 decades, the CoM position within a factor of
    # 2.3 (and no power of ten), the orientation within 17
    rmse = {"full": {c: 10.0 ** -(1 + k % 6) if k < 6 else (0.02 + 0.002 * k if k < 9 else 0.3 / (k - 7) ** 3)
                     for k, c in enumerate(TABLE2_COMPONENTS)}}
    floor = {c: v / 2 for c, v in rmse["full"].items()}
    fig = _figure_of(monkeypatch, figures.horizon_figure, rmse, floor, tmp_path / "h.png")
    wide, narrow, middle = fig.axes[:3]
    assert isinstance(wide.yaxis.get_minor_locator(), NullLocator)
    assert not isinstance(narrow.yaxis.get_minor_locator(), NullLocator)
    assert not isinstance(middle.yaxis.get_minor_locator(), NullLocator)
    lo, hi = narrow.get_ylim()  # no power of ten inside: the minor ticks carry the values
    assert not [v for v in narrow.get_yticks() if lo <= v <= hi]
    labels = [t.get_text() for t in narrow.get_yticklabels(minor=True) if lo <= t.get_position()[1] <= hi]
    assert len([t for t in labels if t]) >= 2, labels


def test_selection_figure_names_the_yardstick_its_score_divides_by(tmp_path, monkeypatch):
    from symrom.evaluate.records import SELECTION
    from symrom.report.run import Run
    from symrom.report.selection import selection_blocks

    row = {"encoder": "base_position", "latent_dim": 2, "library": "poly1", "threshold": 0.01, "refine": False,
           "active_terms": 5, "score": 0.5, "horizons": {h: {"score": 0.5, "worst": 0.8, "diverged_jumps": 0}
                                                         for h in ("full", "0.1")}}
    for reference, want in ((None, "spread"), ({"full": {"x": 0.01}}, "paper's RMSE")):
        (tmp_path / "s").mkdir(exist_ok=True)
        (tmp_path / "s" / "selection.json").write_text(json.dumps(
            {"config": {"reference": reference}, "rows": [row], "chosen": 0, "rule": "r", "seconds": 1}))
        entry = ManifestEntry("go1_sim/selection", SELECTION, files={"table": "s/selection.json"}, of="go1_sim")
        run = Run(tmp_path, {}, [entry])
        fig = _figure_of(monkeypatch, selection_blocks, run, [entry], Context(run, tmp_path))
        assert fig.axes[0].get_ylabel() == f"validation score (mean RMSE / {want})"


def test_figures_drawn_in_other_processes_are_the_same_files(built, run_dir, tmp_path):
    # workers=2: a second process draws whichever figure comes while it is free; the page and
    # every figure must equal the one-process report's, byte for byte (the build time aside).
    _, md_one, out_one = built
    html, md = build_report(run_dir, tmp_path / "report.html", workers=2)
    one = sorted((out_one.parent / "report_files").glob("*.png"))
    two = sorted((tmp_path / "report_files").glob("*.png"))
    assert [p.name for p in one] == [p.name for p in two] and len(one) >= 5
    for a, b in zip(one, two):
        assert a.read_bytes() == b.read_bytes(), a.name
    built_at = re.compile(r"Built \d{4}-\d\d-\d\d \d\d:\d\d UTC")
    assert built_at.sub("", md.read_text()) == built_at.sub("", md_one)


def test_an_error_in_a_figure_drawn_in_another_process_is_raised(tmp_path):
    from symrom.report import figures
    from symrom.report.context import Drawing

    drawing = Drawing(2)
    try:  # the first figure goes to the other process; its error comes back at finish
        path = drawing.draw(figures.encoder_heatmap, np.zeros((2, 5)), tmp_path / "bad.png")
        assert path == tmp_path / "bad.png"
        with pytest.raises(ValueError, match="5 columns, expected 18"):
            drawing.finish()
    finally:
        drawing.close()
    assert not path.exists()


def _dies_elsewhere(path):
    """A figure whose drawing process dies unless it is the report's own."""
    import multiprocessing
    import os

    if multiprocessing.parent_process() is not None:
        os._exit(1)
    Path(path).write_bytes(b"drawn here")


def test_figures_of_a_dead_drawing_process_are_drawn_here(tmp_path):
    from symrom.report.context import Drawing

    drawing = Drawing(2)
    try:
        path = drawing.draw(_dies_elsewhere, tmp_path / "f.png")
        drawing.finish()  # the other process died: its figure is drawn in this one
        assert path.read_bytes() == b"drawn here"
        second = drawing.draw(_dies_elsewhere, tmp_path / "g.png")  # the pool is gone: here at once
        assert second.read_bytes() == b"drawn here"
    finally:
        drawing.close()
