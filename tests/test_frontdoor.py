"""What a new user meets first: true plot titles, outputs refused before any work, hints,
clean pipes, the version, reports of a model folder."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import one_line_error
from typer.testing import CliRunner

import symrom
from symrom.cli import app
from symrom.data.io import write_dataset
from symrom.model.persistence import load_model
from symrom.testing import make_planted_dataset

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[1]


def _run(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    ds, _ = make_planted_dataset(n_jumps=6, n_samples=80, seed=7)
    path = tmp_path_factory.mktemp("data") / "good.h5"
    write_dataset(ds, path)
    return ds, path


@pytest.fixture(scope="module")
def model(data, tmp_path_factory):
    out = tmp_path_factory.mktemp("runs") / "run"
    r = _run("train", data[1], "--out", out)
    assert r.exit_code == 0, r.output
    return out / "model.json"


# ----------------------------------------------------------------- 1: --plot-jump
def test_plot_jump_counts_the_jumps_of_the_evaluated_split(data, model, tmp_path, monkeypatch):
    import importlib

    outputs = importlib.import_module("symrom.evaluate.outputs")  # symrom.evaluate is also a function
    ds, path = data
    test_jumps = ds.jumps_in("test")
    assert test_jumps.size and test_jumps[0] != 0 and ds.split[0] == "train"
    titles = {}
    real = outputs.plot_jump

    def spy(ds_, rollouts, jump, p, title=""):
        titles[jump] = title
        return real(ds_, rollouts, jump, p, title=title)

    monkeypatch.setattr(outputs, "plot_jump", spy)
    out = tmp_path / "ev"
    r = _run("evaluate", model, path, "--split", "test", "--plot-jump", 0, "--integrator", "rk4", "--out", out)
    assert r.exit_code == 0, r.output
    j = int(test_jumps[0])
    # The plotted jump is the split's first, and its title and file say which it is.
    assert list(titles) == [j] and ds.split[j] == "test"
    assert f"test jump 0 (dataset jump {j})" in titles[j]
    assert (out / f"jump_{j}.png").is_file() and not (out / "jump_0.png").exists()
    assert f"plot: {out / f'jump_{j}.png'}" in r.output.replace("\n", "")
    # An index past the split's jumps is refused, naming the split.
    one_line_error(_run("evaluate", model, path, "--split", "test", "--plot-jump", test_jumps.size,
                        "--out", tmp_path / "ev2"), "--plot-jump", "test split")


# ----------------------------------------------------------------- 3: unwritable --out
def _commands(data_path: Path, model_path: Path, tmp: Path) -> dict[str, list]:
    log = tmp / "log.csv"
    log.write_text("t\n0\n")
    return {
        "train": ["train", data_path, "--out", "{out}"],
        "train --select": ["train", data_path, "--select", "--out", "{out}"],
        "evaluate": ["evaluate", model_path, data_path, "--out", "{out}"],
        "export": ["export", model_path, "--to", "python", "--out", "{out}"],
        "import": ["import", log, "--robot", "go1", "--out", "{out}.h5"],
        "sweep": ["sweep", data_path, "--latent-dims", "2", "--seeds", "1", "--out", "{out}"],
        "report": ["report", tmp, "--out", "{out}.html"],
        "demo": ["demo", "--out", "{out}"],
        "generate": ["generate", "--robot", "go1", "--motion", "pronk", "--jumps", "3", "--out", "{out}.h5"],
        "finetune": ["finetune", model_path, data_path, "--out", "{out}"],
        "aslip": ["aslip", data_path, "--out", "{out}"],
        "newton": ["newton", data_path, "--out", "{out}"],
        "reproduce": ["reproduce", "--quick", "--out", "{out}"],
        "jump": ["jump", "--planner", "point-mass", "--target-x", "0.2", "--out", "{out}"],
    }


COMMANDS = ["train", "train --select", "evaluate", "export", "import", "sweep", "report", "demo", "generate",
            "finetune", "aslip", "newton", "reproduce", "jump"]


@pytest.mark.parametrize("variant", ["under a file", "read-only folder"])
@pytest.mark.parametrize("command", COMMANDS)
def test_an_unwritable_out_is_refused_before_any_work(command, variant, data, model, tmp_path):
    if variant == "under a file":
        blocker = tmp_path / "a_file"
        blocker.write_text("a regular file, not a folder\n")
        out = blocker / "out"
    else:
        if os.geteuid() == 0:
            pytest.skip("root writes into read-only folders; the file-in-the-way variant covers root")
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        out = ro / "out"
    args = [str(out) + a[5:] if isinstance(a, str) and a.startswith("{out}") else a
            for a in _commands(data[1], model, tmp_path)[command]]
    try:
        r = _run(*args)
        line = one_line_error(r, str(out))
        assert "not a folder" in line or "not writable" in line, line
        assert "/." not in line.replace(str(tmp_path), "")  # no hidden temporary file named
        assert "training rows" not in r.output and "%" not in r.output  # refused before any work
    finally:
        if variant != "under a file":
            (tmp_path / "ro").chmod(0o755)


def test_check_writable_names_the_folder_in_the_way(tmp_path):
    from symrom.atomic import OutputNotWritableError, check_writable

    assert check_writable(tmp_path / "new" / "deeper" / "model") == tmp_path / "new" / "deeper" / "model"
    (tmp_path / "f").write_text("x")
    with pytest.raises(OutputNotWritableError, match=str(tmp_path / "f") + " is not a folder"):
        check_writable(tmp_path / "f" / "sub" / "out")
    with pytest.raises(OutputNotWritableError):
        check_writable(tmp_path / "f", inside=True)


# ----------------------------------------------------------------- 4: casadi hint
def test_export_to_casadi_without_casadi_names_the_extra(model, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "casadi", None)  # as if not installed
    out = tmp_path / "exp"
    one_line_error(_run("export", model, "--to", "casadi", "--out", out), "--to casadi",
                   "pip install 'symrom[export]'")
    assert not out.exists()
    assert "symrom[export]" in (ROOT / "README.md").read_text()


# ----------------------------------------------------------------- 7: --workers 0
@pytest.mark.parametrize("args", [["train", "{data}", "--select"], ["sweep", "{data}", "--latent-dims", "2"],
                                  ["generate", "--robot", "go1", "--motion", "pronk", "--jumps", "3"],
                                  ["demo"], ["reproduce", "--quick"]])
def test_workers_zero_is_refused_naming_workers(args, data, tmp_path):
    args = [str(data[1]) if a == "{data}" else a for a in args]
    out = tmp_path / ("out.h5" if args[0] == "generate" else "out")
    line = one_line_error(_run(*args, "--workers", 0, "--out", out), "--workers 0", "at least 1")
    assert "refine_top" not in line
    assert not out.exists()


# ----------------------------------------------------------------- 8: progress and words
def test_selection_progress_reaches_its_total_and_announces_the_refinement(data):
    from symrom.experiments.select import SelectionConfig, select

    ds, _ = data
    cfg = SelectionConfig(encoders=("base_position",), latent_dims=(2,), libraries=("poly1+inputs",),
                          thresholds=(1e-2,), refine_top=1)
    seen = []
    select(ds, cfg, progress=lambda done, total, what: seen.append((done, total, what)))
    assert seen[-1][0] == seen[-1][1]  # ends at total/total
    refining = [s for s in seen if s[2].startswith("refining")]
    assert refining and refining[0][0] < refining[0][1]  # said before the long step, not after


def test_train_counts_library_terms_not_candidates(data, tmp_path):
    r = _run("train", data[1], "--out", tmp_path / "m")
    assert r.exit_code == 0, r.output
    assert "library terms" in r.output and "candidates" not in r.output


# ----------------------------------------------------------------- 9: equations
def test_equations_latex_is_latex_throughout(model):
    r = _run("equations", model, "--latex")
    assert r.exit_code == 0, r.output
    lines = [line for line in r.stdout.splitlines() if line.strip()]
    assert any(line.startswith(r"\lambda_{\mathrm{") for line in lines)
    for line in lines:  # every line a LaTeX comment or a LaTeX formula, none plain text
        assert line.startswith("%") or line.startswith("\\"), line


def test_equations_into_a_closed_pipe_ends_quietly(model):
    script = Path(sys.executable).with_name("symrom")
    cmd = [str(script)] if script.is_file() else [sys.executable, "-c", "from symrom.cli import main; main()"]
    p = subprocess.Popen([*cmd, "equations", str(model)], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()  # the reader is gone before the command writes (as `| head` after one line)
    err = p.stderr.read().decode()
    p.wait(timeout=120)
    assert "Broken pipe" not in err and "Traceback" not in err and "error" not in err, err
    assert p.returncode in (0, 141), (p.returncode, err)


# ----------------------------------------------------------------- 10: small missing pieces
def test_version():
    r = _run("--version")
    assert r.exit_code == 0 and r.output.strip() == f"symrom {symrom.__version__}"


def test_log_lines_carry_no_source_location():
    from symrom.cli import console

    with console.capture() as cap:
        console.log("generating go1_sim")
    assert "generating go1_sim" in cap.get() and ".py:" not in cap.get()


def test_report_of_a_train_folder_then_with_its_evaluation(data, tmp_path):
    ds, path = data
    folder = tmp_path / "go1"
    assert _run("train", path, "--out", folder).exit_code == 0
    r = _run("report", folder)
    assert r.exit_code == 0, r.output
    html = (folder / "report.html").read_text()
    assert "Model folder:" in html and "ddxi1" in html and "eigenvalues" in html.lower()
    assert '<section id="table2">' not in html and "symrom evaluate" in html  # says how to add the evaluation
    ev = folder / "eval"
    assert _run("evaluate", folder / "model.json", path, "--integrator", "rk4", "--out", ev).exit_code == 0
    # A baseline's evaluation beside it (its "model" names no model file) is not taken for the model's.
    (folder / "a_baseline").mkdir()
    (folder / "a_baseline" / "metrics.json").write_text(
        json.dumps({**json.loads((ev / "metrics.json").read_text()), "model": "Newton"}))
    r = _run("report", folder, "--force")
    assert r.exit_code == 0, r.output
    html = (folder / "report.html").read_text()
    md = (folder / "report.md").read_text()
    metrics = json.loads((ev / "metrics.json").read_text())
    assert "Table 2" in html and "ours RMSE" in html and "data:image/png;base64," in html
    from symrom.evaluate.tables import fmt_value

    x = metrics["horizons"]["full"]["components"]["x"]["rmse"]
    assert fmt_value(x) in md  # the numbers are those of the evaluation
    assert f"test jumps: {metrics['n_jumps']}" in md and "metrics: eval/metrics.json" in md
    # An evaluation folder alone finds its model through its metrics.
    r = _run("report", ev, "--out", tmp_path / "ev.html")
    assert r.exit_code == 0, r.output
    assert "ddxi1" in (tmp_path / "ev.html").read_text()


# ----------------------------------------------------------------- 12: the README, a front page
def test_readme_is_a_front_page_with_the_details_in_docs():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) < 200
    heads = [line for line in text.splitlines() if line.startswith("## ")]
    assert heads == ["## Quick start", "## Install", "## Using it", "## Results", "## Documentation"]
    # The quick start, as .ci/run reads it: the block's second line is the test command.
    block = text.split("## Quick start", 1)[1].split("```")[1].strip().splitlines()
    assert block == ["python3.11 -m pip install -e . && symrom demo",
                     "python3.11 -m pip install -e '.[test,ray]' && python3.11 -m pytest -q -n 2 --dist loadfile"]
    # Results: each names the command that gives it, and that command its wall time.
    from test_benchmark_records import WALL_TIME, readme_result_problems

    assert readme_result_problems(text.split("## Results", 1)[1].split("\n## ", 1)[0]) == []
    pages = set(re.findall(r"\]\((docs/[a-z_]+\.md)\)", text))
    assert {"docs/method.md", "docs/results.md", "docs/benchmarks.md", "docs/design.md",
            "docs/import.md", "docs/engines.md"} <= pages
    for page in pages - {"docs/import.md", "docs/engines.md"}:  # those two come with their own changes
        assert (ROOT / page).is_file(), page
    results = (ROOT / "docs" / "results.md").read_text()
    run = re.search(r"`symrom reproduce --out runs/paper`[^`]*", results)
    assert run and WALL_TIME.search(run.group(0)), "docs/results.md: the run's command and its wall time"
    assert "| experiment | horizon | RMSE | fl_hx |" in results
    for img in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", results):
        assert (ROOT / "docs" / img).is_file(), img
    assert "python benchmarks/bench_learner.py" in (ROOT / "docs" / "benchmarks.md").read_text()


# ----------------------------------------------------------------- the selection's term budget
def test_train_term_budget_is_an_option_of_the_refinement(data, tmp_path):
    out = tmp_path / "m"
    one_line_error(_run("train", data[1], "--max-terms", 4, "--out", out), "--max-terms", "--refine", "--select")
    one_line_error(_run("train", data[1], "--select", "--max-terms", 0, "--out", out), "--max-terms", "0")
    one_line_error(_run("train", data[1], "--latent-dim", 2, "--encoder-base-latents", 2, "--out", out),
                   "encoder_base_latents", "1..1")
    one_line_error(_run("train", data[1], "--select", "--encoder-base-latents", 1, "--out", out),
                   "--encoder-base-latents")
    one_line_error(_run("train", data[1], "--polish", "flight", "--out", out), "--polish flight", "needs --refine")
    one_line_error(_run("train", data[1], "--refine", "--polish", "air", "--out", out), "polish", "air")
    one_line_error(_run("train", data[1], "--refine", "--keep", "flight", "--out", out), "--keep flight",
                   "needs --max-terms")
    one_line_error(_run("train", data[1], "--refine", "--max-terms", 5, "--keep", "air", "--out", out), "keep", "air")
    assert not out.exists()


def test_train_refine_prunes_one_model_to_its_term_budget(data, tmp_path):
    """One compact candidate from the command line: the encoder split into base and joint latents,
    the refined model pruned to the budget, which the exact fit of the same settings exceeds."""
    common = ("--latent-dim", 2, "--encoder-base-latents", 1, "--threshold", 1.0)
    r = _run("train", data[1], *common, "--out", tmp_path / "exact")
    assert r.exit_code == 0, r.output
    exact = load_model(tmp_path / "exact" / "model.json")
    assert exact.estimator["encoder"]["base_latents"] == 1
    budget = int(exact.mask.sum()) // 3
    r = _run("train", data[1], *common, "--refine", "--max-terms", budget, "--polish", "flight",
             "--out", tmp_path / "compact")
    assert r.exit_code == 0, r.output
    compact = load_model(tmp_path / "compact" / "model.json")
    assert 0 < int(compact.mask.sum()) <= budget < int(exact.mask.sum())
    assert compact.estimator["regressor"]["max_terms"] == budget
    assert compact.estimator["regressor"]["polish"] == ["flight"]
    assert compact.phase_info["flight"].report["refinement"]["polish"]
    assert compact.estimator["encoder"] == exact.estimator["encoder"]
    assert np.array_equal(compact.autoencoder.W_e, exact.autoencoder.W_e)


def test_train_select_keeps_the_chosen_model_within_its_term_budget(data, tmp_path):
    out = tmp_path / "m"
    # the planted latents read x, so the dynamics are not held invariant to it
    r = _run("train", data[1], "--select", "--select-dims", "2", "--max-terms", 4, "--invariant", "none", "--out", out)
    assert r.exit_code == 0, r.output
    table = json.loads((out / "selection.json").read_text())
    chosen = table["rows"][table["chosen"]]
    assert chosen["active_terms"] <= 4 and "within 4 terms" in table["rule"]
    # every pruned refinement is polished (the refinement before its pruning is a candidate too)
    assert all(r["polish"] == ["flight"] for r in table["rows"] if r["refine"] and r.get("max_terms"))
    assert int(load_model(out / "model.json").mask.sum()) == chosen["active_terms"]
