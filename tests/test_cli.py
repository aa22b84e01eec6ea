"""End to end through the command line: train -> evaluate -> equations."""

import json
import os
import stat

from typer.testing import CliRunner

from symrom.cli import app
from symrom.data.io import write_dataset
from symrom.names import Q_NAMES

runner = CliRunner()


def test_train_evaluate_equations(planted_block, tmp_path):
    ds, _ = planted_block
    data = tmp_path / "data.h5"
    write_dataset(ds, data)
    run = tmp_path / "run"
    r = runner.invoke(app, ["train", str(data), "--latent-dim", "2", "--poly-order", "1", "--out", str(run)])
    assert r.exit_code == 0, r.output
    model = json.loads((run / "model.json").read_text())
    assert model["latent_dim"] == 2 and len(model["library"]["feature_names"]) == 15
    ev = tmp_path / "eval"
    r = runner.invoke(app, ["evaluate", str(run / "model.json"), str(data), "--split", "test",
                            "--reset", "0.1", "--out", str(ev), "--integrator", "rk4"])
    assert r.exit_code == 0, r.output
    metrics = json.loads((ev / "metrics.json").read_text())
    assert metrics["split"] == "test" and metrics["n_jumps"] == len(ds.jumps_in("test"))
    assert set(metrics["horizons"]) == {"full", "0.1"}
    for h in metrics["horizons"].values():
        assert h["diverged_jumps"] == 0
        assert list(h["components"]) == list(Q_NAMES)
        for stats in h["components"].values():
            assert set(stats) == {"mean", "std", "mae", "rmse"}
            assert stats["rmse"] >= stats["mae"] >= abs(stats["mean"]) - 1e-15
    assert (ev / "table.md").read_text().count("mean±std") == 2
    pngs = list(ev.glob("jump_*.png"))
    assert pngs and pngs[0].read_bytes()[:4] == b"\x89PNG"
    r = runner.invoke(app, ["equations", str(run / "model.json")])
    assert r.exit_code == 0 and "[contact]" in r.output and "ddxi2 =" in r.output
    r = runner.invoke(app, ["equations", str(run / "model.json"), "--latex"])
    assert r.exit_code == 0 and r"\ddot{\xi}_{1}" in r.output


def test_demo_runs_the_pipeline_and_refuses_to_overwrite(tmp_path):
    out = tmp_path / "demo"
    r = runner.invoke(app, ["demo", "--out", str(out), "--jumps", "4", "--workers", "1"])
    assert r.exit_code == 0, r.output
    assert f"report: {out / 'report.html'}" in r.output.replace("\n", "")
    assert f"dataset: {out / 'data' / 'go1_sim.h5'}" in r.output.replace("\n", "")  # where its jumps are
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["experiments"]) == {"go1_sim"}
    go1 = summary["experiments"]["go1_sim"]
    for name in ("aslip", "aslip_rollout", "newton", "newton_fitted"):
        assert set(go1["baselines"][name]["horizons"]["full"]["components"]) == {"x", "y", "z"}
    table = json.loads((out / "go1_sim" / "selection" / "selection.json").read_text())
    assert table["chosen"] is not None and table["rows"][table["chosen"]]["score"] is not None
    assert (out / "go1_sim" / "equations.txt").read_text().startswith("[contact]")
    assert len(list((out / "go1_sim" / "eval").glob("jump_*.png"))) == 1  # its first test jump drawn
    report = (out / "report.md").read_text()
    assert "Table 2" in report
    # The report names the run's directory, not the temporary one the run was made in.
    assert f"Run directory: {out.resolve()}." in report
    umask = os.umask(0)
    os.umask(umask)
    for d in (out, out / "go1_sim", out / "report_files"):
        assert stat.S_IMODE(d.stat().st_mode) == 0o777 & ~umask, d
    before = (out / "go1_sim" / "model.json").read_text()
    r = runner.invoke(app, ["demo", "--out", str(out)])
    assert r.exit_code != 0 and "--force" in r.output
    assert (out / "go1_sim" / "model.json").read_text() == before


def test_help_pages_show_no_type_next_to_flags():
    for args in ([], ["train"], ["evaluate"], ["import"], ["generate"], ["report"], ["finetune"]):
        r = runner.invoke(app, [*args, "--help"])
        assert r.exit_code == 0, r.output
        assert "<bool>" not in r.output, args
    assert "<int>" in runner.invoke(app, ["train", "--help"]).output  # options with a value keep theirs


def test_progress_reaches_the_end_with_the_batch_integrator(planted_block, tmp_path):
    from symrom.evaluate.metrics import evaluate_model
    from symrom.learn.training import TrainConfig, train
    from symrom.model.persistence import save_model
    from symrom.rollout.integrate import RolloutOptions

    ds, _ = planted_block
    model = train(ds, TrainConfig())
    for method in ("rk4", "lsoda"):
        seen = []
        evaluate_model(model, ds, "test", (None, 0.1, 0.2), RolloutOptions(method),
                       progress=lambda d, t: seen.append((d, t)))
        n = 3 * ds.jumps_in("test").size
        assert seen[-1] == (n, n) and all(t == n for _, t in seen), method
        assert [d for d, _ in seen] == sorted(d for d, _ in seen), method
    data, path = tmp_path / "data.h5", tmp_path / "model.json"
    write_dataset(ds, data)
    save_model(model, path)  # the model above: its command-line evaluation's progress
    r = runner.invoke(app, ["evaluate", str(path), str(data), "--out", str(tmp_path / "ev"),
                            "--integrator", "rk4"])
    assert r.exit_code == 0, r.output
    assert "100%" in r.output and "50%" not in r.output
