"""The configuration of a generated file: everything that determines its jumps.

``GenerateConfig`` is recorded whole in the file's ``generator`` attribute;
its ``fingerprint`` ties resumed part files to the options that made them.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field
from typing import Any

from symrom.sim.engines.world import WorldConfig
from symrom.sim.generation.checks import JumpChecks

# 2: compiled per-tick arithmetic (the jumps of 1 to rounding, not bitwise); 3: the engine is a
# choice and its true contact forces are logged (PyBullet's jumps bitwise those of 2); 4: feet
# under the hips where straight legs are not plumb (the Laikago's stance), froggy crouches level
# on robots other than the A1, MuJoCo's state read compiled (its jumps those of 3 to ~1e-9); the
# proxy draws joint damping, armature, friction loss, a soft contact and a measured torque, and
# is one robot per file (its hardware constants drawn once from the generation seed, only the
# per-jump effects per jump; its jumps change), the randomized variant (all per jump); the A1's
# and Go1's nominal and noisy PyBullet jumps bitwise those of 3; 5: the MPC's QP solver is a
# choice (``mpc_solver``), DAQP by default in MuJoCo (its pronk jumps change), OSQP in PyBullet
# (its jumps bitwise those of 4); 6: froggy's randomised jumps draw two kinds of push (a quick one and
# a real froggy's long one; its data change), froggy has a hardware-like variant (``proxy``), a drawn
# variant replaces a draw that does not land up to ``runner.DRAWN_ATTEMPTS`` times, and a file may be
# logged with a real robot's log faults (``log_faults``); nominal, noisy and proxy pronk jumps and
# nominal froggy jumps bitwise those of 5; 7: froggy's real-like push (``proxy``) thrusts softer, so
# that its rear feet hold the ground 0.25 s or more, and the randomised long push reaches 0.4 s
# (its proxy and randomised jumps change; every other jump bitwise those of 6)
GENERATOR_VERSION = 7

# The MPC's QP solver when a config names none, per engine. PyBullet keeps OSQP: every PyBullet
# dataset behind the documented results was made with it, and stays reproducible bit for bit.
# MuJoCo takes DAQP: exact, and cheaper per solve (timed in docs/engines.md, "Speed").
MPC_SOLVER = {"pybullet": "osqp", "mujoco": "daqp"}


@dataclass(frozen=True)
class NoiseConfig:
    """Noise of the ``--noise`` variant (standard deviations, SI units).

    Initial configuration: q0_joint rad on the joint angles, q0_xy m on base
    x/y, q0_rp rad on roll/pitch (the base is then put back on the ground).
    Readings (what the controller sees and what is logged): q_joint rad,
    q_base_pos m, q_rpy rad, dq_joint rad/s, dq_base_lin m/s, dq_rpy rad/s.
    External push on the CoM: a constant force ~ N(0, force_std) N per world
    axis, held for force_duration s from a start time uniform in force_start s.
    """

    q0_joint: float = 0.02
    q0_xy: float = 0.005
    q0_rp: float = 0.01
    q_joint: float = 0.002
    q_base_pos: float = 0.002
    q_rpy: float = 0.005
    dq_joint: float = 0.05
    dq_base_lin: float = 0.02
    dq_rpy: float = 0.05
    force_std: tuple[float, float, float] = (15.0, 15.0, 10.0)
    force_duration: float = 0.2
    force_start: tuple[float, float] = (0.2, 1.2)


@dataclass(frozen=True)
class GenerateConfig:
    """Everything that determines a generated file (recorded in its ``generator``).

    robot: a built-in name or the key of a description file (its absolute path,
    ``symrom.robots.robot_key``); motion: a name in ``symrom.motions.MOTIONS``;
    n_jumps; seed; proxy: the motion's hardware-like variant; randomize: its
    domain-randomised variant (``randomized``; not with proxy); noise: the noisy
    variant or None; world, checks: physics and the kept-jump checks;
    max_attempts: tries per jump before generation fails (a drawn variant, proxy or randomized,
    has at least ``runner.DRAWN_ATTEMPTS``: a draw that fails is replaced); engine: the physics engine
    (``symrom.sim.engines.registry.ENGINES``); splits: (train, val, test) jump counts, None for the
    motion's (``generate.split_counts``); mpc_solver: the QP solver of a motion's MPC
    (``symrom.sim.controllers.motion.QP_SOLVERS``: ``osqp`` or ``daqp``; motions without an MPC ignore it),
    None for the engine's (``MPC_SOLVER``), which is what the file records; log_faults: the
    jumps are logged with a real robot's log faults (``symrom.sim.proxy.LogFaults``: a slow or
    wobbling loop, velocities and torques off, a height offset, a contact lag), one robot's
    drawn once from the seed (``runner.log_faults_of``) and applied to each kept jump.
    """

    robot: str
    motion: str
    n_jumps: int
    seed: int = 0
    proxy: bool = False
    noise: NoiseConfig | None = None
    world: WorldConfig = field(default_factory=WorldConfig)
    checks: JumpChecks = field(default_factory=JumpChecks)
    max_attempts: int = 8
    engine: str = "pybullet"
    randomize: bool = False
    splits: tuple[int, int, int] | None = None
    mpc_solver: str | None = None
    log_faults: str | None = None

    def __post_init__(self) -> None:
        if self.mpc_solver is None:  # an unknown engine is refused by ``generate.check_config``
            object.__setattr__(self, "mpc_solver", MPC_SOLVER.get(self.engine, "osqp"))

    @property
    def variant(self) -> str | None:
        """The motion variant the jumps are drawn with: ``proxy``, ``randomized`` or None."""
        return "proxy" if self.proxy else "randomized" if self.randomize else None

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["noise"] = None if self.noise is None else asdict(self.noise)
        if self.log_faults is None:  # the record (and fingerprint) of a file without them, as before
            del d["log_faults"]
        return d

    def fingerprint(self) -> str:
        """Hash of what makes each jump (not the jump count), to match resumed parts."""
        d = self.to_dict()
        d.pop("n_jumps")
        d["version"] = GENERATOR_VERSION
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]
