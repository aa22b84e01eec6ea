"""Logs repaired from physics (``symrom import --repair``): faults planted in simulated Go1
pronk and A1 froggy jumps (tests/_logs.py) with known sizes, each recovered within its
bound (time 0.5 %, torque gain 3 %, height 2 mm, contact rows exact), a clean log left bit
for bit unchanged, and what the data cannot determine refused in one line."""

from __future__ import annotations

import numpy as np
import pytest
from _logs import jump, on_clock, proxy_go1, sim_a1_froggy, sim_go1, write_plain, write_ros2
from conftest import one_line_error
from typer.testing import CliRunner

from symrom.cli import app
from symrom.data import importers
from symrom.data.importers import import_logs, read_log
from symrom.data.io import read_dataset
from symrom.data.repair import REPAIR_VERSION, RepairError, RepairLimits, repair_log
from symrom.data.repair_body import body_state
from symrom.data.repair_clock import flight_fall, flight_runs
from symrom.names import GRAVITY as G

runner = CliRunner()
REPAIR = RepairLimits()
ARRAYS = ("jump", "t", "q", "dq", "ddq", "tau", "contact", "u", "phase")
Z = 14
SIMS = {"go1": (sim_go1, "pronk"), "a1": (sim_a1_froggy, "froggy")}


def _sim(robot: str):
    make, motion = SIMS[robot]
    return make(), motion


def _copy(m: dict) -> dict:
    return {k: v.copy() for k, v in m.items()}


def _repaired(tmp_path, robot: str, logged: dict, name: str = "log.csv", **kw):
    """Import one planted jump with the repair; the dataset and its jump's record."""
    ds, _ = import_logs([write_plain(tmp_path / name, [logged], accelerations=False)], robot=robot,
                     motion=SIMS[robot][1], repair=REPAIR, **kw)
    (record,) = ds.generator["repairs"]["jumps"]
    return ds, record


def _logs_read(monkeypatch) -> list:
    """The logs the import reads, as it leaves them (repaired in place): every row's repaired
    time, which the dataset, on one grid, no longer holds."""
    read, source = [], importers.read_source

    def keep(*args, **kw):
        read.append(source(*args, **kw))
        return read[-1]

    monkeypatch.setattr(importers, "read_source", keep)
    return read


def _lagged(contact: np.ndarray, rows: int = 1) -> np.ndarray:
    """Flags written ``rows`` rows late."""
    return np.r_[np.repeat(contact[:1], rows, axis=0), contact[:-rows]]


# ----------------------------------------------------------------- the physics behind it

def test_the_mass_model_holds_the_legs_as_pybullet_does():
    """The legs' holding torques and the whole body's centre of mass, read from the URDF
    without an engine, against PyBullet's inverse dynamics and its composite body."""
    from symrom.robots import mass_model
    from symrom.robots.kinematics import rpy_to_matrix
    from symrom.robots.stance import standing_joints
    from symrom.sim.controllers.body import LegGravity, body_model

    rng = np.random.default_rng(4)
    for robot in ("go1", "a1", "laikago"):
        mm = mass_model(robot)
        q = standing_joints(robot) + rng.normal(0, 0.3, 12)
        rpy = np.array([0.1, -0.2, 0.3])
        ours = mm.hold_torques(q[None], rpy[None], G)[0]
        theirs = LegGravity(robot).torques(q, rpy_to_matrix(rpy[None])[0])
        np.testing.assert_allclose(ours, theirs, atol=1e-9)
        np.testing.assert_allclose(mm.com_base(standing_joints(robot)[None])[0], body_model(robot).com_base,
                                   atol=5e-4)


@pytest.mark.parametrize("robot", ["go1", "a1"])
def test_in_flight_the_centre_of_mass_falls_at_g_and_the_feet_carry_the_weight(robot):
    """What the repair stands on, on clean simulated jumps: the whole body's centre of mass
    (not the base: 2-4 % off, the legs swing) falls at g, and the torques' vertical force,
    the legs' weight held, is m (g + a) of the centre of mass row by row."""
    ds, _ = _sim(robot)
    for j in range(ds.n_jumps):
        m = jump(ds, j)
        state = body_state(robot, m["q"], m["dq"])
        runs = flight_runs(m["contact"], m["t"], REPAIR)
        fall, _, _ = flight_fall(m["t"], state.com_z, runs, 0.0)
        base, _, _ = flight_fall(m["t"], m["q"][:, Z], runs, 0.0)
        assert abs(fall - 1) < 0.002 and abs(base - 1) > 0.015
        from symrom.data.repair_body import vertical_forces

        force = vertical_forces(state, m["tau"], m["contact"]).sum(axis=1)
        acc = np.gradient(state.com_vz, m["t"])
        calm = (m["contact"].all(axis=1)) & (np.abs(acc) < 0.5)
        assert abs(np.median(force[calm] / (state.mass * (G + acc[calm]))) - 1) < 0.01


# ----------------------------------------------------------------- nothing to repair

@pytest.mark.parametrize("robot", ["go1", "a1"])
def test_a_clean_log_is_left_bit_for_bit_unchanged(tmp_path, robot):
    ds, motion = _sim(robot)
    log = write_plain(tmp_path / "clean.csv", [jump(ds, j) for j in range(ds.n_jumps)])
    plain, _ = import_logs([log], robot=robot, motion=motion)
    fixed, _ = import_logs([log], robot=robot, motion=motion, repair=REPAIR)
    for key in ARRAYS:
        np.testing.assert_array_equal(getattr(fixed, key), getattr(plain, key), err_msg=key)
    rec = fixed.generator["repairs"]
    assert rec["version"] == REPAIR_VERSION and len(rec["jumps"]) == ds.n_jumps
    for r in rec["jumps"]:
        assert not r["changed"] and r["clock"]["finding"] == "none" and "nothing to repair" in r["line"]
        assert abs(r["gain"]["gain"] - 1) < 0.02 and abs(r["height"]["offset"]) < 5e-4
    # the options say it; without the repair the record is as before
    assert fixed.generator["options"]["repair"]["z"] == REPAIR.z
    assert "repairs" not in plain.generator and "repair" not in plain.generator["options"]


# ----------------------------------------------------------------- the time base

@pytest.mark.parametrize("robot", ["go1", "a1"])
def test_a_clock_running_slow_is_scaled(tmp_path, robot):
    """Rows truly 1.06 logged periods apart (a loop slower than its nominal rate): the flight
    falls at 1.1236 g on the logged clock, so the clock is wrong, the velocities right."""
    ds, _ = _sim(robot)
    m = jump(ds, 0)
    logged = _copy(m)
    logged["t"] = m["t"] / 1.06
    got, rec = _repaired(tmp_path, robot, logged)
    clock = rec["clock"]
    assert clock["finding"] == "clock" and not clock["warp"]
    assert abs(clock["scale"] / 1.06 - 1) < 0.005 and abs(clock["flight_g"] - 1) < 0.01
    assert abs(got.dt / 0.002 - 1) < 0.005  # back on its true period
    assert not any(v["applied"] for v in rec["velocities"])
    np.testing.assert_array_equal(got.dq, m["dq"])
    assert got.generator["files"][0]["consistency"] == []


@pytest.mark.parametrize("robot", ["go1", "a1"])
def test_velocities_scaled_on_a_right_clock_are_told_from_a_wrong_clock(tmp_path, robot):
    """The same position/velocity ratio of 1.06 from velocities logged 1/1.06 too small: the
    flight falls at g on the logged clock, so the clock is kept and the velocities scaled."""
    ds, _ = _sim(robot)
    m = jump(ds, 1)
    logged = _copy(m)
    logged["dq"] = m["dq"] / 1.06
    got, rec = _repaired(tmp_path, robot, logged)
    assert rec["clock"]["finding"] == "velocities" and not rec["clock"]["applied"]
    assert abs(rec["clock"]["ratio"] / 1.06 - 1) < 0.005
    for v in rec["velocities"]:
        assert v["applied"] and abs(v["gain"] * 1.06 - 1) < 0.005, v
    np.testing.assert_array_equal(got.t, m["t"])
    assert np.all(np.abs(got.dq - m["dq"]) <= 0.005 * np.abs(m["dq"]).max(axis=0))
    assert rec["accelerations"] == "as logged"  # the log had none: differentiated from the repaired dq


def test_flags_that_never_let_go_leave_the_flight_to_the_feet(tmp_path):
    """Contact flags stuck at 1 show no flight; the feet's heights and speeds do, and the
    flight still tells wrong velocities from a wrong clock."""
    m = jump(sim_go1(), 0)
    logged = _copy(m)
    logged["dq"] = m["dq"] / 1.06
    logged["contact"][:] = 1
    (rec,) = repair_log(read_log(write_plain(tmp_path / "stuck.csv", [logged])), "go1", REPAIR)
    assert rec.clock.finding == "velocities" and abs(rec.clock.flight_g - 1) < 0.01
    assert "from the feet's heights" in rec.clock.note and rec.clock.flight_rows > 100


def _drift_go1(t_end: float):
    return lambda t: 0.94 + 0.12 * t / t_end  # -6 % .. +6 % over the jump


def _drift_a1(t_end: float):
    return lambda t: 1.0 + 0.06 * np.sin(2 * np.pi * t / t_end)


def _times_within(repaired: np.ndarray, true: np.ndarray, logged: np.ndarray) -> None:
    """Every row within 0.5 % of its true time (past 0.2 s; 1 ms before), the rate between
    rows 50 ms apart within 0.5 % in the median."""
    err = np.abs(repaired - true)
    late = true >= 0.2
    assert np.all(err[late] <= 0.005 * true[late]) and np.all(err[~late] <= 0.001), err.max()
    rate = np.diff(repaired[::25]) / np.diff(true[::25])
    assert np.median(np.abs(rate - 1)) < 0.005


@pytest.mark.parametrize("robot, drift", [("go1", _drift_go1), ("a1", _drift_a1)])
def test_a_rate_drifting_within_a_jump_is_warped_back(tmp_path, robot, drift):
    """A loop whose rate drifts by +-6 % within the jump, logged as if evenly spaced: the
    position/velocity ratio changes window by window, a smooth monotone warp of the clock,
    anchored by the flight, puts every row back at its true time."""
    ds, _ = _sim(robot)
    m = jump(ds, 2)
    logged = on_clock(m, drift(m["t"][-1]))
    lg = read_log(write_plain(tmp_path / "drift.csv", [logged], accelerations=False))
    (rec,) = repair_log(lg, robot, REPAIR)
    assert rec.clock.finding == "clock" and rec.clock.warp
    assert 0.93 < rec.clock.rate_low < 0.95 and 1.05 < rec.clock.rate_high < 1.07
    _times_within(lg.t, logged["t_true"], logged["t"])
    assert np.all(np.diff(lg.t) > 0)
    assert not any(v.applied for v in rec.velocities)


# ----------------------------------------------------------------- torques, height, contacts

@pytest.mark.parametrize("robot", ["go1", "a1"])
def test_a_torque_gain_is_found_from_the_weight(tmp_path, robot):
    """Measured torques 0.56 of the true ones: the feet would carry 56 % of the weight."""
    ds, _ = _sim(robot)
    m = jump(ds, 0)
    logged = _copy(m)
    logged["tau"] = 0.56 * m["tau"]
    got, rec = _repaired(tmp_path, robot, logged)
    g = rec["gain"]
    assert g["applied"] and abs(g["gain"] / 0.56 - 1) < 0.03 and g["static_windows"] >= REPAIR.min_static
    assert abs(g["dynamic"] / 0.56 - 1) < 0.03  # the dynamic windows agree
    assert g["kinds"] is None  # one gain for all joints is never taken for two
    np.testing.assert_allclose(got.tau, m["tau"], rtol=0.03, atol=1e-9)
    assert got.generator["files"][0]["consistency"] == []


def test_torque_gains_per_joint_kind_where_the_jumps_tell_them_apart(tmp_path):
    """The hips' torques 0.6 and the knees' 0.5 of the true ones. An A1 froggy jump, whose
    rear-only push and landing load hips and knees in changing shares, tells the two apart;
    a Go1 pronk jump, loading them alike throughout, does not, and one gain (the knees',
    which carry the weight) is kept for all."""
    kinds = np.tile([0.6, 0.6, 0.5], 4)
    m = jump(sim_a1_froggy(), 1)
    logged = _copy(m)
    logged["tau"] = kinds * m["tau"]
    got, rec = _repaired(tmp_path, "a1", logged, name="a1.csv")
    g = rec["gain"]
    assert g["applied"] and g["kinds"] is not None and "per joint kind" in rec["line"]
    assert np.all(np.abs(np.array(g["kinds"]) / kinds[:3] - 1) < 0.03), g["kinds"]
    np.testing.assert_allclose(got.tau, m["tau"], rtol=0.03, atol=1e-9)
    m = jump(sim_go1(), 1)
    logged = _copy(m)
    logged["tau"] = kinds * m["tau"]
    _, rec = _repaired(tmp_path, "go1", logged, name="go1.csv")
    assert rec["gain"]["kinds"] is None and abs(rec["gain"]["gain"] / 0.5 - 1) < 0.03
    # one gain for all joints is never taken for two: test_a_torque_gain_is_found_from_the_weight


@pytest.mark.parametrize("robot", ["go1", "a1"])
@pytest.mark.parametrize("offset", [0.022, -0.022])
def test_a_height_offset_is_found_from_the_stance_feet(tmp_path, robot, offset):
    """The base height 22 mm too high (feet in contact above the ground) or too low (below)."""
    ds, _ = _sim(robot)
    m = jump(ds, 1)
    logged = _copy(m)
    logged["q"][:, Z] += offset
    got, rec = _repaired(tmp_path, robot, logged)
    h = rec["height"]
    assert h["applied"] and abs(h["offset"] + offset) < 0.002
    assert np.abs(got.q[:, Z] - m["q"][:, Z]).max() < 0.002
    assert ("below" if offset < 0 else "above") in rec["line"]


def test_rebased_segments_get_their_height_back_as_without_the_repair(tmp_path):
    """Loggers that start every segment at z = 0: whole jumps and flight-only segments (no
    foot down: the repair cannot weigh or place them) are raised as without --repair, and
    the repair then finds nothing more."""
    from _logs import flight_segment

    ds = sim_go1()
    whole = _copy(jump(ds, 0))
    whole["q"][:, 12:15] -= whole["q"][0, 12:15]
    log = write_plain(tmp_path / "rebased.csv", [whole] + [flight_segment(ds, j) for j in (1, 2)])
    plain, _ = import_logs([log], robot="go1")
    fixed, _ = import_logs([log], robot="go1", repair=REPAIR)
    for key in ARRAYS:
        np.testing.assert_array_equal(getattr(fixed, key), getattr(plain, key), err_msg=key)
    assert len(fixed.generator["rebased"]) == 3
    assert not any(r["changed"] for r in fixed.generator["repairs"]["jumps"])


@pytest.mark.parametrize("robot", ["go1", "a1"])
def test_a_one_row_contact_lag_is_undone_exactly(tmp_path, robot):
    """Every flag change logged one row late: the feet's heights and speeds say where each
    touch-down and lift-off was; the flags move back to the true rows exactly."""
    ds, _ = _sim(robot)
    m = jump(ds, 0)
    logged = _copy(m)
    logged["contact"] = _lagged(m["contact"])
    assert (logged["contact"] != m["contact"]).sum() >= 8
    got, rec = _repaired(tmp_path, robot, logged)
    k = rec["contacts"]
    assert k["lag"] == 1 and k["applied"] and "1 row late" in rec["line"]
    np.testing.assert_array_equal(got.contact, m["contact"])


def test_a_header_less_contact_topic_lands_on_the_nearest_row(tmp_path):
    """Contact flags without a header, received 0.8 ms after the joints' stamps (at 500 Hz):
    matched to the nearest joint row, every flag is on its row; the last message at or before
    each row (the reader's former rule) put every change one row late."""
    from symrom.data.bags import read_bag

    m = jump(sim_go1(), 0)
    bag = write_ros2(tmp_path / "late", m, storage="sqlite3", contact_delay=0.0008)
    lg = read_bag(bag, "go1")
    np.testing.assert_array_equal(lg.contact, m["contact"])
    t_ns = np.round(m["t"] * 1e9).astype(np.int64)
    former = m["contact"][np.clip(np.searchsorted(t_ns + 800_000, t_ns, side="right") - 1, 0, None)]
    assert (former != m["contact"]).sum() == 8  # 4 feet x (lift-off, touch-down)
    # a delay past half a period lands one row late by nearest too: the repair moves it back
    bag = write_ros2(tmp_path / "later", m, storage="sqlite3", contact_delay=0.0013)
    got, _ = import_logs([bag], robot="go1", repair=REPAIR, segment="off")
    (rec,) = got.generator["repairs"]["jumps"]
    assert rec["contacts"]["lag"] == 1
    np.testing.assert_array_equal(got.contact, m["contact"][1:])  # row 0 has no message within half a period


# ----------------------------------------------------------------- faults as real logs have them

def test_a_go1_log_with_the_faults_of_the_real_one(tmp_path):
    """Velocities 1/1.06 of the true ones on a right clock, torques 0.56 of the true ones,
    the feet in contact 21.7 mm below the ground, and a one-row contact lag: refused as
    logged, repaired with --repair (every estimate within its bound) and then passing every
    check."""
    m = jump(sim_go1(), 2)
    logged = _copy(m)
    logged["dq"] = m["dq"] / 1.06
    logged["tau"] = 0.56 * m["tau"]
    logged["q"][:, Z] -= 0.0217
    logged["contact"] = _lagged(m["contact"])
    log = write_plain(tmp_path / "go1_real.csv", [logged], accelerations=False)
    one_line_error(runner.invoke(app, ["import", str(log), "--robot", "go1", "--out", str(tmp_path / "x.h5")]),
                   "go1_real.csv", "jump 0", "1.06 times")
    out = tmp_path / "go1.h5"
    r = runner.invoke(app, ["import", str(log), "--robot", "go1", "--out", str(out), "--repair"])
    assert r.exit_code == 0, r.output
    assert "warning" not in r.output
    text = " ".join(r.output.split())
    assert "repair: go1_real.csv jump 0: clock right" in text and "velocities wrong" in text
    got = read_dataset(out)
    (rec,) = got.generator["repairs"]["jumps"]
    assert rec["clock"]["finding"] == "velocities" and abs(rec["clock"]["flight_g"] - 1) < 0.01
    assert all(abs(v["gain"] * 1.06 - 1) < 0.005 for v in rec["velocities"])
    assert abs(rec["gain"]["gain"] / 0.56 - 1) < 0.03
    assert abs(rec["height"]["offset"] - 0.0217) < 0.002
    assert rec["contacts"]["lag"] == 1
    np.testing.assert_array_equal(got.t, m["t"])
    np.testing.assert_array_equal(got.contact, m["contact"])
    np.testing.assert_allclose(got.tau, m["tau"], rtol=0.03, atol=1e-9)
    assert np.abs(got.q[:, Z] - m["q"][:, Z]).max() < 0.002
    assert got.generator["files"][0]["consistency"] == []


def test_a1_froggy_logs_without_timestamps_with_the_faults_of_the_real_ones(tmp_path, monkeypatch):
    """Logs without timestamps, their period estimated 2 % short and the loop's rate drifting
    +-6 % within each jump, the feet 28 mm above the ground: each jump's clock is warped
    back (velocities right: the flight falls at g on it) and its height found."""
    ds = sim_a1_froggy()
    logs, truth = [], []
    for j in range(ds.n_jumps):
        m = jump(ds, j)
        t_end = m["t"][-1]
        logged = on_clock(m, lambda t: 1.02 + 0.06 * np.sin(2 * np.pi * t / t_end + j))
        logged["q"][:, Z] += 0.028
        logs.append(logged)
        truth.append(m)
    path = write_plain(tmp_path / "a1_real.csv", logs, accelerations=False)
    with pytest.raises(Exception, match="feet in contact sit 28"):
        import_logs([path], robot="a1", motion="froggy")
    read = _logs_read(monkeypatch)
    got, _ = import_logs([path], robot="a1", motion="froggy", repair=REPAIR)
    (lg,) = read
    recs = got.generator["repairs"]["jumps"]
    assert len(recs) == len(logs)
    for j, (rec, logged) in enumerate(zip(recs, logs)):
        a, b = lg.bounds()[j]
        assert rec["clock"]["finding"] == "clock" and rec["clock"]["warp"], rec["line"]
        assert abs(rec["clock"]["flight_g"] - 1) < 0.01
        _times_within(lg.t[a:b], logged["t_true"], logged["t"])
        assert abs(rec["height"]["offset"] + 0.028) < 0.002
        assert not rec["gain"]["applied"] and not any(v["applied"] for v in rec["velocities"])
    assert all(f["consistency"] == [] for f in got.generator["files"])
    # the dataset's period: the coarsest jump's, now on its true clock (2 % longer and drifting)
    assert abs(got.dt / max(np.median(np.diff(x["t_true"])) for x in logs) - 1) < 0.005


def _without_time(path):
    """The plain log at ``path`` with its time column removed (a logger that writes none)."""
    lines = path.read_text().splitlines()
    col = lines[0].split(",").index("t")
    path.write_text("\n".join(",".join(c for i, c in enumerate(line.split(",")) if i != col) for line in lines) + "\n")
    return path


def test_a1_froggy_logs_without_a_time_column_are_read_at_their_nominal_period_and_retimed(tmp_path,
                                                                                         monkeypatch):
    """A1 froggy logs with no time column, by a loop 3 % slower than its 2 ms and drifting +-5 %
    within each jump: refused without a period (one line naming the time column and period);
    read 2 ms apart, each jump's rows are warped back to their true times by the flight."""
    ds = sim_a1_froggy()
    logs = []
    for j in range(ds.n_jumps):
        m = jump(ds, j)
        t_end = m["t"][-1]
        logs.append(on_clock(m, lambda t: 1.03 + 0.05 * np.sin(2 * np.pi * t / t_end + j)))
    path = _without_time(write_plain(tmp_path / "a1_untimed.csv", logs, accelerations=False))
    one_line_error(runner.invoke(app, ["import", str(path), "--robot", "a1", "--motion", "froggy", "--out",
                                       str(tmp_path / "x.h5"), "--repair"]),
                   "a1_untimed.csv", "without a time column ('t')", "--period", "--repair")
    lg = read_log(path, period=0.002)
    assert lg.period == 0.002 and lg.n_jumps == ds.n_jumps
    for a, b in lg.bounds():
        np.testing.assert_array_equal(lg.t[a:b], np.arange(b - a) * 0.002)
    read = _logs_read(monkeypatch)
    out = tmp_path / "a1.h5"
    r = runner.invoke(app, ["import", str(path), "--robot", "a1", "--motion", "froggy", "--out", str(out),
                            "--repair", "--period", "0.002"])
    assert r.exit_code == 0 and "warning" not in r.output, r.output
    (lg,) = read
    got = read_dataset(out)
    recs = got.generator["repairs"]["jumps"]
    assert len(recs) == len(logs)
    for j, rec in enumerate(recs):
        a, b = lg.bounds()[j]
        assert rec["clock"]["finding"] == "clock" and rec["clock"]["warp"], rec["line"]
        _times_within(lg.t[a:b], logs[j]["t_true"], logs[j]["t"])
    assert got.generator["files"][0]["time"] == {"column": False, "period": 0.002}
    assert got.generator["files"][0]["consistency"] == []
    assert abs(got.dt / max(np.median(np.diff(x["t_true"])) for x in logs) - 1) < 0.005


def test_proxy_go1_jumps_noise_drift_and_soft_feet_repaired_alike(tmp_path):
    """Hardware-like jumps (sensor noise, estimator drift, soft feet, their own torque
    sensor): the planted Go1 faults are found on top of what each jump shows clean."""
    ds = proxy_go1()
    for j in range(ds.n_jumps):
        m = jump(ds, j)
        # the clean jump's own estimates: the repair alone, no dataset needed
        (clean,) = repair_log(read_log(write_plain(tmp_path / f"clean{j}.csv", [m], accelerations=False)), "go1",
                              REPAIR)
        logged = _copy(m)
        logged["dq"] = m["dq"] / 1.06
        logged["tau"] = 0.56 * m["tau"]
        logged["q"][:, Z] -= 0.0217
        got, rec = _repaired(tmp_path, "go1", logged, name=f"faults{j}.csv")
        assert rec["clock"]["finding"] == "velocities", rec["line"]
        joints = rec["velocities"][0]
        assert abs(joints["gain"] * 1.06 - 1) < 0.02  # the noise: 1.5 % at most over these jumps
        assert abs(rec["gain"]["gain"] / clean.gain.gain / 0.56 - 1) < 0.03
        assert abs(rec["height"]["offset"] - clean.height.offset - 0.0217) < 0.002
        assert got.generator["files"][0]["consistency"] == []


def test_the_flights_of_a_file_together_tell_a_clock_from_velocities(tmp_path):
    """Velocities 1/1.03 of the true ones on hardware-like Go1 jumps (noise, drift, soft feet):
    on some jumps the ratio is off but their flight alone fits a wrong clock and wrong
    velocities alike (undetermined, kept as logged); in one file, written by one logger, the
    flights of its jumps together tell the velocities apart on those jumps too."""
    ds = proxy_go1()
    logs = []
    for j in range(ds.n_jumps):
        m = jump(ds, j)
        m["dq"] = m["dq"] / 1.03
        logs.append(m)
    alone = [repair_log(read_log(write_plain(tmp_path / f"one{j}.csv", [m], accelerations=False)), "go1", REPAIR)[0]
             for j, m in enumerate(logs)]
    undetermined = [j for j, r in enumerate(alone) if r.clock.finding == "undetermined"]
    assert undetermined and all(r.clock.finding in ("none", "velocities", "undetermined") for r in alone)
    together = repair_log(read_log(write_plain(tmp_path / "all.csv", logs, accelerations=False)), "go1", REPAIR)
    for j in undetermined:
        r = together[j]
        assert r.clock.finding == "velocities" and "told by the file's flights together" in r.line(), r.line()
        assert abs(r.velocities[0].gain * 1.03 - 1) < 0.01 and not r.clock.applied
    for a, b in zip(alone, together):  # the jumps one flight decides are decided alike
        if a.clock.finding != "undetermined":
            assert b.clock.finding == a.clock.finding


@pytest.mark.parametrize("retime", [False, True])
def test_stale_rows_do_not_pass_for_faults(tmp_path, retime):
    """16 % of the joint rows and 40 % of the base rows repeat the previous one (stale reads,
    as a real logger's), as logged or retimed (--retime-stale): nothing to repair, and the
    planted velocity and torque faults still found."""
    m = jump(sim_go1(), 2)
    rng = np.random.default_rng(5)
    stale = _copy(m)
    for i in np.flatnonzero(rng.random(m["t"].size - 2) < 0.16) + 1:
        stale["q"][i, :12], stale["dq"][i, :12], stale["tau"][i] = stale["q"][i - 1, :12], stale["dq"][i - 1, :12], \
            stale["tau"][i - 1]
    for i in np.flatnonzero(rng.random(m["t"].size - 2) < 0.4) + 1:
        stale["q"][i, 12:], stale["dq"][i, 12:] = stale["q"][i - 1, 12:], stale["dq"][i - 1, 12:]
    _, rec = _repaired(tmp_path, "go1", stale, name="stale.csv", retime=retime)
    assert not rec["changed"], rec["line"]
    stale["dq"] = stale["dq"] / 1.06
    stale["tau"] = 0.56 * stale["tau"]
    _, rec = _repaired(tmp_path, "go1", stale, name="faults.csv", retime=retime)
    assert rec["clock"]["finding"] == "velocities" and abs(rec["velocities"][0]["gain"] * 1.06 - 1) < 0.005
    assert abs(rec["gain"]["gain"] / 0.56 - 1) < 0.03 and rec["gain"]["kinds"] is None


# ----------------------------------------------------------------- refusals

def test_a_ratio_without_a_flight_to_tell_clock_from_velocities_is_refused(tmp_path):
    """The push-off alone (no flight): positions change 1.06 times as fast as the velocities
    integrate to, and nothing tells a wrong clock from wrong velocities."""
    m = jump(sim_go1(), 0)
    stance = int(np.flatnonzero(m["contact"].sum(axis=1) == 0)[0])
    logged = {k: v[:stance].copy() for k, v in m.items()}
    logged["dq"] = logged["dq"] / 1.06
    log = write_plain(tmp_path / "stance.csv", [logged], accelerations=False)
    line = one_line_error(runner.invoke(app, ["import", str(log), "--robot", "go1", "--out",
                                              str(tmp_path / "x.h5"), "--repair"]),
                          "stance.csv", "jump 0", "1.06 times as fast", "without a flight",
                          "wrong clock cannot be told from wrong velocities")
    assert "lenient keeps it as logged" in line
    # --lenient keeps it as logged and says so; the check's problem is listed
    got, _ = import_logs([log], robot="go1", repair=REPAIR, lenient=True)
    (rec,) = got.generator["repairs"]["jumps"]
    assert rec["clock"]["finding"] == "undetermined" and "without a flight" in rec["kept"][0]
    assert [p["check"] for p in got.generator["files"][0]["consistency"]] == ["time scale"] * 2
    # a small ratio the check accepts as logged is kept, not refused
    logged["dq"] = logged["dq"] * 1.06 / 1.03
    kept, _ = import_logs([write_plain(tmp_path / "small.csv", [logged], accelerations=False)], robot="go1",
                       repair=REPAIR)
    (rec,) = kept.generator["repairs"]["jumps"]
    assert rec["clock"]["finding"] == "undetermined" and "passes the consistency check" in rec["kept"][0]


def test_a_rate_changing_faster_than_the_windows_resolve_is_refused(tmp_path):
    """The loop's rate jumping between 0.9 and 1.1 every 60 ms: no smooth warp fits the 50 ms
    windows."""
    m = jump(sim_go1(), 1)
    steps = np.random.default_rng(1).choice([0.9, 1.1], 100)
    logged = on_clock(m, lambda t: steps[int(t / 0.06)])
    log = write_plain(tmp_path / "jumpy.csv", [logged], accelerations=False)
    one_line_error(runner.invoke(app, ["import", str(log), "--robot", "go1", "--out", str(tmp_path / "x.h5"),
                                       "--repair"]),
                   "jumpy.csv", "jump 0", "changes faster than the 50 ms windows resolve", "the limit is 2 %")
    with pytest.raises(RepairError, match="faster than the 50 ms windows"):
        repair_log(read_log(log), "go1", REPAIR)


def test_units_are_checked_before_the_repair(tmp_path):
    """Degrees for radians are named as such, not taken for a clock fault."""
    m = jump(sim_go1(), 0)
    m["q"][:, 2] = np.degrees(m["q"][:, 2])
    log = write_plain(tmp_path / "deg.csv", [m])
    one_line_error(runner.invoke(app, ["import", str(log), "--robot", "go1", "--out", str(tmp_path / "x.h5"),
                                       "--repair"]),
                   "deg.csv", "column 'fr_kn'", "degrees for radians")
