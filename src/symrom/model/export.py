"""Models outside Python: standalone C, a CasADi function with its Jacobians, plain Python.

Every export holds the whole model: the encoder (xi = W_e q + B_e, dxi = W_e
dq, nu = pinv(W_e^T) u), the decoder (q = W_d xi + B_d), every phase's latent
dynamics ddxi = f_k(xi, dxi, nu) written out term by term from the sympy form
of the library (full double precision, only the active terms), and one
classical Runge-Kutta step of the latent state with the input and the phase
held, as the rollouts do; the learned contact guards, free prediction from
(q0, dq0) with an input sequence (the schedule given or the guards deciding,
as ``HybridModel.predict_path``), and, for a model of a described robot, the
input map from joint torques and feet to u (``symrom.model.export_io``). Each
file states the model's hash (SHA-256 of its model file's content) and its
phase names; phase k is the k-th name. Every function takes the latent state
as one vector s = [xi, dxi] (2l) and the inputs as nu (l).

- ``c``: ``symrom_model.h`` and ``symrom_model.c`` (C99, math.h only), from
  sympy's C printer;
- ``casadi``: one ``symrom_model_<name>.casadi`` per ``casadi.Function``
  (``casadi_functions``: ``dynamics(s, nu, phase) -> ddxi``, ``rk4_step(s, nu,
  phase, h)``, the per-phase functions and their Jacobians, the guards, the
  input map), written with CasADi's own format (``casadi.Function.load``);
- ``python``: ``symrom_model.py``, NumPy only.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import sympy

from symrom.atomic import write_text_atomic
from symrom.model.export_io import c_declarations, c_source, casadi_extras, python_source, robot_chains
from symrom.model.expressions import latent_expressions
from symrom.model.hybrid import HybridModel
from symrom.model.library import symbols
from symrom.model.persistence import model_hash
from symrom.rollout.integrate import RolloutOptions

TARGETS = ("c", "casadi", "python")
PREFIX = "symrom_model"
BOUND = RolloutOptions.bound  # divergence bound of the exported predict_path, x the model's yardstick


def export(model: HybridModel, target: str, out: str | os.PathLike) -> list[Path]:
    """Write the export of ``model`` for ``target`` into directory ``out``; the paths written."""
    if target not in TARGETS:
        raise ValueError(f"unknown export target {target!r}; choose from {TARGETS}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    return {"c": _export_c, "casadi": _export_casadi, "python": _export_python}[target](model, out)


# ------------------------------------------------------------------ C
def _c_init(a: np.ndarray) -> str:
    """A C initializer of a 1-D or 2-D array, rows in braces, every double exact (repr)."""
    a = np.asarray(a, dtype=float)
    if a.ndim == 1:
        return "{" + ", ".join(repr(float(v)) for v in a) + "}"
    return "{" + ", ".join(_c_init(row) for row in a) + "}"


def _c_array(name: str, a: np.ndarray) -> str:
    dims = "".join(f"[{n}]" for n in np.shape(a))
    return f"static const double {name}{dims} = {_c_init(a)};"


def _export_c(model: HybridModel, out: Path) -> list[Path]:
    l, P = model.latent_dim, len(model.phase_names)
    ae = model.autoencoder
    s, nu = symbols(l)
    subs = {v: sympy.Symbol(f"s[{i}]") for i, v in enumerate(s)} | {v: sympy.Symbol(f"nu[{i}]") for i, v in enumerate(nu)}
    digest = model_hash(model)
    names = ", ".join(model.phase_names)
    header = f"""/* symrom model, exported: the encoder, the decoder and the latent dynamics.
 * model sha256: {digest}
 * latent dimension: {l}; phases (index: name): {", ".join(f"{k}: {n}" for k, n in enumerate(model.phase_names))}
 * q (18): fr_hx fr_hy fr_kn fl_... rl_kn, x y z (m), roll pitch yaw (rad); u (18): joint torques (N m)
 * then the CoM wrench (N, N m). The latent state is s = [xi (l), dxi (l)]. */
#ifndef SYMROM_MODEL_H
#define SYMROM_MODEL_H
#define SYMROM_LATENT_DIM {l}
#define SYMROM_N_PHASES {P}
#define SYMROM_MODEL_SHA256 "{digest}"
#define SYMROM_PHASES "{names}"
#define SYMROM_N_GUARDS {len(model.guards or [])}
#define SYMROM_HAS_INPUT_MAP {int(robot_chains(model) is not None)}
void symrom_encode(const double q[18], const double dq[18], double s[2 * SYMROM_LATENT_DIM]);
void symrom_encode_input(const double u[18], double nu[SYMROM_LATENT_DIM]);
void symrom_decode(const double s[2 * SYMROM_LATENT_DIM], double q[18]);
/* ddxi (l) of phase `phase` (0 .. SYMROM_N_PHASES - 1); returns -1 for an unknown phase. */
int symrom_accel(int phase, const double s[2 * SYMROM_LATENT_DIM], const double nu[SYMROM_LATENT_DIM],
                 double ddxi[SYMROM_LATENT_DIM]);
/* One classical Runge-Kutta step of length h (s) of s in place, nu and phase held. */
int symrom_rk4_step(int phase, double s[2 * SYMROM_LATENT_DIM], const double nu[SYMROM_LATENT_DIM], double h);
{c_declarations()}#endif
"""
    cases = []
    for k, rows in enumerate(latent_expressions(model.library, model.Xi)):
        body = "\n".join(f"        ddxi[{j}] = {sympy.ccode(e.xreplace(subs))};" for j, e in enumerate(rows))
        cases.append(f"    case {k}: /* {model.phase_names[k]} */\n{body}\n        return 0;")
    source = f"""/* symrom model sha256: {digest}; phases: {names} */
#include <math.h>
#include "{PREFIX}.h"
#define L SYMROM_LATENT_DIM
{_c_array("W_E", ae.W_e)}
{_c_array("B_E", ae.B_e)}
{_c_array("W_D", ae.W_d)}
{_c_array("B_D", ae.B_d)}
{_c_array("IN_MAP", ae.input_map)}

void symrom_encode(const double q[18], const double dq[18], double s[2 * L]) {{
    for (int i = 0; i < L; i++) {{
        double a = B_E[i], b = 0.0;
        for (int c = 0; c < 18; c++) {{ a += W_E[i][c] * q[c]; b += W_E[i][c] * dq[c]; }}
        s[i] = a; s[L + i] = b;
    }}
}}

void symrom_encode_input(const double u[18], double nu[L]) {{
    for (int i = 0; i < L; i++) {{
        double a = 0.0;
        for (int c = 0; c < 18; c++) a += u[c] * IN_MAP[c][i];
        nu[i] = a;
    }}
}}

void symrom_decode(const double s[2 * L], double q[18]) {{
    for (int c = 0; c < 18; c++) {{
        double a = B_D[c];
        for (int i = 0; i < L; i++) a += W_D[c][i] * s[i];
        q[c] = a;
    }}
}}

int symrom_accel(int phase, const double s[2 * L], const double nu[L], double ddxi[L]) {{
    (void)nu;
    switch (phase) {{
{chr(10).join(cases)}
    default:
        return -1;
    }}
}}

static int field(int phase, const double s[2 * L], const double nu[L], double ds[2 * L]) {{
    for (int i = 0; i < L; i++) ds[i] = s[L + i];
    return symrom_accel(phase, s, nu, ds + L);
}}

int symrom_rk4_step(int phase, double s[2 * L], const double nu[L], double h) {{
    double k1[2 * L], k2[2 * L], k3[2 * L], k4[2 * L], t[2 * L];
    if (field(phase, s, nu, k1)) return -1;
    for (int i = 0; i < 2 * L; i++) t[i] = s[i] + 0.5 * h * k1[i];
    field(phase, t, nu, k2);
    for (int i = 0; i < 2 * L; i++) t[i] = s[i] + 0.5 * h * k2[i];
    field(phase, t, nu, k3);
    for (int i = 0; i < 2 * L; i++) t[i] = s[i] + h * k3[i];
    field(phase, t, nu, k4);
    for (int i = 0; i < 2 * L; i++) s[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    return 0;
}}
{c_source(model, BOUND)}"""
    paths = [out / f"{PREFIX}.h", out / f"{PREFIX}.c"]
    write_text_atomic(paths[0], header)
    write_text_atomic(paths[1], source)
    return paths


# ------------------------------------------------------------------ CasADi
def casadi_functions(model: HybridModel):
    """``{name: casadi.Function}``, every one taking the latent state as s = [xi, dxi] (2l):
    ``dynamics`` (s, nu, phase -> ddxi), ``rk4_step`` (s, nu, phase, h -> s_next), per phase
    ``accel_<phase>`` (s, nu -> ddxi), its Jacobians ``jac_<phase>`` (s, nu -> d ddxi / d s,
    d ddxi / d nu) and ``rk4_step_<phase>`` (s, nu, h -> s_next); ``encode`` (q, dq -> s),
    ``encode_input`` (u -> nu), ``decode`` (s -> q); the guards (``guard_switch`` and one
    ``guard_<source>_<target>`` each) and, for a described robot, the input map ``input`` and
    ``input_kinematics`` (``symrom.model.export_io.casadi_extras``)."""
    try:
        import casadi as ca
    except ImportError:
        raise ImportError("the CasADi export needs casadi: pip install 'symrom[export]'") from None
    l = model.latent_dim
    ae = model.autoencoder
    s, nu, h, phase = ca.SX.sym("s", 2 * l), ca.SX.sym("nu", l), ca.SX.sym("h"), ca.SX.sym("phase")
    s_sym, nu_sym = symbols(l)
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

    for k, rows in enumerate(latent_expressions(model.library, model.Xi)):
        f = sympy.lambdify([*s_sym, *nu_sym], rows, modules=[table, "math"])
        dd = ca.vertcat(*[ca.SX(v) if not isinstance(v, ca.SX) else v for v in f(*args)])
        name = model.phase_names[k]
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
    W_e, W_d = ca.DM(ae.W_e), ca.DM(ae.W_d)
    fns["encode"] = ca.Function("encode", [q, dq], [ca.vertcat(W_e @ q + ca.DM(ae.B_e), W_e @ dq)], ["q", "dq"], ["s"])
    fns["encode_input"] = ca.Function("encode_input", [u], [ca.DM(ae.input_map.T) @ u], ["u"], ["nu"])
    fns["decode"] = ca.Function("decode", [s], [W_d @ s[:l] + ca.DM(ae.B_d)], ["s"], ["q"])
    casadi_extras(model, fns, ca)
    return fns


def _export_casadi(model: HybridModel, out: Path) -> list[Path]:
    import casadi as ca

    fns = casadi_functions(model)
    paths = []
    for name, f in fns.items():
        p = out / f"{PREFIX}_{name}.casadi"
        tmp = p.with_name(f".{p.name}.tmp")
        f.save(str(tmp))
        os.replace(tmp, p)
        paths.append(p)
    meta = out / f"{PREFIX}_casadi.json"
    write_text_atomic(meta, json.dumps({"model_sha256": model_hash(model), "phase_names": model.phase_names,
                                        "latent_dim": model.latent_dim, "casadi": ca.__version__,
                                        "state": "s = [xi, dxi] (2l)",
                                        "functions": {n: f"{PREFIX}_{n}.casadi" for n in fns}}, indent=1))
    return paths + [meta]


# ------------------------------------------------------------------ Python
def _export_python(model: HybridModel, out: Path) -> list[Path]:
    from sympy.printing.numpy import NumPyPrinter

    l = model.latent_dim
    ae = model.autoencoder
    s, nu = symbols(l)
    subs = {v: sympy.Symbol(f"s[{i}]") for i, v in enumerate(s)} | {v: sympy.Symbol(f"nu[{i}]") for i, v in enumerate(nu)}
    printer = NumPyPrinter({"fully_qualified_modules": True})
    cases = []
    for k, rows in enumerate(latent_expressions(model.library, model.Xi)):
        body = ", ".join(printer.doprint(e.xreplace(subs)) for e in rows)
        cases.append(f"    if phase == {k}:  # {model.phase_names[k]}\n        return numpy.array([{body}], dtype=float)")
    text = f'''"""symrom model, exported: encoder, decoder, latent dynamics and one RK4 step (NumPy only).

model sha256: {model_hash(model)}
phases (index: name): {", ".join(f"{k}: {n}" for k, n in enumerate(model.phase_names))}
The latent state is s = [xi ({l}), dxi ({l})]; q and u (18) in symrom's order.
"""

import numpy

LATENT_DIM = {l}
PHASES = {list(model.phase_names)!r}
W_E = numpy.array({ae.W_e.tolist()!r})
B_E = numpy.array({ae.B_e.tolist()!r})
W_D = numpy.array({ae.W_d.tolist()!r})
B_D = numpy.array({ae.B_d.tolist()!r})
IN_MAP = numpy.array({ae.input_map.tolist()!r})


def encode(q, dq):
    """q, dq (18,) -> s (2l,)."""
    return numpy.concatenate([W_E @ q + B_E, W_E @ dq])


def encode_input(u):
    """u (18,) -> nu (l,)."""
    return u @ IN_MAP


def decode(s):
    """s (2l,) (or xi (l,)) -> q (18,)."""
    return W_D @ s[:LATENT_DIM] + B_D


def accel(phase, s, nu):
    """ddxi (l,) in phase index ``phase``."""
{chr(10).join(cases)}
    raise ValueError(f"unknown phase {{phase}}; phases are 0..{{len(PHASES) - 1}}")


def rk4_step(phase, s, nu, h):
    """s after one classical Runge-Kutta step of h s, nu and phase held."""
    def field(z):
        return numpy.concatenate([z[LATENT_DIM:], accel(phase, z, nu)])

    k1 = field(s)
    k2 = field(s + h / 2 * k1)
    k3 = field(s + h / 2 * k2)
    k4 = field(s + h * k3)
    return s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
''' + python_source(model, BOUND)
    path = out / f"{PREFIX}.py"
    write_text_atomic(path, text)
    return [path]
