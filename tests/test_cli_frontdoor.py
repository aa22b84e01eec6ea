"""The front door, tried as a new user would: each refusal comes before any work, in one line
naming the flag; the words say what they mean; the README says what the code does."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from conftest import one_line_error
from typer.testing import CliRunner

from symrom.cli import app
from symrom.cli.common import flag_text
from symrom.data.io import read_dataset, write_dataset
from symrom.testing import make_planted_dataset

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()


def _run(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    ds, _ = make_planted_dataset(n_jumps=6, n_samples=120, seed=4)
    path = tmp_path_factory.mktemp("d") / "d.h5"
    write_dataset(ds, path)
    return path


# ----------------------------------------------------------------- library parameters as flags
def test_library_parameters_become_the_commands_flags():
    assert flag_text("split='9,9,9': the counts add up to 27 jumps") == "--split 9,9,9: the counts add up to 27 jumps"
    assert flag_text("x.h5 exists; pass force=True to overwrite it") == "x.h5 exists; pass --force to overwrite it"
    assert flag_text("keep the source decoder (refit_decoder=False)") == "keep the source decoder (--keep-decoder)"
    assert flag_text("out=/tmp/a is the input") == "--out /tmp/a is the input"
    assert flag_text("topics={'joints': '/j'}") == "--topics {'joints': '/j'}"
    assert flag_text("positions='a b': no") == "--positions 'a b': no"  # a value with a space keeps its quotes
    # a name no flag sets, and a name inside a word or a path, stay as they are
    assert flag_text("at l=2 and xi1=0.3, in runs/split=3") == "at l=2 and xi1=0.3, in runs/split=3"


def test_a_library_error_names_the_flag_on_the_command_line(data, tmp_path):
    """The library names ``split=``, the command line ``--split``."""
    from symrom.evaluate.outputs import check_split_and_integrator

    with pytest.raises(ValueError, match=r"^split='nope'"):
        check_split_and_integrator("nope", "rk4")
    line = one_line_error(_run("evaluate", data, data, "--out", tmp_path / "e", "--split", "nope"), "--split nope")
    assert "split=" not in line


# ----------------------------------------------------------------- refused before any work
def test_a_negative_threshold_is_refused_before_the_data_are_read(tmp_path):
    line = one_line_error(_run("train", tmp_path / "absent.h5", "--threshold", -1, "--out", tmp_path / "m"),
                          "--threshold -1", ">= 0")
    assert "absent" not in line and not (tmp_path / "m").exists()


def test_a_dataset_given_as_a_model_is_named(data):
    one_line_error(_run("equations", data), "a dataset file (HDF5), not a model file")


def test_a_folder_given_as_data_or_model_is_named(data, tmp_path):
    folder = tmp_path / "runs"
    folder.mkdir()
    one_line_error(_run("train", folder, "--out", tmp_path / "m"), "a folder, not a dataset file")
    assert _run("train", data, "--out", folder / "m").exit_code == 0
    one_line_error(_run("equations", folder / "m"), "a folder", "give that file")


def test_a_dataset_named_csv_is_refused_before_simulating(tmp_path):
    out = tmp_path / "data.csv"
    one_line_error(_run("generate", "--robot", "go1", "--motion", "pronk", "--jumps", 2, "--out", out),
                   "--out", "data.h5")
    assert not out.exists() and not Path(str(out) + ".parts").exists()


def test_the_point_mass_planner_refuses_a_model(data, tmp_path):
    pytest.importorskip("casadi")
    assert _run("train", data, "--out", tmp_path / "m").exit_code == 0
    one_line_error(_run("jump", tmp_path / "m" / "model.json", "--planner", "point-mass", "--target-x", 0.3,
                        "--out", tmp_path / "j"), "point-mass planner uses no model")
    assert not (tmp_path / "j").exists()


# ----------------------------------------------------------------- generate --split
def test_generate_splits_as_asked(tmp_path):
    from symrom.data.importers import split_counts

    assert split_counts("1,0,2", 3) == (1, 0, 2) and split_counts("0.5,0.25,0.25", 4) == (2, 1, 1)
    assert split_counts(None, 3) is None
    out = tmp_path / "d.h5"
    one_line_error(_run("generate", "--robot", "go1", "--motion", "pronk", "--jumps", 3, "--split", "5,5,5",
                        "--out", out), "--split 5,5,5")
    r = _run("generate", "--robot", "go1", "--motion", "pronk", "--jumps", 3, "--split", "1,0,2", "--out", out)
    assert r.exit_code == 0, r.output
    ds = read_dataset(out)
    assert [int((ds.split == s).sum()) for s in ("train", "val", "test")] == [1, 0, 2]


# ----------------------------------------------------------------- words
def test_the_sweeps_best_dimension_is_told_apart_from_the_model():
    from symrom.experiments.reproduce import summary_lines

    m = {"n_jumps": 2, "horizons": {"full": {"diverged_jumps": 0, "components": {}}}}
    lines = summary_lines({"experiments": {"go1_sim": {"latent_dim": 2, "n_candidates": 9, "active_terms": 5,
                                                       "metrics": m}},
                           "sweep": {"latent_dims": [1, 2, 4], "best_latent_dim": 4}})
    assert "go1_sim: l=2" in lines[0]
    assert lines[-1].startswith("sweep: best latent dimension by L_mod") and lines[-1].count(": 4") == 1
    assert "not the selected model's: go1_sim has l = 2, chosen on the validation jumps" in lines[-1]


def test_a_sim2real_target_is_said_as_logged_repaired_and_fine_tuned():
    """The summary line and the report's repair line of one target: the source's x / z as logged
    and repaired, repaired + fine-tuned, target alone; the planted faults beside the found ones."""
    from symrom.experiments.reproduce import sim2real_checks, summary_lines
    from symrom.report.sim2real import repair_lines, sim2real_markdown

    def col(x, z):
        return {"x_rmse": x, "z_rmse": z, "diverged_jumps": 0, "drifted_jumps": 0, "flight_acc": -9.9,
                "flight_acc_data": -9.8, "flight_ratio": 1.01}

    stat = lambda m, lo, hi: {"median": m, "min": lo, "max": hi}  # noqa: E731
    t = {"logged": col(0.4, 0.3), "source": col(0.2, 0.04), "fine_tuned": col(0.02, 0.01),
         "target_alone": col(0.03, 0.012), "chosen": col(0.02, 0.01), "source_model": "a1_randomized/exact",
         "method": "calibrate_rollout", "chosen_source": "a1_randomized/exact", "chosen_method": "calibrate",
         "engine": "mujoco", "jumps": {"train": 12, "val": 4, "test": 8},
         "repair": {"planted": {"clock": 1.06, "clock_wobble": 0.03, "velocity_gain": 1.0, "torque_gain": 0.6,
                                "height_offset": -0.02, "contact_lag": 1, "sensor_scale": 0.95},
                    "found": {"jumps": 24, "changed": 24, "findings": {"clock": 24},
                              "clock_scale": stat(1.058, 1.04, 1.07), "velocity_gain": stat(1.0, 1.0, 1.0),
                              "torque_gain": stat(0.571, 0.55, 0.59), "height_offset": stat(0.021, 0.019, 0.023),
                              "contact_lag": stat(1.0, 1.0, 1.0)}}}
    t["checks"] = sim2real_checks(t)
    lines = summary_lines({"experiments": {}, "sim2real": {"targets": {"a1_proxy_mujoco": t}}})
    assert lines == ["a1_proxy_mujoco: x / z RMSE as logged 0.400 / 0.300 m, repaired 0.200 / 0.040 m, repaired + "
                     "fine-tuned 0.020 / 0.010 m, target alone 0.030 / 0.012 m; 5 of 5 targets met"]
    (line,) = repair_lines({"a1_proxy_mujoco": t})
    assert line.startswith("a1_proxy_mujoco: planted: loop 1.060x its period +- 3.0 %, velocities x 1.000, "
                           "torques x 0.600 (its sensor x 0.950 under it), z -20.0 mm, contacts 1 row(s) late; "
                           "repaired 24 of 24 jumps (24 clock): duration x 1.058 (1.040..1.070)")
    assert "z +21.0 (+19.0..+23.0) mm" in line
    md = sim2real_markdown({"a1_proxy_mujoco": t})
    assert "| a1_proxy_mujoco | as logged: source as is (a1_randomized/exact) | 4.00e-01 | 3.00e-01 |" in md


@pytest.mark.parametrize("contradicted", [False, True])
def test_the_flight_test_says_what_it_found(contradicted):
    from symrom.experiments.finetune import calibration_lines

    test = {"mean": 0.12, "se": 0.3, "jumps": 3, "limit": 0.5, "t_limit": 2.0, "contradicted": contradicted}
    (line,) = [t for _, t in calibration_lines({"calibration": {"phases": {}, "flight_test": test}})]
    assert "contradicts the source" not in line
    if contradicted:
        assert "beyond the limits" in line and line.endswith("the data contradict the source, gravity calibrated")
    else:
        assert "within the limits" in line and line.endswith("the data do not contradict the source, gravity kept")


def test_a_hip_abduction_in_degrees_gets_the_degrees_hint(tmp_path):
    """Only a few of its rows leave the range: the column against its own rate names the unit."""
    from _logs import jump, sim_go1, write_plain

    from symrom.data.importers import import_logs
    from symrom.data.rawlog import LogError

    m = jump(sim_go1(), 0)
    m["q"][:, 0] = np.degrees(m["q"][:, 0])  # fr_hx
    with pytest.raises(LogError) as e:
        import_logs([write_plain(tmp_path / "hx.csv", [m])], robot="go1")
    text = str(e.value)
    assert "column 'fr_hx'" in text and "it looks like degrees for radians" in text
    assert int(re.search(r"(\d+) of \d+ rows are outside", text).group(1)) < 0.5 * len(m["t"])


# ----------------------------------------------------------------- the README and docs say what the code does
def test_the_readme_names_only_robots_the_code_knows():
    from symrom.robots import ROBOTS, get_robot

    text = " ".join((ROOT / "README.md").read_text().split())
    for name in re.findall(r"--robot ([\w./-]+)", text):
        assert name in ROBOTS or (ROOT / name).is_file(), name
        if name.endswith(".toml"):
            assert get_robot(str(ROOT / name)).name
    assert "Laikago and Mini Cheetah too" not in text and "tests/robots/mini_cheetah.toml" in text


def test_docs_data_states_the_torque_check_the_code_makes():
    from symrom.data.checks import PlausibilityLimits

    text = " ".join((ROOT / "docs" / "data.md").read_text().split())
    assert f"within {PlausibilityLimits().torque_factor:g} x it when `--torques measured`" in text
    assert "torques within 2 x" not in text


def test_the_readme_synopsis_shows_the_defaults():
    """A bracketed ``[--flag value]`` of the README's command synopsis is that flag's default (or
    the default its help states); placeholders (CAPITALS) and choices (a|b) are not values."""
    text = (ROOT / "README.md").read_text()
    block = text[text.index("## Using it"):]
    block = block[block.index("```\n") + 4:]
    block = block[:block.index("```")].replace("\\\n", " ")
    from typer.main import get_command

    cli = get_command(app)
    checked = 0
    for line in block.splitlines():
        words = line.split()
        if len(words) < 2 or words[0] != "symrom":
            continue
        command = cli.commands[words[1]]
        for flag, value in re.findall(r"\[(--[a-z-]+) ([^\]\[|\s]+)\]", line.split("#")[0]):
            if value.isupper() or "|" in value:
                continue
            param = next(p for p in command.params if flag in p.opts)
            default = param.default
            stated = re.search(r"default ([\w.,-]*\w)", param.help or "")
            same = str(default) == value or (isinstance(default, (int, float)) and default == float(value))
            assert same or (stated and stated.group(1) == value), (words[1], flag, value, default)
            checked += 1
    assert checked >= 10
