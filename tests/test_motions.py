"""The motion registry: entries, phase rules, plug-ins behind one Controller protocol."""

from __future__ import annotations

import numpy as np
import pytest

from symrom import motions
from symrom.data.phases import label_phases
from symrom.motions import MOTIONS, MotionEntry, UnknownMotionError, contact_flight, get_motion
from symrom.sim.controllers.motion import Controller, load_motion
from symrom.sim.engines.bullet import BulletWorld as World
from symrom.sim.generation.generate import GenerateConfig, split_counts
from symrom.sim.generation.runner import jump_seed, run_checked_jump, run_jump

# Two jumps: 4 feet, rear only (1), none, staggered touch-down (2), 4 feet | 4, none, 3, 4.
CONTACT = np.array([[1, 1, 1, 1], [0, 0, 1, 1], [0, 0, 0, 0], [1, 0, 1, 0], [1, 1, 1, 1],
                    [1, 1, 1, 1], [0, 0, 0, 0], [1, 1, 1, 0], [1, 1, 1, 1]], dtype=np.uint8)
JUMP = np.array([0, 0, 0, 0, 0, 1, 1, 1, 1])


def test_phase_rules_of_the_registered_motions():
    phase, names = label_phases(CONTACT, JUMP, "pronk")
    assert names == ["contact", "flight"] and phase.tolist() == [0, 0, 1, 0, 0, 0, 1, 0, 0]
    phase, names = label_phases(CONTACT, JUMP, "froggy")
    assert names == ["contact", "partial", "flight"]
    assert phase.tolist() == [0, 1, 2, 0, 0, 0, 2, 0, 0]  # partial only before a jump's first flight
    with pytest.raises(UnknownMotionError, match=r"unknown motion 'walk'; known: \['froggy', 'pronk'\]"):
        label_phases(CONTACT, JUMP, "walk")


def test_every_entry_has_a_plugin_with_one_controller_protocol():
    for name, entry in MOTIONS.items():
        assert entry.name == name and get_motion(name) is entry
        assert set(entry.splits) >= {""} and all(sum(s) > 0 for s in entry.splits.values())
        motion = load_motion(name)
        params = motion.sample_params(np.random.default_rng(0), "go1", False)
        assert params.max_time > 0
        with World("go1") as world:
            ctrl = motion.make_controller("go1", params)
            assert isinstance(ctrl, Controller)
            q0 = ctrl.reset(world)
            assert q0.shape == (18,)
            world.reset(q0)
            s = world.state()
            assert ctrl.torque(s).shape == (12,) and not ctrl.done(s)
            assert isinstance(ctrl.diagnostics(), dict)
        assert motion.source(params) == "sim"
    assert split_counts(156, "pronk") == (120, 30, 6) and split_counts(15, "pronk", True) == (12, 2, 1)


@pytest.fixture()
def toy(monkeypatch):
    """A new motion: one plug-in file (tests/_toy_motion.py) plus one registry entry."""
    entry = MotionEntry("stand", ("contact", "flight"), contact_flight, splits={"": (2, 1, 1)},
                        plugin="_toy_motion:MOTION")
    monkeypatch.setitem(motions.MOTIONS, "stand", entry)
    return entry


def test_a_new_motion_is_an_entry_and_a_plugin(toy):
    cfg = GenerateConfig("go1", "stand", 4, seed=1)
    log, info = run_jump(cfg, jump_seed(1, 0, 0))
    assert info["finished"] and info["diagnostics"] == {"ticks": 20} and info["source"] == "sim"
    assert 150.0 <= info["params"]["stiffness"] <= 250.0
    assert log["q"].shape == (10, 18) and log["contact"].all()
    assert split_counts(4, "stand") == (2, 1, 1)
    assert label_phases(CONTACT, JUMP, "stand")[1] == ["contact", "flight"]
    with pytest.raises(RuntimeError, match="jump 0: no valid jump in 2 attempts .*no flight"):
        run_checked_jump(GenerateConfig("go1", "stand", 1, max_attempts=2), 0)  # common checks apply
