"""CSV log import: the Go1 hardware-log layout, the plain layout, and their errors."""

from __future__ import annotations

import hashlib
import json
from functools import partial

import numpy as np
import pytest
from typer.testing import CliRunner

from symrom.cli import app
from symrom.data.importers import LogError, parse_split, read_log, write_plain_csv
from symrom.data.importers import import_logs as _import_logs
from symrom.data.io import read_dataset
from symrom.data.preprocess import com_wrench, differentiate
from symrom.testing import make_planted_dataset

# The planted motions here test the layouts, not physics: their torques are arbitrary, so
# the physical-consistency checks (tests/test_import_physics.py) are left out.
import_logs = partial(_import_logs, physics=None)

N_PER_JUMP = 60
DT = 0.002

# The hardware layout spelled out by hand (not derived from the importer's tables):
# joints FR FL RR RL x hx hy kn, body linear x y z, body angular x y z = roll pitch yaw.
HW_JOINTS = ["fr.hx", "fr.hy", "fr.kn", "fl.hx", "fl.hy", "fl.kn",
             "rr.hx", "rr.hy", "rr.kn", "rl.hx", "rl.hy", "rl.kn"]
HW_BODY = ["Body linear {} x", "Body linear {} y", "Body linear {} z",
           "Body angular {} x", "Body angular {} y", "Body angular {} z"]
HW_FEET = ["fr Foot", "fl Foot", "rr Foot", "rl Foot"]


def _hw_q_columns(quantity: str) -> list[str]:
    return [f"{j} {quantity}" for j in HW_JOINTS] + [b.format(quantity) for b in HW_BODY]


# Planted values scaled into a Go1's plausible ranges (joint angles about a standing
# posture, a base height about 0.3 m), every component still distinct.
SCALE = np.r_[np.full(12, 0.1), np.full(3, 0.02), np.full(3, 0.1)]
OFFSET = np.r_[np.tile([0.0, 0.8, -1.5], 4), 0.0, 0.0, 0.3, 0.0, 0.0, 0.0]


def plausible(ds):
    """A planted dataset moved into the Go1's plausible ranges (q, dq, ddq scaled alike)."""
    from dataclasses import replace

    return replace(ds, robot="go1", q=SCALE * ds.q + OFFSET, dq=SCALE * ds.dq, ddq=SCALE * ds.ddq)


def _motion():
    """Two jumps of a planted smooth motion with staggered per-foot contact flags."""
    ds = plausible(make_planted_dataset(n_jumps=2, n_samples=N_PER_JUMP, seed=3, noise=0.0)[0])
    n = ds.n_samples
    q, dq, ddq = ds.q, ds.dq, ds.ddq
    tau = np.linspace(-5, 5, n * 12).reshape(n, 12) + np.arange(12)
    i = np.arange(N_PER_JUMP)
    # Foot k leaves at 20 + 2k and lands at 40 + 3k: every foot has its own pattern.
    one = np.stack([((i < 20 + 2 * k) | (i >= 40 + 3 * k)) for k in range(4)], axis=1)
    contact = np.tile(one, (2, 1)).astype(np.uint8)
    return {"jump": ds.jump, "q": q, "dq": dq, "ddq": ddq, "tau": tau, "contact": contact}


def _cell(v: float) -> str:
    return repr(float(v)).replace(".", ",")


def _write_hardware(path, m, *, accelerations=True, shuffle=True, drop=(), extra=()):
    """Write motion ``m`` in the hardware layout: ';', decimal commas, Time restarting."""
    cols: dict[str, np.ndarray] = {}
    n = m["q"].shape[0]
    t = np.tile(np.arange(N_PER_JUMP), 2)
    cols["Time"] = np.array([f"{k * 2 // 1000},{k * 2 % 1000:03d}" for k in t])
    for name, v in zip(_hw_q_columns("Position"), m["q"].T):
        cols[name] = v
    for name, v in zip(_hw_q_columns("Velocity"), m["dq"].T):
        cols[name] = v
    if accelerations:
        for name, v in zip(_hw_q_columns("Acceleration"), m["ddq"].T):
            cols[name] = v
    for j, v in zip(HW_JOINTS, m["tau"].T):
        cols[f"{j} Torque"] = v
    for name, v in zip(HW_FEET, m["contact"].T):
        cols[name] = v.astype(int).astype(str)
    for name in extra:
        cols[name] = np.zeros(n)
    for name in drop:
        del cols[name]
    names = list(cols)
    if shuffle:
        names = [names[k] for k in np.random.default_rng(0).permutation(len(names))]
    lines = [";".join(f"  {nm} " for nm in names)]
    for r in range(n):
        lines.append(";".join(cols[nm][r] if cols[nm].dtype.kind in "US" else _cell(cols[nm][r])
                              for nm in names))
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def motion():
    return _motion()


def test_hardware_layout_every_array(tmp_path, motion):
    log = _write_hardware(tmp_path / "jumps.csv", motion)
    assert "0,002" in log.read_text()
    ds, _ = import_logs([log], robot="go1", motion="pronk", split="1,0,1")
    m = motion
    assert ds.n_jumps == 2 and ds.n_samples == 2 * N_PER_JUMP
    np.testing.assert_array_equal(ds.jump, np.repeat([0, 1], N_PER_JUMP))
    np.testing.assert_allclose(ds.t, np.tile(np.arange(N_PER_JUMP) * DT, 2), atol=1e-12)
    assert ds.dt == pytest.approx(DT, abs=1e-12)
    np.testing.assert_array_equal(ds.q, m["q"])
    np.testing.assert_array_equal(ds.dq, m["dq"])
    np.testing.assert_array_equal(ds.ddq, m["ddq"])
    np.testing.assert_array_equal(ds.tau, m["tau"])
    np.testing.assert_array_equal(ds.contact, m["contact"])
    # q order: spot-check named components against the hardware columns they came from.
    hw = read_log(log)
    assert hw.layout == "hardware"
    np.testing.assert_array_equal(ds.q[:, 5], m["q"][:, 5])    # fl_kn <- "fl.kn Position"
    np.testing.assert_array_equal(ds.q[:, 15], m["q"][:, 15])  # roll  <- "Body angular Position x"
    np.testing.assert_array_equal(ds.q[:, 17], m["q"][:, 17])  # yaw   <- "Body angular Position z"
    np.testing.assert_array_equal(ds.contact[:, 2], m["contact"][:, 2])  # rr <- "rr Foot"
    # Phases (pronk): flight exactly when no foot is down.
    assert ds.phase_names == ["contact", "flight"]
    expect = np.where(m["contact"].sum(1) == 0, 1, 0)
    np.testing.assert_array_equal(ds.phase, expect)
    assert set(ds.phase[:N_PER_JUMP]) == {0, 1}
    # Inputs: torques then the wrench of the named robot.
    np.testing.assert_array_equal(ds.u[:, :12], m["tau"])
    np.testing.assert_allclose(ds.u[:, 12:], com_wrench("go1", m["q"], m["tau"], m["contact"]))
    assert list(ds.split) == ["train", "test"]
    gen = ds.generator
    assert gen["files"][0]["name"] == "jumps.csv"
    assert gen["files"][0]["sha256"] == hashlib.sha256(log.read_bytes()).hexdigest()
    assert gen["files"][0]["ddq"] == "logged"
    assert gen["options"]["robot"] == "go1" and gen["options"]["split"] == "1,0,1"


def test_hardware_without_accelerations_differentiates(tmp_path, motion):
    log = _write_hardware(tmp_path / "noacc.csv", motion, accelerations=False)
    ds, _ = import_logs([log], robot="go1", diff_method="central")
    expect = differentiate(motion["dq"], DT, ds.jump, "central")
    np.testing.assert_allclose(ds.ddq, expect, rtol=1e-9, atol=1e-9)
    assert "differentiated" in ds.generator["files"][0]["ddq"]


def test_several_files_are_consecutive_jumps(tmp_path, motion):
    a = _write_hardware(tmp_path / "a.csv", motion)
    b = _write_hardware(tmp_path / "b.csv", motion, shuffle=False)
    ds, _ = import_logs([a, b], robot="a1", motion="froggy", split="2,1,1")
    assert ds.n_jumps == 4
    np.testing.assert_array_equal(ds.jump, np.repeat(np.arange(4), N_PER_JUMP))
    np.testing.assert_array_equal(ds.q, np.concatenate([motion["q"]] * 2))
    assert list(ds.split) == ["train", "train", "val", "test"]
    assert [f["name"] for f in ds.generator["files"]] == ["a.csv", "b.csv"]
    assert ds.phase_names == ["contact", "partial", "flight"]
    # froggy: 1-3 feet before the first flight is partial, after it contact.
    n_down = motion["contact"][:N_PER_JUMP].sum(1)
    first_flight = np.flatnonzero(n_down == 0)[0]
    ph = ds.phase[:N_PER_JUMP]
    assert np.all(ph[:first_flight][(n_down[:first_flight] > 0) & (n_down[:first_flight] < 4)] == 1)
    assert np.all(ph[first_flight:][(n_down[first_flight:] > 0)] == 0)
    assert np.all(ph[n_down == 0] == 2)


def test_plain_layout_round_trip(tmp_path):
    ds0 = plausible(make_planted_dataset(n_jumps=3, n_samples=50, seed=1)[0])
    ds0, _ = import_logs([_export(ds0, tmp_path / "seed.csv")], robot="go1")  # physical wrench
    path = tmp_path / "plain.csv"
    write_plain_csv(ds0, path)
    header = path.read_text().splitlines()[0].split(",")
    assert header[:3] == ["jump", "t", "fr_hx"] and "dd_yaw" in header and header[-4:] == [
        "c_fr", "c_fl", "c_rr", "c_rl"]
    ds, _ = import_logs([path], robot="go1", split="1,1,1")
    for key in ("jump", "t", "q", "dq", "ddq", "tau", "contact", "u", "phase"):
        np.testing.assert_array_equal(getattr(ds, key), getattr(ds0, key), err_msg=key)
    assert ds.dt == ds0.dt == pytest.approx(DT)
    assert list(ds.split) == ["train", "val", "test"]


def _export(ds, path):
    write_plain_csv(ds, path)
    return path


def test_plain_without_jump_column_uses_time_restart(tmp_path):
    ds0 = plausible(make_planted_dataset(n_jumps=2, n_samples=30, seed=2)[0])
    path = _export(ds0, tmp_path / "p.csv")
    lines = path.read_text().splitlines()
    path.write_text("\n".join(",".join(line.split(",")[1:]) for line in lines) + "\n")
    ds, _ = import_logs([path], robot="go1")
    np.testing.assert_array_equal(ds.jump, ds0.jump)
    np.testing.assert_array_equal(ds.q, ds0.q)


def test_missing_and_unknown_columns_named(tmp_path, motion):
    drop = ["fl.kn Position", "Body angular Velocity z", "rl Foot"]
    log = _write_hardware(tmp_path / "bad.csv", motion, drop=drop, extra=["Battery voltage"])
    with pytest.raises(LogError) as e:
        import_logs([log], robot="go1")
    msg = str(e.value)
    assert "bad.csv" in msg and "\n" not in msg
    for name in drop + ["Battery voltage"]:
        assert name in msg
    assert "Time" not in msg.split("missing columns:")[1].split(";")[0]


def test_partial_acceleration_group_is_missing(tmp_path, motion):
    log = _write_hardware(tmp_path / "acc.csv", motion, drop=["rr.hy Acceleration"])
    with pytest.raises(LogError, match="missing columns: rr.hy Acceleration"):
        read_log(log)


def test_bad_cell_names_line_and_column(tmp_path, motion):
    log = _write_hardware(tmp_path / "cell.csv", motion, shuffle=False)
    lines = log.read_text().splitlines()
    header = [h.strip() for h in lines[0].split(";")]
    col = header.index("fr.kn Velocity")
    cells = lines[7].split(";")
    cells[col] = "abc"
    lines[7] = ";".join(cells)
    log.write_text("\n".join(lines) + "\n")
    with pytest.raises(LogError) as e:
        read_log(log)
    msg = str(e.value)
    assert "cell.csv" in msg and "line 8" in msg and "'fr.kn Velocity'" in msg and "'abc'" in msg


def test_contact_flag_not_binary(tmp_path, motion):
    m = dict(motion, contact=motion["contact"].copy())
    m["contact"][10, 1] = 2
    log = _write_hardware(tmp_path / "flag.csv", m, shuffle=False)
    with pytest.raises(LogError, match=r"line 12, column 'fl Foot': contact flag 2"):
        read_log(log)


def test_parse_split():
    assert list(parse_split(None, 3)) == ["train"] * 3
    assert list(parse_split("2,1,0", 3)) == ["train", "train", "val"]
    assert list(parse_split("0.5,0.25,0.25", 4)) == ["train", "train", "val", "test"]
    with pytest.raises(ValueError, match="add up to 4 jumps"):
        parse_split("2,1,1", 3)
    with pytest.raises(ValueError, match="three"):
        parse_split("2,1", 3)


def test_cli_import(tmp_path, motion):
    log = _write_hardware(tmp_path / "cli.csv", motion)
    out = tmp_path / "real.h5"
    runner = CliRunner()
    r = runner.invoke(app, ["import", str(log), "--robot", "go1", "--out", str(out),
                            "--split", "1,1,0", "--motion", "pronk", "--no-physics"])
    assert r.exit_code == 0, r.output
    ds = read_dataset(out)
    assert ds.robot == "go1" and ds.source == "hardware" and list(ds.split) == ["train", "val"]
    np.testing.assert_array_equal(ds.q, motion["q"])
    assert json.loads(json.dumps(ds.generator))["files"][0]["name"] == "cli.csv"
    before = out.read_bytes()
    r = runner.invoke(app, ["import", str(log), "--robot", "go1", "--out", str(out)])
    assert r.exit_code != 0 and "--force" in r.output and out.read_bytes() == before
    r = runner.invoke(app, ["import", str(log), "--robot", "go1", "--out", str(out), "--force", "--no-physics"])
    assert r.exit_code == 0, r.output
    assert list(read_dataset(out).split) == ["train", "train"]


@pytest.mark.parametrize("cell", ["nan", "", "inf"])
def test_non_finite_or_empty_cell(tmp_path, cell):
    ds0, _ = make_planted_dataset(n_jumps=2, n_samples=20, seed=4)
    path = _export(ds0, tmp_path / "p.csv")
    lines = path.read_text().splitlines()
    cells = lines[3].split(",")
    cells[-5] = cell  # tau_rl_kn
    lines[3] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(LogError, match=r"p\.csv, line 4, column 'tau_rl_kn': .* is not a finite number"):
        read_log(path)


def test_wrong_number_of_cells(tmp_path):
    ds0, _ = make_planted_dataset(n_jumps=2, n_samples=20, seed=4)
    path = _export(ds0, tmp_path / "p.csv")
    lines = path.read_text().splitlines()
    lines[9] = lines[9].rsplit(",", 2)[0]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(LogError, match=r"line 10: 70 cells, the header has 72"):
        read_log(path)


def test_repeated_time_is_an_error(tmp_path, motion):
    log = _write_hardware(tmp_path / "rep.csv", motion, shuffle=False)
    lines = log.read_text().splitlines()
    cells = lines[6].split(";")
    cells[0] = lines[5].split(";")[0]
    lines[6] = ";".join(cells)
    log.write_text("\n".join(lines) + "\n")
    with pytest.raises(LogError, match="line 7: time .* repeats"):
        read_log(log)


def test_plain_jump_column_must_be_contiguous(tmp_path):
    ds0, _ = make_planted_dataset(n_jumps=2, n_samples=10, seed=4)
    path = _export(ds0, tmp_path / "p.csv")
    lines = path.read_text().splitlines()
    lines[5] = "1" + lines[5][1:]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(LogError, match="line 7, column 'jump': jump 0 continues after another jump"):
        read_log(path)


# ----------------------------------------------------------------- front door

@pytest.mark.parametrize("text", ["symrom dataset\n", "t,fr_hx\n0,0.1\n"])
def test_a_text_file_named_h5_is_named_as_such(tmp_path, text):
    path = tmp_path / "jumps.h5"
    path.write_text(text)
    out = tmp_path / "out.h5"
    r = CliRunner().invoke(app, ["import", str(path), "--robot", "go1", "--out", str(out)])
    assert r.exit_code != 0 and "Traceback" not in r.output
    line = " ".join(r.output.split())
    assert "jumps.h5: named like an HDF5 file (.h5) but its content is not one" in line
    assert "CSV logs" in line and "name it .csv" in line and "no samples" not in line
    assert not out.exists()


def test_an_hdf5_dataset_given_as_a_log_is_named(tmp_path):
    ds = plausible(make_planted_dataset(n_jumps=2, n_samples=30, seed=2)[0])
    from symrom.data.io import write_dataset

    write_dataset(import_logs([_export(ds, tmp_path / "p.csv")], robot="go1")[0], tmp_path / "d.h5")
    with pytest.raises(LogError, match=r"d\.h5: an HDF5 file \(a symrom dataset\?\), not a log"):
        import_logs([tmp_path / "d.h5"], robot="go1")


def test_fractions_that_leave_a_split_empty_are_refused(tmp_path):
    ds = plausible(make_planted_dataset(n_jumps=5, n_samples=30, seed=2)[0])
    log = _export(ds, tmp_path / "five.csv")
    out = tmp_path / "out.h5"
    r = CliRunner().invoke(app, ["import", str(log), "--robot", "go1", "--out", str(out), "--no-physics",
                                 "--split", "0.8,0.1,0.1"])
    assert r.exit_code != 0 and len(r.output.strip().splitlines()) >= 1 and "Traceback" not in r.output
    line = " ".join(r.output.split())
    for needle in ("--split 0.8,0.1,0.1", "5 jumps divide as 4 train, 1 val, 0 test", "test split is empty",
                   "e.g. 3,1,1"):
        assert needle in line, (needle, line)
    assert not out.exists()
    assert list(parse_split("0.6,0.2,0.2", 5)) == ["train"] * 3 + ["val", "test"]  # every split used: fine
    assert list(parse_split("1,0,0", 5)) == ["train"] * 5  # a split asked for as 0 stays empty
