"""A real robot's log faults on generated files (``symrom generate --log-faults``): applied as a
faulty logger writes them, drawn once per file, and found again by the import's repair, which
knows nothing of them (the sim-to-real targets of ``symrom reproduce``); the hardware-like A1
froggy that holds its rear feet as a real froggy does."""

from __future__ import annotations

from dataclasses import asdict
from functools import cache

import numpy as np
import pytest
from _logs import jump, sim_go1
from _simdata import tmp_path
from scipy.interpolate import CubicSpline

from symrom.data.importers import import_logs, write_plain_csv
from symrom.data.repair import RepairLimits
from symrom.sim.controllers.flight import longest_run
from symrom.sim.generation.generate import GenerateConfig, GenerationError, generate
from symrom.sim.generation.runner import faults_seed
from symrom.sim.proxy import LOG_FAULTS, LogFaults, apply_log_faults, logged_times, sample_log_faults

Z = 14


def _log(m: dict) -> dict:
    """A jump of a dataset as a generated log (with feet and contact forces)."""
    n = m["t"].size
    return {**m, "foot_pos": np.zeros((n, 4, 3)), "contact_force": np.ones((n, 4, 3))}


def test_a_slow_loop_takes_its_rows_late_and_writes_them_on_its_own_clock():
    """A loop 6 % slower than 2 ms: row k is the true jump at 1.06 k dt (exact at the true rows,
    a cubic spline between), written at k dt; the torques 0.6 of the true ones, the base 20 mm
    high, the flags a row late. No faults: the log as it is."""
    m = _log(jump(sim_go1(), 0))
    assert apply_log_faults(m, LogFaults(), 0.002) is m
    f = LogFaults(clock=1.06, torque_gain=0.6, height_offset=0.02, contact_lag=1)
    out = apply_log_faults(m, f, 0.002)
    T = logged_times(float(m["t"][-1]), 0.002, f, 0.0)
    np.testing.assert_allclose(np.diff(T), 0.002 * 1.06, rtol=1e-12)
    assert out["t"].size == T.size == int(m["t"][-1] / (0.002 * 1.06)) + 1
    np.testing.assert_allclose(out["t"], np.arange(T.size) * 0.002, atol=1e-15)
    q = CubicSpline(m["t"], m["q"], axis=0)(T)
    np.testing.assert_allclose(out["q"][:, :Z], q[:, :Z], atol=1e-12)
    np.testing.assert_allclose(out["q"][:, Z], q[:, Z] + 0.02, atol=1e-12)
    np.testing.assert_allclose(out["dq"], CubicSpline(m["t"], m["dq"], axis=0)(T), atol=1e-12)
    every = np.arange(0, T.size, 50)  # where a true row lies: rows 50 k at 0.106 k s = 53 k true rows
    np.testing.assert_allclose(out["tau"][every], 0.6 * m["tau"][53 * every // 50], atol=1e-9)
    prev = m["contact"][np.searchsorted(m["t"], T + 1e-12, side="right") - 1]
    np.testing.assert_array_equal(out["contact"][1:], prev[:-1])
    # velocities off on a right clock: the rows as taken, every velocity scaled
    v = apply_log_faults(m, LogFaults(velocity_gain=0.94), 0.002)
    np.testing.assert_array_equal(v["t"], m["t"])
    np.testing.assert_array_equal(v["q"], m["q"])
    np.testing.assert_allclose(v["dq"], 0.94 * m["dq"], rtol=1e-15)
    # a wobbling loop: its rate 1.05 +- 4 % over the jump
    w = LogFaults(clock=1.05, clock_wobble=0.04)
    steps = np.diff(logged_times(1.2, 0.002, w, 0.3)) / 0.002
    assert 1.05 * 0.96 - 1e-9 <= steps.min() < 1.05 * 0.962 and 1.05 * 1.038 < steps.max() <= 1.05 * 1.04 + 1e-9


@cache
def _proxy_go1(faults: str | None) -> object:
    # two jumps: one logger's faults are the same in both
    cfg = GenerateConfig("go1", "pronk", 2, seed=21, proxy=True, log_faults=faults)
    return generate(cfg, tmp_path(f"faulty_go1_{faults}.h5"), force=True)


def test_a_faulty_file_is_one_logger_whose_faults_the_repair_finds(tmp_path):
    """Go1 proxy jumps logged with velocities off, torques off, a height offset and a contact
    lag, drawn once from the seed's own stream (the robot and every jump as without them):
    the repair of the written log finds each (velocities within 2 %, torques within 3 % and
    height within 2 mm of the planted fault on top of what the clean jumps show, the lag exact)
    and the jumps then pass every check."""
    clean, faulty = _proxy_go1(None), _proxy_go1("velocities")
    planted = sample_log_faults(np.random.default_rng(faults_seed(21)), LOG_FAULTS["velocities"])
    assert faulty.generator["log_faults"] == asdict(planted)
    assert "log_faults" not in clean.generator and "log_faults" not in clean.generator["config"]
    assert clean.generator["proxy_robot"] == faulty.generator["proxy_robot"]
    for c, f in zip(clean.generator["jumps"], faulty.generator["jumps"]):
        assert c["params"] == f["params"] and f["log_faults"]["velocity_gain"] == planted.velocity_gain
    with pytest.raises(GenerationError, match="log_faults='loop': not a kind of log faults; one of: clock"):
        generate(GenerateConfig("go1", "pronk", 1, log_faults="loop"), tmp_path / "x.h5")
    found = []
    for ds in (clean, faulty):
        write_plain_csv(ds, tmp_path / "log.csv", accelerations=False)
        rep, report = import_logs([tmp_path / "log.csv"], robot="go1", segment="off", repair=RepairLimits())
        assert rep.generator["files"][0]["consistency"] == [] and len(report.repairs) == 2
        found.append(rep.generator["repairs"]["jumps"])
    for c, f in zip(*found):
        assert f["clock"]["finding"] == "velocities" and not f["clock"]["applied"], f["line"]
        assert abs(f["velocities"][0]["gain"] / planted.velocity_gain - 1) < 0.02  # the sensor noise: 0.9 % here
        clean_gain = c["gain"]["gain"] if c["gain"]["applied"] else 1.0  # the proxy's own sensor, damping ...
        assert abs(f["gain"]["gain"] / clean_gain / planted.torque_gain - 1) < 0.03
        offset = (f["height"]["offset"] if f["height"]["applied"] else 0.0) - (
            c["height"]["offset"] if c["height"]["applied"] else 0.0)
        assert abs(offset + planted.height_offset) < 0.002
        assert f["contacts"]["lag"] == planted.contact_lag


def test_the_hardware_like_a1_froggy_holds_its_rear_feet_as_a_real_one_and_its_slow_loop_is_found(tmp_path):
    """Three jumps of the A1 froggy proxy (the sim-to-real target's robot, seed 5) in MuJoCo,
    logged by a slow wobbling loop: each holds the rear feet alone 0.25-0.4 s before the flight
    and turns nose-up by 0.15 rad or more; the repair finds a wrong clock in every one (the
    file's flights together where one cannot tell: the second's alone fits both) and puts the
    jumps back on the true clock within its stated uncertainty."""
    ds = generate(GenerateConfig("a1", "froggy", 3, seed=5, proxy=True, engine="mujoco", log_faults="clock",
                                 splits=(2, 0, 1)), tmp_path / "a1_real.h5")
    planted = ds.generator["log_faults"]
    assert ds.source == "proxy" and planted["clock"] >= 1.04
    for (a, b), rec in zip(ds.jump_bounds(), ds.generator["jumps"]):
        c = ds.contact[a:b]
        start = longest_run(c.sum(axis=1) == 0)[0]
        rear = (c[:, 0] == 0) & (c[:, 1] == 0) & (c[:, 2:].sum(axis=1) > 0)
        n = 0
        while rear[start - n - 1]:
            n += 1
        rear_s = n * ds.dt * rec["log_faults"]["true_samples"] / rec["samples"]  # on about the true clock
        assert 0.25 <= rear_s <= 0.4 and -ds.q[a:b, 16].min() >= 0.15, (rear_s, ds.q[a:b, 16].min())
    write_plain_csv(ds, tmp_path / "a1.csv", accelerations=False)
    rep, _ = import_logs([tmp_path / "a1.csv"], robot="a1", motion="froggy", segment="off", repair=RepairLimits())
    for r, rec in zip(rep.generator["repairs"]["jumps"], ds.generator["jumps"]):
        assert r["clock"]["finding"] == "clock", r["line"]
        true_duration = (rec["log_faults"]["true_samples"] - 1) * 0.002
        # within its own uncertainty (3 sd; a wobbling loop fitted by one scale has a wide one), and 2 %
        err = abs(r["clock"]["scale"] * (rec["samples"] - 1) * 0.002 / true_duration - 1)
        assert err < min(0.02, max(0.005, 3 * r["clock"]["scale_sd"])), (err, r["clock"]["scale_sd"])
