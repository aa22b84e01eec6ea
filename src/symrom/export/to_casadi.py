"""The CasADi export: the model as ``casadi.Function`` objects, with their Jacobians.

Built from the model's tables (``symrom.export.tables``); the planner
(``symrom.plan.dynamics``) takes its per-phase dynamics from here, and ``write``
saves every function in CasADi's own format (``casadi.Function.load`` reads it).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import sympy

from symrom.atomic import write_text_atomic
from symrom.export.tables import ExportTables

PREFIX = "symrom_model"


def _casadi():
    try:
        import casadi as ca
    except ImportError:
        raise ImportError("the CasADi export needs casadi: pip install 'symrom[export]'") from None
    return ca


def functions(t: ExportTables) -> dict:
    """``{name: casadi.Function}``, every one taking the latent state as s = [xi, dxi] (2l):
    ``dynamics`` (s, nu, phase -> ddxi), ``rk4_step`` (s, nu, phase, h -> s_next), per phase
    ``accel_<phase>`` (s, nu -> ddxi), its Jacobians ``jac_<phase>`` (s, nu -> d ddxi / d s,
    d ddxi / d nu) and ``rk4_step_<phase>`` (s, nu, h -> s_next); ``encode`` (q, dq -> s),
    ``encode_input`` (u -> nu), ``decode`` (s -> q); the guards (``guard_switch`` (s, nu,
    phase, k_in, dt -> phase); ``guard_switch_staged`` (s, nu, phase, k_in, dt, stage -> phase,
    stage), the same along the model's phase sequence, as free prediction switches: stage -1 for
    none, else the place in it, phase0's first place at the start; and one
    ``guard_<source>_<target>`` (s, nu -> g) each) and, for a
    described robot, the input map ``input`` (q, tau, contact, foot_pos -> u) and
    ``input_kinematics`` (q, tau, contact -> u, the feet from the kinematics)."""
    ca = _casadi()
    l = t.latent_dim
    s, nu, h, phase = ca.SX.sym("s", 2 * l), ca.SX.sym("nu", l), ca.SX.sym("h"), ca.SX.sym("phase")
    table = {"sin": ca.sin, "cos": ca.cos, "tan": ca.tan, "exp": ca.exp, "log": ca.log, "sqrt": ca.sqrt,
             "tanh": ca.tanh, "Abs": ca.fabs, "sign": ca.sign, "atan": ca.atan}
    args = [s[i] for i in range(2 * l)] + [nu[i] for i in range(l)]
    fns, per_phase = {}, []

    def rk4(acc):
        def field(z):
            return ca.vertcat(z[l:], acc(z))

        k1 = field(s)
        k2 = field(s + h / 2 * k1)
        k3 = field(s + h / 2 * k2)
        k4 = field(s + h * k3)
        return s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    for k, rows in enumerate(t.dynamics):
        f = sympy.lambdify([*t.state, *t.inputs], list(rows), modules=[table, "math"])
        dd = ca.vertcat(*[ca.SX(v) if not isinstance(v, ca.SX) else v for v in f(*args)])
        name = t.phase_names[k]
        per_phase.append(dd)
        fns[f"accel_{name}"] = acc = ca.Function(f"accel_{name}", [s, nu], [dd], ["s", "nu"], ["ddxi"])
        fns[f"jac_{name}"] = ca.Function(f"jac_{name}", [s, nu], [ca.jacobian(dd, s), ca.jacobian(dd, nu)],
                                         ["s", "nu"], ["d_s", "d_nu"])
        fns[f"rk4_step_{name}"] = ca.Function(f"rk4_step_{name}", [s, nu, h], [rk4(lambda z, a=acc: a(z, nu))],
                                              ["s", "nu", "h"], ["s_next"])
    dyn = per_phase[-1]
    for k in range(len(per_phase) - 2, -1, -1):
        dyn = ca.if_else(phase == k, per_phase[k], dyn)
    fns["dynamics"] = dynamics = ca.Function("dynamics", [s, nu, phase], [dyn], ["s", "nu", "phase"], ["ddxi"])
    fns["rk4_step"] = ca.Function("rk4_step", [s, nu, phase, h], [rk4(lambda z: dynamics(z, nu, phase))],
                                  ["s", "nu", "phase", "h"], ["s_next"])
    q, dq, u = ca.SX.sym("q", 18), ca.SX.sym("dq", 18), ca.SX.sym("u", 18)
    W_e, W_d = ca.DM(t.W_e), ca.DM(t.W_d)
    fns["encode"] = ca.Function("encode", [q, dq], [ca.vertcat(W_e @ q + ca.DM(t.B_e), W_e @ dq)], ["q", "dq"], ["s"])
    fns["encode_input"] = ca.Function("encode_input", [u], [ca.DM(t.input_map.T) @ u], ["u"], ["nu"])
    fns["decode"] = ca.Function("decode", [s], [W_d @ s[:l] + ca.DM(t.B_d)], ["s"], ["q"])
    _guards(t, fns, ca)
    _input_map(t, fns, ca)
    return fns


def _guard_value(g, z, ca):
    """The guard row ``g``'s g(z) as a CasADi expression (a clock, of no terms: its bias, 0)."""
    return g.bias + sum((w * z[c] for c, w in g.terms), ca.SX(0.0))


def _guards(t: ExportTables, fns: dict, ca) -> None:
    """``guard_switch``, ``guard_switch_staged`` and one ``guard_<source>_<target>`` per guard,
    added to ``fns``."""
    l = t.latent_dim
    s, nu = ca.SX.sym("s", 2 * l), ca.SX.sym("nu", l)
    phase, k_in, dt = ca.SX.sym("phase"), ca.SX.sym("k_in"), ca.SX.sym("dt")
    z = ca.vertcat(s, nu)
    best, best_v = phase, ca.SX(-np.inf)
    for g in t.guards:
        v = _guard_value(g, z, ca)
        name = f"guard_{t.phase_names[g.source]}_{t.phase_names[g.target]}"
        fns[name] = ca.Function(name, [s, nu], [v], ["s", "nu"], ["g"])
        fire = ca.logic_and(ca.logic_and(phase == g.source, k_in * dt + t.eps_t >= g.dwell),
                            ca.logic_and(v >= 0, v > best_v))
        best = ca.if_else(fire, g.target, best)
        best_v = ca.if_else(fire, v, best_v)
    fns["guard_switch"] = ca.Function("guard_switch", [s, nu, phase, k_in, dt], [best],
                                      ["s", "nu", "phase", "k_in", "dt"], ["phase_next"])
    # Along the phase sequence: from stage i only guards into a later phase of it fire, and a
    # switch moves to that phase's first place after i (stage -1: no sequence, any guard).
    stage = ca.SX.sym("stage")
    seq = t.sequence
    best, best_v = phase, ca.SX(-np.inf)
    for g in t.guards:
        v = _guard_value(g, z, ca)
        later = ca.SX(0)
        for j, p in enumerate(seq):
            if p == g.target:
                later = ca.logic_or(later, stage < j)
        fire = ca.logic_and(ca.logic_and(phase == g.source, k_in * dt + t.eps_t >= g.dwell),
                            ca.logic_and(ca.logic_and(v >= 0, v > best_v), ca.logic_or(stage < 0, later)))
        best = ca.if_else(fire, g.target, best)
        best_v = ca.if_else(fire, v, best_v)
    moved = ca.SX(-1)
    for j in reversed(range(len(seq))):
        moved = ca.if_else(ca.logic_and(stage < j, best == seq[j]), j, moved)
    stage_next = ca.if_else(stage < 0, -1, ca.if_else(best == phase, stage, moved))
    fns["guard_switch_staged"] = ca.Function("guard_switch_staged", [s, nu, phase, k_in, dt, stage],
                                             [best, stage_next],
                                             ["s", "nu", "phase", "k_in", "dt", "stage"], ["phase_next", "stage_next"])


def _input_map(t: ExportTables, fns: dict, ca) -> None:
    """With the robot's legs, ``input`` and ``input_kinematics`` added to ``fns``."""
    if t.chains is None:
        return
    c = t.chains
    n_el, xyz, rot, axis, col = c.n_el, c.xyz, c.rot, c.axis, c.col
    q, tau, contact, feet = ca.SX.sym("q", 18), ca.SX.sym("tau", 12), ca.SX.sym("contact", 4), ca.SX.sym("foot_pos", 12)
    r, p_, y = q[15], q[16], q[17]
    cr, sr, cp, sp, cy, sy = ca.cos(r), ca.sin(r), ca.cos(p_), ca.sin(p_), ca.cos(y), ca.sin(y)
    R = ca.vertcat(ca.horzcat(cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
                   ca.horzcat(sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
                   ca.horzcat(-sp, cp * sr, cp * cr))
    base = q[12:15]

    def wrench(foot):
        f, m = ca.SX.zeros(3), ca.SX.zeros(3)
        for k in range(4):
            Rk, p = ca.SX.eye(3), ca.SX.zeros(3)
            axes, origins = {}, {}
            for e in range(int(n_el[k])):
                p = p + Rk @ ca.DM(xyz[k, e])
                Rk = Rk @ ca.DM(rot[k, e])
                j = int(col[k, e])
                if j < 0:
                    continue
                u_ = axis[k, e]
                axes[j], origins[j] = Rk @ ca.DM(u_), p
                K = ca.DM([[0, -u_[2], u_[1]], [u_[2], 0, -u_[0]], [-u_[1], u_[0], 0]])
                Rk = Rk @ (ca.DM.eye(3) + ca.sin(q[j]) * K + (1 - ca.cos(q[j])) * (K @ K))
            J = ca.horzcat(*[ca.cross(axes[j], p - origins[j]) for j in range(3 * k, 3 * k + 3)])
            F = R @ (-ca.solve(J.T, tau[3 * k:3 * k + 3])) * contact[k]
            pk = (base + R @ p) if foot is None else foot[3 * k:3 * k + 3]
            f, m = f + F, m + ca.cross(pk - base, F)
        return ca.vertcat(tau, f, m)

    fns["input"] = ca.Function("input", [q, tau, contact, feet], [wrench(feet)],
                               ["q", "tau", "contact", "foot_pos"], ["u"])
    fns["input_kinematics"] = ca.Function("input_kinematics", [q, tau, contact], [wrench(None)],
                                          ["q", "tau", "contact"], ["u"])


def write(t: ExportTables, out: Path) -> list[Path]:
    """Save every function as ``symrom_model_<name>.casadi`` in ``out``, and ``symrom_model_casadi.json``
    naming them (the model's hash, phases, latent dimension, CasADi's version)."""
    ca = _casadi()
    fns = functions(t)
    paths = []
    for name, f in fns.items():
        p = out / f"{PREFIX}_{name}.casadi"
        tmp = p.with_name(f".{p.name}.tmp")
        f.save(str(tmp))
        os.replace(tmp, p)
        paths.append(p)
    meta = out / f"{PREFIX}_casadi.json"
    write_text_atomic(meta, json.dumps({"model_sha256": t.model_sha256, "phase_names": list(t.phase_names),
                                        "latent_dim": t.latent_dim, "casadi": ca.__version__,
                                        "state": "s = [xi, dxi] (2l)",
                                        "functions": {n: f"{PREFIX}_{n}.casadi" for n in fns}}, indent=1))
    return paths + [meta]
