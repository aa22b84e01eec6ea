"""Real logs as robots write them: a wrong time base, stale rows, a sign-flipped torque, the
wrong robot, commanded torques over the motor limit, a continuous recording of several
jumps, time-based grid and differentiation. Every log is made here from simulated Go1 jumps
(tests/_logs.py); each bad one must be refused in one line naming file, jump, rows, figure
and limit, with nothing written."""

from __future__ import annotations

import numpy as np
import pytest
from _logs import at_times, jump, proxy_go1, sim_go1, write_hardware, write_plain
from conftest import one_line_error
from typer.testing import CliRunner

from symrom.cli import app
from symrom.data.consistency import stale_mask
from symrom.data.importers import LogError, diff_samples, import_logs
from symrom.data.io import read_dataset
from symrom.data.preprocess import differentiate
from symrom.data.timebase import TimeBase, jump_timing, on_grid

runner = CliRunner()
FR_HY, RL_KN = 1, 11


def _import(*args):
    return runner.invoke(app, ["import", *(str(a) for a in args)])


def _nothing_written(folder, logs):
    assert sorted(p.name for p in folder.iterdir()) == sorted(p.name for p in logs)


# ----------------------------------------------------------------- time scale

def test_a_1khz_loop_log_given_the_wrong_period_is_refused(tmp_path):
    """Loop iterations 1.16 ms apart written as 1 ms apart: positions change 1.16 times as fast
    as the velocities say."""
    m = jump(sim_go1(), 0)
    true = np.arange(int(m["t"][-1] / 0.00116) + 1) * 0.00116
    wrong = at_times(m, true)
    wrong["t"] = np.arange(true.size) * 0.001
    log = write_plain(tmp_path / "loop.csv", [wrong], accelerations=False)
    line = one_line_error(_import(log, "--robot", "go1", "--out", tmp_path / "d.h5"),
                          "loop.csv", "jump 0", f"rows 0-{true.size - 1}", "joint angles change 1.16 times",
                          "0.95..1.05", "1.16 ms apart logged as 1 ms")
    assert "base position" not in line  # the first failing group only
    _nothing_written(tmp_path, [log])


def test_the_same_log_with_its_true_times_is_stored_as_logged_at_its_own_period(tmp_path):
    m = jump(sim_go1(), 0)
    true = np.arange(int(m["t"][-1] / 0.00116) + 1) * 0.00116
    log = write_plain(tmp_path / "loop.csv", [at_times(m, true)], accelerations=False)
    ds, _ = import_logs([log], robot="go1")
    assert ds.dt == 0.00116 and ds.generator["time_base"]["jumps"][0]["stored"] == "as logged"
    assert ds.generator["files"][0]["consistency"] == []


def test_a_file_on_its_grid_is_not_pushed_off_it_by_rounding_its_period():
    """25 s at 1160 Hz: the period's 6-digit rounding (0.000862069 s) drifts 0.9 us off the
    logged times by the end; the jump is on its own grid and must be stored as logged."""
    t = np.arange(30000) / 1160.0
    x = jump_timing("f.csv", 0, t, list(range(t.size)), TimeBase())
    assert abs(x.period - 1 / 1160) < 1e-15 and x.median_dt == 0.000862069
    assert on_grid(t, x.period, TimeBase().grid_tol)
    assert not on_grid(t, x.median_dt, TimeBase().grid_tol)  # what the rounded period did
    # 500 Hz keeps its round period exactly
    assert jump_timing("g.csv", 0, np.arange(700) * 0.002, list(range(700)), TimeBase()).period == 0.002


def test_velocities_in_degrees_per_second_against_radians_are_named(tmp_path):
    m = jump(sim_go1(), 1)
    m["dq"][:, :12] = np.degrees(m["dq"][:, :12]) / 20  # within the speed limits, wrong by 57.3/20
    log = write_plain(tmp_path / "units.csv", [m])
    one_line_error(_import(log, "--robot", "go1", "--out", tmp_path / "d.h5"),
                   "units.csv", "jump 0", "joint angles change 0.349 times", "0.95..1.05")


def test_a_noisy_base_position_on_a_right_clock_passes_and_a_wrong_clock_is_still_caught():
    """The base position read with a proxy's sensor noise (2 mm, 0.02 m/s per row): the windows'
    ratios scatter widely, and their median left 1 by more than 5 % on a right clock; the
    least-squares ratio over the windows together stays within 2 % of 1 on every draw, and a
    loop 6 % slower than logged is still found at 1.06 in both groups."""
    from symrom.data.consistency import ConsistencyLimits, pooled_ratio, time_scale, window_ratios
    from symrom.names import BASE_POS

    limits, medians = ConsistencyLimits(), []
    for j in range(3):
        for seed in range(6):
            m = jump(sim_go1(), j)
            rng = np.random.default_rng(seed)
            m["q"][:, BASE_POS] += rng.normal(0.0, 0.002, (m["t"].size, 3))
            m["dq"][:, BASE_POS] += rng.normal(0.0, 0.02, (m["t"].size, 3))
            _, r, p = window_ratios(m["t"], m["q"][:, BASE_POS], m["dq"][:, BASE_POS], limits.window,
                                    limits.min_motion)
            medians.append(float(np.median(r)))
            assert abs(pooled_ratio(r, p) - 1.0) < 0.02 and time_scale("x", m["t"], m["q"], m["dq"], limits) == []
            if seed == 0:
                slow = {k: v.copy() for k, v in m.items()}
                slow["t"] = m["t"] / 1.06  # rows 1.06 times further apart than logged
                found = {p["group"]: p["value"] for p in time_scale("x", slow["t"], slow["q"], slow["dq"], limits)}
                assert set(found) == {"joint angles", "base position"}
                assert all(abs(v - 1.06) < 0.015 for v in found.values()), found
    assert min(medians) < 0.95  # what the median over windows refused


# ----------------------------------------------------------------- stale rows

def _stale(m: dict, rng, joints: float, base: float) -> tuple[dict, np.ndarray, np.ndarray]:
    """Copy m with a fraction of rows repeating the previous row's joint group (q, dq of the
    joints and tau) or base group (pose and rates): stale reads, caught up afterwards."""
    out = {k: v.copy() for k, v in m.items()}
    n = m["t"].size
    sj = np.r_[False, rng.random(n - 2) < joints, False]
    sb = np.r_[False, rng.random(n - 2) < base, False]
    for i in range(1, n):
        if sj[i]:
            out["q"][i, :12], out["dq"][i, :12], out["tau"][i] = out["q"][i - 1, :12], out["dq"][i - 1, :12], \
                out["tau"][i - 1]
        if sb[i]:
            out["q"][i, 12:], out["dq"][i, 12:] = out["q"][i - 1, 12:], out["dq"][i - 1, 12:]
    return out, sj, sb


def test_stale_rows_are_reported_and_retimed_on_request(tmp_path):
    m = jump(sim_go1(), 2)
    bad, sj, sb = _stale(m, np.random.default_rng(5), 0.16, 0.4)
    log = write_plain(tmp_path / "stale.csv", [bad], accelerations=False)
    out = tmp_path / "d.h5"
    r = _import(log, "--robot", "go1", "--out", out)
    assert r.exit_code == 0, r.output
    text = " ".join(r.output.split())
    assert f"stale.csv, jump 0: {int(sj.sum())} of {sj.size} rows" in text and "joints exactly" in text
    assert f"{int(sb.sum())} of {sb.size} rows" in text and "--retime-stale" in text
    kept = read_dataset(out)
    report = {s["group"]: s for s in kept.generator["files"][0]["stale"]}
    assert report["joints"]["rows"] == sj.sum() and report["base"]["rows"] == sb.sum()
    np.testing.assert_array_equal(kept.q, bad["q"])  # reported, not changed

    r = _import(log, "--robot", "go1", "--out", tmp_path / "r.h5", "--retime-stale")
    assert r.exit_code == 0, r.output
    fixed = read_dataset(tmp_path / "r.h5")
    assert {s["group"]: s["retimed"] for s in fixed.generator["files"][0]["stale"]} == {
        "joints": int(sj.sum()), "base": int(sb.sum())}
    # The stale rows now lie near the motion they stood for, far nearer than the repeats did.
    for rows, cols in ((sj, slice(0, 12)), (sb, slice(12, 18))):
        before = np.abs(bad["q"][rows, cols] - m["q"][rows, cols]).max()
        after = np.abs(fixed.q[rows, cols] - m["q"][rows, cols]).max()
        assert after < before / 5, (after, before)
    # and the differentiated accelerations lose the spikes the catch-ups made (the median row's
    # error falls 36-fold; what remains is at touch-down, where a velocity jump hides in stale rows).
    truth = differentiate(m["dq"], 0.002, np.zeros(m["t"].size, int))
    spike = np.median(np.abs(kept.ddq[:, :12] - truth[:, :12]))
    assert np.median(np.abs(fixed.ddq[:, :12] - truth[:, :12])) < spike / 10
    assert not stale_mask(fixed.q, fixed.dq, fixed.tau)["joints"][1:-2].any()


# ----------------------------------------------------------------- forces, robot

def test_a_sign_flipped_knee_torque_is_refused(tmp_path):
    m = jump(sim_go1(), 0)
    m["tau"][:, RL_KN] *= -1
    log = write_plain(tmp_path / "flip.csv", [m])
    one_line_error(_import(log, "--robot", "go1", "--out", tmp_path / "d.h5"),
                   "flip.csv", "jump 0", f"rows 0-{m['t'].size - 1}", "weight 128.5 N", "ratio 0.3",
                   "0.6..1.5", "sign flipped")
    _nothing_written(tmp_path, [log])


def test_all_torques_with_the_opposite_sign_give_a_negative_impulse(tmp_path):
    m = jump(proxy_go1(), 1)
    m["tau"] *= -1
    # about -0.9: the proxy's measured torque is off by up to 10 % in scale
    with pytest.raises(LogError, match=r"ratio -0\.[89]\d*, the limit is 0\.6\.\.1\.5; "
                                       r"the torques have the opposite sign"):
        import_logs([write_plain(tmp_path / "neg.csv", [m])], robot="go1")


def test_a_go1_log_imported_as_an_a1_is_refused(tmp_path):
    """Its values are all within the A1's ranges and its weight is the A1's within 5 %; its
    stance feet, placed by the A1's shorter legs, float 15 mm above the ground."""
    m = jump(sim_go1(), 1)
    log = write_hardware(tmp_path / "go1.csv", [m])
    one_line_error(_import(log, "--robot", "a1", "--out", tmp_path / "d.h5"),
                   "go1.csv", "jump 0", "by the a1 URDF the feet in contact sit 15", "mm above the ground",
                   "the limit is 8 mm", "another robot")
    _nothing_written(tmp_path, [log])
    assert import_logs([log], robot="go1")[0].generator["files"][0]["consistency"] == []


def test_lenient_keeps_and_lists_the_physical_problems(tmp_path):
    m = jump(sim_go1(), 0)
    m["tau"][:, RL_KN] *= -1
    log = write_plain(tmp_path / "flip.csv", [m])
    r = _import(log, "--robot", "go1", "--out", tmp_path / "d.h5", "--lenient")
    assert r.exit_code == 0, r.output
    assert "kept as logged (--lenient): " in r.output and "sign flipped" in " ".join(r.output.split())
    got = read_dataset(tmp_path / "d.h5")
    assert [p["check"] for p in got.generator["files"][0]["consistency"]] == ["vertical impulse"]
    np.testing.assert_array_equal(got.tau, m["tau"])


# ----------------------------------------------------------------- torques

def test_commanded_torques_over_the_motor_limit_are_refused(tmp_path):
    m = jump(sim_go1(), 0)
    m["tau"][:, FR_HY] *= 25.0 / np.abs(m["tau"][:, FR_HY]).max()  # peaks at 25 N m; the motor: 23.7
    first = int(np.flatnonzero(np.abs(m["tau"][:, FR_HY]) > 23.7)[0])
    log = write_plain(tmp_path / "cmd.csv", [m])
    one_line_error(_import(log, "--robot", "go1", "--out", tmp_path / "d.h5", "--torques", "commanded"),
                   "cmd.csv", "jump 0", f"row {first}", "column 'tau_fr_hy'", "commanded joint torque",
                   "[-23.7, 23.7] N m", "commanded: the motor limit 23.7 N m")
    _nothing_written(tmp_path, [log])
    # The same values read as measured torques are within 1.25 x the limit, and the flag is stored.
    r = _import(log, "--robot", "go1", "--out", tmp_path / "d.h5", "--torques", "measured")
    assert r.exit_code == 0, r.output
    got = read_dataset(tmp_path / "d.h5")
    assert got.generator["torques"] == "measured" and got.generator["options"]["limits"]["torques"] == "measured"


def test_the_a1_motor_limit_not_its_urdf_effort_bounds_commanded_torques(tmp_path):
    """The A1's URDF gives its thigh and knee 55 N m; its motors saturate at 33.5 N m."""
    from symrom.data.checks import PlausibilityLimits, check_samples

    tau = np.zeros((4, 12))
    tau[2, 2] = 34.0
    q = np.tile(np.r_[np.tile([0.0, 0.8, -1.5], 4), 0, 0, 0.3, 0, 0, 0], (4, 1))
    (p,) = check_samples("a1", q, np.zeros((4, 18)), tau, PlausibilityLimits(torques="commanded"))
    assert (p.name, p.first, p.high) == ("fr_kn", 2, 33.5)
    assert check_samples("a1", q, np.zeros((4, 18)), tau, PlausibilityLimits(torques="measured")) == []
    with pytest.raises(ValueError, match="torques='desired'"):
        PlausibilityLimits(torques="desired")


def test_commanded_torques_within_the_limit_store_the_flag(tmp_path):
    m = jump(sim_go1(), 2)
    log = write_plain(tmp_path / "ok.csv", [m])
    r = _import(log, "--robot", "go1", "--out", tmp_path / "d.h5", "--torques", "commanded")
    assert r.exit_code == 0, r.output and "torques: commanded" in r.output
    assert read_dataset(tmp_path / "d.h5").generator["torques"] == "commanded"


# ----------------------------------------------------------------- segmentation

def _continuous(ds, jumps) -> tuple[dict, list[int]]:
    """Jumps of ``ds`` one after the other as one recording: time running on, x and y carried on."""
    parts, starts, t0, offset = [], [], 0.0, np.zeros(18)
    for j in jumps:
        m = jump(ds, j)
        m["q"] = m["q"] + offset
        m["t"] = m["t"] + t0
        parts.append(m)
        starts.append(sum(p["t"].size for p in parts[:-1]))
        t0 = m["t"][-1] + ds.dt
        offset[12:14] = m["q"][-1, 12:14] - jump(ds, j)["q"][0, 12:14]
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}, starts


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """Five hardware-like jumps as one recording in the hardware layout (Time never restarts),
    read by both segmentation tests."""
    rec, starts = _continuous(proxy_go1(), range(5))
    return rec, starts, write_hardware(tmp_path_factory.mktemp("rec") / "rec.csv", [rec], accelerations=False)


def test_a_continuous_five_jump_recording_is_cut_into_five_jumps(tmp_path, recording):
    ds = proxy_go1()
    rec, starts, log = recording
    out = tmp_path / "d.h5"
    # --lenient: the proxy's sensor noise can move the time-scale check's median a little past its
    # 5 % on a quiet jump (the times here are exact); what is tested is the cutting
    r = _import(log, "--robot", "go1", "--out", out, "--split", "3,1,1", "--lenient")
    assert r.exit_code == 0, r.output
    text = " ".join(r.output.split())
    assert "segments: rec.csv jump 0 holds 5 flights, cut into 5 jumps" in text
    got = read_dataset(out)
    assert got.n_jumps == 5 and list(got.split) == ["train"] * 3 + ["val", "test"]
    (seg,) = got.generator["segments"]
    assert [s["rows"][0] for s in seg["segments"]][0] == 0 and seg["segments"][-1]["rows"][1] == rec["t"].size
    flight = got.phase_names.index("flight")
    for k, (a, b) in enumerate(got.jump_bounds()):
        air = np.diff(np.r_[0, got.phase[a:b] == flight, 0].astype(int))
        assert (air == 1).sum() == 1  # one flight per jump, with ground before and after it
        assert got.phase[a] != flight and got.phase[b - 1] != flight
        src = ds.jump_bounds()[k]
        src_air = np.flatnonzero(ds.phase[src[0]:src[1]] == flight)
        mine = np.flatnonzero(got.phase[a:b] == flight)
        offset = seg["segments"][k]["rows"][0] - starts[k]
        np.testing.assert_array_equal(mine + offset, src_air)  # the same flight rows as the source jump
        assert got.t[a] == 0.0
    # --segment off keeps the recording whole, as before
    whole, _ = import_logs([log], robot="go1", segment="off")
    assert whole.n_jumps == 1 and whole.generator["segments"] == []


def test_split_counts_apply_after_segmentation(recording):
    _, _, log = recording
    with pytest.raises(ValueError, match=r"0.8,0.1,0.1'.*5 jumps divide as 4 train, 1 val, 0 test.*test split"):
        import_logs([log], robot="go1", split="0.8,0.1,0.1")


# ----------------------------------------------------------------- differentiation in seconds

def test_the_differentiation_window_is_set_in_seconds(tmp_path):
    assert diff_samples(0.018, 0.002) == 9 and diff_samples(0.018, 0.001) == 19
    assert diff_samples(0.018, 0.00116) == 15 and diff_samples(0.001, 0.002) == 3
    m = jump(sim_go1(), 0)
    slow, _ = import_logs([write_plain(tmp_path / "500.csv", [m], accelerations=False)], robot="go1")
    np.testing.assert_array_equal(slow.ddq, differentiate(m["dq"], 0.002, slow.jump, "savgol", window=9))
    fast_m = at_times(m, np.arange(int(m["t"][-1] / 0.001) + 1) * 0.001)
    fast, _ = import_logs([write_plain(tmp_path / "1k.csv", [fast_m], accelerations=False)], robot="go1")
    assert fast.dt == 0.001
    np.testing.assert_array_equal(fast.ddq, differentiate(fast_m["dq"], 0.001, fast.jump, "savgol", window=19))
    # the same 18 ms at both rates: the two estimates agree on the shared instants far better
    # than a 9-sample window at 1 kHz (9 ms) would
    same = np.abs(fast.ddq[::2][:slow.n_samples] - slow.ddq[:fast.ddq[::2].shape[0]])
    nine = differentiate(fast_m["dq"], 0.001, fast.jump, "savgol", window=9)
    assert np.median(same) < np.median(np.abs(nine[::2][:slow.n_samples] - slow.ddq[:nine[::2].shape[0]]))
    with pytest.raises(ValueError, match="diff_window=0"):
        import_logs([tmp_path / "500.csv"], robot="go1", diff_window=0)
