"""Generation at scale: checks, splits, determinism across workers, resume, noise, Go1 pronk."""

from __future__ import annotations

import subprocess
import sys

import h5py
import numpy as np
import pytest
from _simdata import N_JUMPS, SEED, config, reference_file, tmp_path

from symrom.data.io import read_dataset
from symrom.robots import get_robot
from symrom.sim.controllers.froggy import MOTION as FROGGY
from symrom.sim.generation import generate as gen
from symrom.sim.generation.checks import JumpChecks, check_jump
from symrom.sim.generation.generate import GenerateConfig, GenerationError, generate, parts_dir, split_counts
from symrom.sim.generation.parts import read_part, write_part


def _same_file(a, b) -> None:
    da, db = read_dataset(a), read_dataset(b)
    for key in ("jump", "t", "q", "dq", "ddq", "tau", "contact", "u", "phase", "foot_pos", "contact_force"):
        np.testing.assert_array_equal(getattr(da, key), getattr(db, key), err_msg=key)
    assert list(da.split) == list(db.split)
    assert da.generator == db.generator


# ---------------------------------------------------------------- fast, no simulation
def test_paper_splits_and_scaling():
    assert split_counts(156, "pronk") == (120, 30, 6)
    assert split_counts(150, "froggy") == (100, 40, 10)
    assert split_counts(15, "pronk", proxy=True) == (12, 2, 1)
    for n in (1, 2, 3, 7, 40, 300):
        for motion, proxy in (("pronk", False), ("froggy", False), ("pronk", True)):
            c = split_counts(n, motion, proxy)
            assert sum(c) == n and c[0] >= 1
    assert split_counts(300, "froggy") == (200, 80, 20)
    for n in (2, 3, 4, 10):  # small sets can still be evaluated (and validated from 3 on)
        for motion, proxy in (("pronk", False), ("froggy", False), ("pronk", True)):
            tr, va, te = split_counts(n, motion, proxy)
            assert tr >= 1 and te >= 1 and (va >= 1 or n < 3)


def test_seeds_are_per_jump_and_attempt():
    a = np.random.default_rng(gen.jump_seed(1, 5, 0)).random()
    assert a == np.random.default_rng(gen.jump_seed(1, 5, 0)).random()
    assert a != np.random.default_rng(gen.jump_seed(1, 5, 1)).random()
    assert a != np.random.default_rng(gen.jump_seed(1, 6, 0)).random()
    assert a != np.random.default_rng(gen.jump_seed(2, 5, 0)).random()


def test_checks_catch_bad_jumps():
    n = 400
    log = {"q": np.zeros((n, 18)), "tau": np.zeros((n, 12)), "contact": np.ones((n, 4), np.uint8),
           "t": np.arange(n) * 0.002}
    log["q"][:, 14] = 0.3
    def reasons():
        return check_jump(log, "a1", 0.002) + FROGGY.check(log, 0.002, JumpChecks())

    bad = reasons()
    assert any("no flight" in b for b in bad) and any("travel" in b for b in bad)
    log["contact"][100:180] = 0  # 0.16 s flight ...
    log["contact"][90:100, :2] = 0  # ... after 0.02 s on the rear feet: too short for froggy
    log["q"][:, 12] = np.linspace(0, 0.3, n)
    log["q"][100:180, 14] = 0.4
    assert reasons() == ["rear-only contact 0.020 s before flight"]
    log["contact"][80:100, :2] = 0  # 0.04 s
    assert reasons() == []
    log["q"][300, 16] = 1.0
    assert any("tilt" in b for b in reasons())
    log["q"][300, 16] = 0.0
    log["tau"][5, 2] = 40.0
    assert any("torque" in b for b in reasons())


def test_bad_requests_fail_clearly(tmp_path, monkeypatch):
    from dataclasses import replace

    from symrom import motions

    with pytest.raises(GenerationError, match="unknown robot 'b2'"):
        generate(GenerateConfig("b2", "pronk", 2), tmp_path / "x.h5")
    with pytest.raises(GenerationError, match="unknown motion 'walk'"):
        generate(GenerateConfig("a1", "walk", 2), tmp_path / "x.h5")
    # every built-in motion offers both variants; a motion registered without the proxy's
    monkeypatch.setitem(motions.MOTIONS, "froggy", replace(motions.MOTIONS["froggy"], variants=("randomized",)))
    with pytest.raises(GenerationError, match=r"proxy=True is not a variant of 'froggy'; motions with it: \['pronk'\]"):
        generate(GenerateConfig("a1", "froggy", 2, proxy=True), tmp_path / "x.h5")
    with pytest.raises(GenerationError, match="at least one jump"):
        generate(GenerateConfig("a1", "froggy", 0), tmp_path / "x.h5")
    (tmp_path / "exists.h5").write_text("x")
    with pytest.raises(GenerationError, match="force=True"):
        generate(GenerateConfig("a1", "froggy", 1), tmp_path / "exists.h5")
    assert not (tmp_path / "x.h5.parts").exists()  # nothing started


def test_part_files_are_plain_npz(tmp_path):
    log = {"t": np.arange(3.0), "q": np.zeros((3, 18)), "dq": np.zeros((3, 18)),
           "tau": np.zeros((3, 12)), "contact": np.ones((3, 4), np.uint8),
           "foot_pos": np.zeros((3, 4, 3)), "contact_force": np.zeros((3, 4, 3))}
    p = tmp_path / "jump_00000.npz"
    write_part(p, log, {"jump": 0, "params": {"a": 1.0}}, "abc")
    with np.load(p, allow_pickle=False) as z:  # loads without pickle
        assert set(z.files) == set(log) | {"meta"}
    back, rec, fp, _ = read_part(p)
    assert fp == "abc" and rec["params"] == {"a": 1.0}
    np.testing.assert_array_equal(back["contact"], log["contact"])


# ---------------------------------------------------------------- simulation
@pytest.mark.slow
def test_froggy_same_seed_same_file_with_two_workers():
    out = tmp_path("froggy_w2.h5")
    calls = []
    generate(config("froggy"), out, workers=2, progress_callback=lambda d, t, i: calls.append((d, t)))
    _same_file(reference_file("froggy"), out)
    assert calls[-1] == (N_JUMPS["froggy"], N_JUMPS["froggy"])
    assert not parts_dir(out).exists()
    with h5py.File(out) as f:
        assert "workers" not in f.attrs["generator"]


@pytest.mark.slow
def test_froggy_interrupted_then_resumed_gives_the_same_file():
    out = tmp_path("froggy_resumed.h5")
    assert generate(config("froggy"), out, stop_after=1) is None
    assert not out.exists() and len(list(parts_dir(out).glob("jump_*.npz"))) == 1
    with pytest.raises(GenerationError, match="resume=True"):
        generate(config("froggy"), out)
    with pytest.raises(GenerationError, match="other options"):
        generate(config("froggy", seed=SEED + 1), out, resume=True)
    seen = []
    generate(config("froggy"), out, resume=True, progress_callback=lambda d, t, i: seen.append(i))
    assert seen[0] == {"resumed": 1}
    _same_file(reference_file("froggy"), out)


@pytest.mark.slow
def test_killed_subprocess_leaves_parts_that_resume(tmp_path):
    # one jump: the process dies with its part written and the file not; the resume builds the
    # file from that part (one with jumps left to run: test_froggy_interrupted_then_resumed_...)
    out = tmp_path / "killed.h5"
    code = ("import sys; from symrom.sim.generation.generate import GenerateConfig, generate; "
            f"generate(GenerateConfig('a1', 'froggy', 1, seed=7), {str(out)!r}, "
            "progress_callback=lambda d, t, i: sys.exit(3) if d == 1 else None)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=300)
    assert r.returncode == 3 and not out.exists()
    assert [p.name for p in parts_dir(out).glob("jump_*.npz")] == ["jump_00000.npz"]
    part = read_part(parts_dir(out) / "jump_00000.npz")[0]
    seen = []
    ds = generate(GenerateConfig("a1", "froggy", 1, seed=7), out, resume=True,
                  progress_callback=lambda d, t, i: seen.append(i))
    assert seen == [{"resumed": 1}] and ds.n_jumps == 1 and read_dataset(out).n_jumps == 1
    np.testing.assert_array_equal(ds.q, part["q"])


@pytest.mark.slow
def test_noise_variant_is_recorded_and_valid():
    # one jump: its record and its start against the clean file's first jump
    ds = generate(config("froggy", n_jumps=1, noise=True), tmp_path("froggy_noise.h5"))
    g = ds.generator
    assert g["config"]["noise"]["force_std"] == [15.0, 15.0, 10.0]
    assert all("push" in r for r in g["jumps"])
    clean = read_dataset(reference_file("froggy"))
    assert not np.array_equal(ds.q[:10], clean.q[:10])  # noisy start and readings


@pytest.mark.slow
def test_go1_pronk_dataset():
    ds = read_dataset(reference_file("pronk"))
    assert ds.robot == "go1" and ds.motion == "pronk" and ds.phase_names == ["contact", "flight"]
    assert ds.dt == 0.002
    limit = np.asarray(get_robot("go1").torque_limit)
    for j, (a, b) in enumerate(ds.jump_bounds()):
        c, q = ds.contact[a:b], ds.q[a:b]
        air = (c.sum(axis=1) == 0).astype(int)
        d = np.diff(np.r_[0, air, 0])
        runs = np.flatnonzero(d == -1) - np.flatnonzero(d == 1)
        assert runs.max() * ds.dt >= 0.12, f"jump {j}: flight"
        assert q[:, 14].max() - q[0, 14] >= 0.05
        yaw = q[0, 17]
        assert np.dot(q[-1, 12:14] - q[0, 12:14], [np.cos(yaw), np.sin(yaw)]) >= 0.1
        assert np.abs(q[:, 15:17]).max() < 0.8 and q[-1, 14] > 0.15
        assert np.all(np.abs(ds.tau[a:b]) <= limit + 1e-9)


# ---------------------------------------------------------------- command line
@pytest.mark.slow
def test_cli_generate_and_show(tmp_path):
    from typer.testing import CliRunner

    from symrom.cli import app

    runner = CliRunner()
    motion, robot = "pronk", "go1"
    out = tmp_path / "cli.h5"
    args = ["generate", "--robot", robot, "--motion", motion, "--jumps", "1", "--out", str(out)]
    r = runner.invoke(app, args)
    assert r.exit_code == 0, r.output
    assert read_dataset(out).n_jumps == 1
    r = runner.invoke(app, args)  # no overwrite without --force: one clear line, no traceback
    assert r.exit_code == 1 and "--force" in r.output and "Traceback" not in r.output
    frames = tmp_path / "frames"
    r = runner.invoke(app, ["show", str(reference_file("froggy")), "--jump", "1", "--out", str(frames),
                            "--frames", "3"])
    assert r.exit_code == 0, r.output
    pngs = sorted(frames.glob("jump_0001_t*.png"))
    assert len(pngs) == 3
    import matplotlib.image as mpimg

    img = mpimg.imread(pngs[1])
    assert img.shape[:2] == (360, 480) and img.std() > 0.01  # a picture, not a blank
    r = runner.invoke(app, ["show", str(reference_file("froggy")), "--jump", "99", "--out",
                            str(tmp_path / "f2")])
    assert r.exit_code == 1 and "jump 99" in r.output


@pytest.mark.slow
def test_pybullet_banner_is_not_printed_by_any_process(tmp_path):
    motion, robot = "pronk", "go1"
    out = tmp_path / "two.h5"
    code = "import sys; from symrom.cli import main; sys.argv[0] = 'symrom'; main()"
    r = subprocess.run([sys.executable, "-c", code, "generate", "--robot", robot, "--motion", motion,
                        "--jumps", "2", "--workers", "2", "--out", str(out)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "pybullet build time" not in r.stdout + r.stderr
    assert read_dataset(out).n_jumps == 2


def test_flight_watch_fails_exactly_when_the_brief_flight_check_does():
    """The runner stops an attempt once FlightWatch fails: only when the whole log would."""
    from symrom.sim.controllers.flight import BRIEF_FLIGHT, FlightWatch, one_main_flight
    from symrom.sim.controllers.pronk import MOTION as PRONK

    rng = np.random.default_rng(0)
    for _ in range(2000):
        n = int(rng.integers(2, 40))
        air = rng.random(n) < rng.uniform(0.1, 0.9)
        contact = np.repeat((~air)[:, None], 4, axis=1).astype(np.uint8)
        watch = FlightWatch()
        seen = [watch.update(c) for c in contact]
        assert seen == sorted(seen)  # once failed, failed for good
        log = {"q": np.zeros((n, 18)), "tau": np.zeros((n, 12)), "contact": contact}
        assert watch.failed == (BRIEF_FLIGHT in one_main_flight(log))
        assert one_main_flight(log) == PRONK.check(log, 0.002, None)  # pronk's own check
        assert isinstance(PRONK.watch(), FlightWatch) and isinstance(FROGGY.watch(), FlightWatch)
