"""A checked import of robot logs: plausibility against the robot, one time base per jump,
rebased segments holding only some phases. Every log is made here from simulated Go1 jumps,
in the hardware layout (';', decimal commas) or the plain one."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from _logs import at_times, flight_segment, jump, sim_go1, write_hardware, write_plain
from conftest import one_line_error
from typer.testing import CliRunner

from symrom.cli import app
from symrom.data.dataset import DatasetError, validate
from symrom.data.importers import import_logs
from symrom.data.io import read_dataset
from symrom.data.timebase import TimeBase, TimeBaseError
from symrom.evaluate.metrics import evaluate_model
from symrom.learn.training import TrainConfig, train
from symrom.rollout.integrate import RolloutOptions

runner = CliRunner()
KN = 2  # fr_kn
TAU_RL_KN = 11


def _import(*args):
    return runner.invoke(app, ["import", *(str(a) for a in args)])


def _nothing_written(folder, logs):
    assert sorted(p.name for p in folder.iterdir()) == sorted(p.name for p in logs)


# ----------------------------------------------------------------- plausibility

def test_knee_angles_in_degrees_are_refused_in_one_line(tmp_path):
    m = jump(sim_go1(), 0)
    m["q"][:, [2, 5, 8, 11]] = np.degrees(m["q"][:, [2, 5, 8, 11]])
    log = write_hardware(tmp_path / "deg.csv", [m])
    line = one_line_error(_import(log, "--robot", "go1", "--out", tmp_path / "d.h5"),
                          "deg.csv", "jump 0", "row 0", "line 2", "column 'fr.kn Position'",
                          f"{m['q'][0, KN]:.6g} rad", "[-3.018, -0.688] rad", "URDF range -2.818..-0.888",
                          "degrees for radians", "3 more columns")
    assert "Traceback" not in line
    _nothing_written(tmp_path, [log])


def test_a_torque_column_scaled_by_1000_is_refused(tmp_path):
    m = jump(sim_go1(), 1)
    m["tau"][:, TAU_RL_KN] *= 1000
    log = write_plain(tmp_path / "torque.csv", [m])
    first = int(np.flatnonzero(np.abs(m["tau"][:, TAU_RL_KN]) > 1.25 * 35.55)[0])
    one_line_error(_import(log, "--robot", "go1", "--out", tmp_path / "d.h5"),
                   "torque.csv", "jump 0", f"row {first}", f"line {first + 2}", "column 'tau_rl_kn'",
                   "joint torque", "[-44.44, 44.44] N m", "1.25 x motor limit 35.55", "1000 times too large")
    _nothing_written(tmp_path, [log])


@pytest.mark.parametrize("what, edit, needles", [
    ("mm", lambda m: m["q"].__setitem__((slice(None), 14), 1000 * m["q"][:, 14]),
     ["column 'Body linear Position z'", "base height", "mm for m"]),
    ("sign", lambda m: m["q"].__setitem__((slice(None), 5), -m["q"][:, 5]),
     ["column 'fl.kn Position'", "the opposite sign"]),
    ("speed", lambda m: m["dq"].__setitem__((slice(None), 1), np.degrees(m["dq"][:, 1])),
     ["column 'fr.hy Velocity'", "joint speed", "x URDF velocity limit 30.1"]),
])
def test_other_implausible_columns_name_the_likely_mistake(tmp_path, what, edit, needles):
    m = jump(sim_go1(), 2)
    edit(m)
    log = write_hardware(tmp_path / f"{what}.csv", [m])
    one_line_error(_import(log, "--robot", "go1", "--out", tmp_path / "d.h5"), f"{what}.csv", *needles)
    _nothing_written(tmp_path, [log])


def test_lenient_reports_per_file_and_keeps_the_values(tmp_path):
    ds = sim_go1()
    bad = jump(ds, 0)
    bad["q"][:, KN] = np.degrees(bad["q"][:, KN])
    logs = [write_hardware(tmp_path / "bad.csv", [bad]), write_hardware(tmp_path / "good.csv", [jump(ds, 1)])]
    out = tmp_path / "d.h5"
    r = _import(*logs, "--robot", "go1", "--out", out, "--lenient")
    assert r.exit_code == 0, r.output
    text = " ".join(r.output.split())
    assert "bad.csv: 1 column(s) fail the plausibility checks; kept as logged (--lenient)" in text
    assert "'fr.kn Position' (first at jump 0, row 0, line 2)" in text and "degrees for radians" in text
    assert "good.csv" not in text.split("dataset:")[0]
    got = read_dataset(out)
    np.testing.assert_array_equal(got.q[:bad["t"].size, KN], bad["q"][:, KN])
    files = got.generator["files"]
    assert files[0]["checks"][0]["header"] == "fr.kn Position" and files[1]["checks"] == []


def test_plausible_logs_pass_and_keep_every_value(tmp_path):
    ds = sim_go1()
    m = jump(ds, 1)
    got, _ = import_logs([write_plain(tmp_path / "p.csv", [m])], robot="go1")
    for k in ("q", "dq", "ddq", "tau", "contact"):
        np.testing.assert_array_equal(getattr(got, k), m[k], err_msg=k)
    np.testing.assert_array_equal(got.phase, ds.phase[ds.jump == 1])
    assert got.generator["files"][0]["checks"] == []


# ----------------------------------------------------------------- one time base per jump

def _grid(t_end: float, dt: float) -> np.ndarray:
    return np.arange(int(np.floor(t_end / dt + 1e-9)) + 1) * dt


def test_a_1khz_file_with_a_500hz_file(tmp_path):
    ds = sim_go1()
    slow, fast = jump(ds, 0), jump(ds, 1)
    fast_1k = at_times(fast, _grid(fast["t"][-1], 0.001))  # its every other sample is the 500 Hz one
    logs = [write_hardware(tmp_path / "500hz.csv", [slow]), write_plain(tmp_path / "1khz.csv", [fast_1k])]
    out = tmp_path / "d.h5"
    r = _import(*logs, "--robot", "go1", "--out", out)
    assert r.exit_code == 0, r.output
    text = " ".join(r.output.split())
    assert "time base: dt 0.002 s (the coarsest jump's period)" in text
    assert "1 of 2 jumps resampled" in text and "1khz.csv jump 0 (logged every 1 ms)" in text
    got = read_dataset(out)
    assert got.dt == 0.002
    b = got.jump_bounds()
    np.testing.assert_array_equal(got.t[b[1, 0]:b[1, 1]], np.arange(b[1, 1] - b[1, 0]) * 0.002)
    for k in ("q", "dq", "ddq", "tau", "contact"):  # the 1 kHz jump lands on the 500 Hz samples
        np.testing.assert_allclose(getattr(got, k)[b[1, 0]:b[1, 1]], fast[k], rtol=0, atol=1e-9, err_msg=k)
        np.testing.assert_array_equal(getattr(got, k)[:b[0, 1]], slow[k], err_msg=k)
    np.testing.assert_array_equal(got.phase, ds.phase[ds.jump <= 1])
    tb = got.generator["time_base"]
    assert [j["stored"] for j in tb["jumps"]] == ["as logged", "resampled"]
    assert [j["median_dt"] for j in tb["jumps"]] == [0.002, 0.001] and "makima" in tb["method"]


def test_jittered_segments_are_resampled_consistently():
    """Logged every 0.87-1.43 ms without accelerations: q, dq on the 2 ms grid match the
    motion, and ddq (differentiated on the grid) matches its acceleration."""
    ds = sim_go1()
    m = jump(ds, 1)
    rng = np.random.default_rng(4)
    t = np.r_[0.0, np.cumsum(rng.uniform(0.00087, 0.00143, 3000))]
    jit = at_times(m, t[t <= m["t"][-1]])
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as d:
        got, _ = import_logs([write_plain(Path(d) / "jit.csv", [jit], accelerations=False)], robot="go1",
                          time_base=TimeBase(dt=0.002))
    truth = at_times(m, np.arange(got.n_samples) * 0.002)
    spread = np.ptp(m["q"], axis=0) + 1e-9
    assert np.max(np.abs(got.q - truth["q"]) / spread) < 3e-3
    smooth = m["contact"].sum(axis=1) == 4  # away from the touch-down kinks
    smooth = np.convolve(smooth, np.ones(15), "same") == 15
    smooth = smooth[:got.n_samples]
    dspread = np.ptp(m["dq"], axis=0) + 1e-9
    assert np.max(np.abs(got.dq - truth["dq"])[smooth] / dspread) < 5e-3
    # ddq was differentiated from the resampled dq: it agrees with the motion's acceleration
    rel = np.abs(got.ddq - truth["ddq"])[smooth] / (np.ptp(m["ddq"], axis=0) + 1e-9)
    assert np.median(rel) < 0.01
    tb = got.generator["time_base"]["jumps"][0]
    assert tb["stored"] == "resampled" and tb["jitter_steps"] > 100 and tb["max_deviation"] > 0.2
    mismatch = (got.contact != truth["contact"]).any(axis=1).mean()
    assert mismatch < 0.01  # flags by the nearest sample: off only at switches


def test_a_jump_with_a_20ms_gap(tmp_path):
    ds = sim_go1()
    m = jump(ds, 2)
    keep = np.r_[np.arange(200), np.arange(209, m["t"].size)]  # samples 200-208 lost: a 20 ms step
    gap = {k: v[keep] for k, v in m.items()}
    log = write_hardware(tmp_path / "gap.csv", [gap])
    one_line_error(_import(log, "--robot", "go1", "--out", tmp_path / "d.h5"),
                   "gap.csv", "jump 0", "line 202", "a gap of 20 ms after t = 0.3980 s",
                   "logged every 2 ms", "longer than 10 ms", "--max-gap")
    _nothing_written(tmp_path, [log])
    out = tmp_path / "bridged.h5"
    r = _import(log, "--robot", "go1", "--out", out, "--max-gap", "0.025")
    assert r.exit_code == 0, r.output
    assert "gaps bridged by interpolation: gap.csv jump 0: 20 ms after t = 0.398 s" in " ".join(r.output.split())
    got = read_dataset(out)
    assert got.n_samples == m["t"].size and got.dt == 0.002  # the lost samples are interpolated
    np.testing.assert_array_equal(got.q[:200], m["q"][:200])
    np.testing.assert_allclose(got.q[209:], m["q"][209:], rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.q[200:209], m["q"][200:209], atol=0.02)
    assert got.generator["time_base"]["jumps"][0]["gaps"][0]["line"] == 202


def test_refusing_to_resample(tmp_path):
    ds = sim_go1()
    fast = at_times(jump(ds, 0), _grid(jump(ds, 0)["t"][-1], 0.001))
    logs = [write_plain(tmp_path / "a.csv", [jump(ds, 1)]), write_plain(tmp_path / "b.csv", [fast])]
    with pytest.raises(TimeBaseError, match=r"b\.csv, jump 0: logged every 1 ms .* not on the dataset's grid of 2 ms"):
        import_logs(logs, robot="go1", time_base=TimeBase(resample=False))
    one_line_error(_import(*logs, "--robot", "go1", "--out", tmp_path / "d.h5", "--no-resample"),
                   "b.csv, jump 0", "logged every 1 ms", "not on the dataset's grid of 2 ms")
    _nothing_written(tmp_path, logs)


def test_a_stored_jump_off_its_time_base_is_refused():
    ds = sim_go1()
    t = ds.t.copy()
    t[ds.jump == 1] *= 0.5  # a jump logged at 1 kHz stored with the dataset's 2 ms
    with pytest.raises(DatasetError, match=r"key 't': .* jump 1, row \d+ is not sample 1 x dt"):
        validate(replace(ds, t=t))


def test_a_hardware_jump_evaluates_the_same_alone_or_with_other_rates(tmp_path):
    ds = sim_go1()
    model = train(ds, TrainConfig(latent_dim=2, encoder_components=("x", "y", "z"), decoded_weight=0.0,
                                  alpha=1e-3))
    hw = write_hardware(tmp_path / "hardware.csv", [jump(ds, 2)])
    fast = at_times(jump(ds, 0), _grid(jump(ds, 0)["t"][-1], 0.001))
    rng = np.random.default_rng(1)
    segs = []
    for j in (0, 1):  # segments logged every 0.87-1.43 ms
        m = jump(ds, j)
        t = np.r_[0.0, np.cumsum(rng.uniform(0.00087, 0.00143, 3000))]
        segs.append(at_times(m, t[t <= m["t"][-1]]))
    others = [write_plain(tmp_path / "1khz.csv", [fast]), write_hardware(tmp_path / "segments.csv", segs)]
    alone, _ = import_logs([hw], robot="go1", split="0,0,1")
    mixed, _ = import_logs([*others, hw], robot="go1", split="3,0,1")
    assert alone.dt == mixed.dt == 0.002
    opts = RolloutOptions("lsoda")
    a, _ = evaluate_model(model, alone, "test", (None, 0.1), opts)
    b, _ = evaluate_model(model, mixed, "test", (None, 0.1), opts)
    a, b = a.to_dict(), b.to_dict()
    for key in a["horizons"]:
        ha, hb = a["horizons"][key], b["horizons"][key]
        assert ha["diverged_jumps"] == hb["diverged_jumps"] and ha["scored_samples"] == hb["scored_samples"]
        for c, s in ha["components"].items():
            for stat, v in s.items():
                assert hb["components"][c][stat] == pytest.approx(v, rel=1e-9, abs=1e-12), (key, c, stat)


# ----------------------------------------------------------------- partial logs

def test_flight_only_segments_with_rebased_z(tmp_path):
    ds = sim_go1()
    segs = [flight_segment(ds, j) for j in range(ds.n_jumps)]
    assert all(s["q"][0, 14] == 0.0 and s["contact"].sum() == 0 for s in segs)
    log = write_hardware(tmp_path / "flights.csv", segs)
    out = tmp_path / "flights.h5"
    r = _import(log, "--robot", "go1", "--out", out, "--split", "2,1,0")
    assert r.exit_code == 0, r.output
    text = " ".join(r.output.split())
    assert "positions: 3 jump(s) start at z = 0 (rebased)" in text and "take-off" in text
    assert "phases: contact none, flight" in text
    got = read_dataset(out)
    assert set(got.phase_names[p] for p in got.phase) == {"flight"}
    z_true = np.concatenate([s["z_true"] for s in segs])
    assert np.max(np.abs(got.q[:, 14] - z_true)) < 0.005  # the height is back, to a few mm
    assert [x["jump"] for x in got.generator["rebased"]] == [0, 1, 2]
    np.testing.assert_array_equal(got.q[:, 12], np.concatenate([s["q"][:, 12] for s in segs]))  # x as logged
    # Rebased but told absolute: the height check names it.
    one_line_error(_import(log, "--robot", "go1", "--out", tmp_path / "abs.h5", "--positions", "absolute"),
                   "column 'Body linear Position z'", "base height 0 m")
    # train on them says what it can fit
    run = tmp_path / "run"
    r = runner.invoke(app, ["train", str(out), "--out", str(run), "--encoder-components", "x,y,z",
                            "--decoded-weight", "0"])
    assert r.exit_code == 0, r.output
    text = " ".join(r.output.split())
    assert "training rows: contact none, flight" in text
    assert "can fit: flight" in text and "cannot fit: contact" in text
    assert "encoder (step a) is fitted on all training rows" in text
    model = json.loads((run / "model.json").read_text())
    assert model["provenance"]["training"]["untrained_phases"] == ["contact"]


def test_segments_holding_some_phases_keep_their_rebased_height_from_the_contact_rows(tmp_path):
    ds = sim_go1()
    a, b = ds.jump_bounds()[0]
    land = np.flatnonzero(ds.contact[a:b].sum(axis=1) == 0)[-1]  # the last flight row, then landing
    m = jump(ds, 0, slice(int(land) - 20, b - a))
    z = m["q"][:, 14].copy()
    m["q"][:, 12:15] -= m["q"][0, 12:15]
    got, _ = import_logs([write_plain(tmp_path / "landing.csv", [m])], robot="go1")
    assert np.max(np.abs(got.q[:, 14] - z)) < 0.002
    assert "feet in contact" in got.generator["rebased"][0]["from"]
    assert set(got.phase_names[p] for p in got.phase) == {"contact", "flight"}
