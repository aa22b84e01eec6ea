"""The Python export: one NumPy-only module, the static runtime fed by the model's tables.

``symrom_model.py`` holds, after a docstring naming the model, the runtime
(``runtime/symrom_runtime.py`` as the package holds it), then the model's tables
and one function per phase (written term by term by sympy's NumPy printer, every
double exact), and binds the runtime's functions to them as the module's own:
``encode``, ``encode_input``, ``decode``, ``accel``, ``rk4_step``,
``guard_switch``, ``predict_path`` and, for a described robot,
``input_from_torques``.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

import sympy
from sympy.printing.numpy import NumPyPrinter

from symrom.atomic import write_text_atomic
from symrom.export.tables import ExportTables

PREFIX = "symrom_model"
RUNTIME = "symrom_runtime.py"


def module_text(t: ExportTables) -> str:
    """The text of ``symrom_model.py``."""
    l = t.latent_dim
    subs = ({v: sympy.Symbol(f"s[{i}]") for i, v in enumerate(t.state)}
            | {v: sympy.Symbol(f"nu[{i}]") for i, v in enumerate(t.inputs)})
    printer = NumPyPrinter({"fully_qualified_modules": True})
    phases = ", ".join(f"{k}: {n}" for k, n in enumerate(t.phase_names))
    head = f'''"""symrom model, exported: encoder, decoder, latent dynamics and one RK4 step (NumPy only).

model sha256: {t.model_sha256}
phases (index: name): {phases}
The latent state is s = [xi ({l}), dxi ({l})]; q and u (18) in symrom's order.
"""

# ---- symrom's runtime (symrom/export/runtime/{RUNTIME}) ----
'''
    guards = [(g.source, g.target, g.dwell, g.bias, [(int(c), float(w)) for c, w in g.terms]) for g in t.guards]
    lines = ["", "", "# ---- the model (generated) ----", f"LATENT_DIM = {l}", f"PHASES = {list(t.phase_names)!r}",
             f"W_E = numpy.array({t.W_e.tolist()!r})", f"B_E = numpy.array({t.B_e.tolist()!r})",
             f"W_D = numpy.array({t.W_d.tolist()!r})", f"B_D = numpy.array({t.B_d.tolist()!r})",
             f"IN_MAP = numpy.array({t.input_map.tolist()!r})", f"LIMIT = numpy.array({t.limit.tolist()!r})",
             f"EPS_T = {t.eps_t!r}",
             "# guards: (source, target, dwell s, bias, [(column of z = [s, nu], weight), ...])",
             f"GUARDS = {guards!r}",
             "# the phases of one jump of the motion, in order (empty: none): free prediction takes each "
             "transition once",
             f"SEQUENCE = {list(t.sequence)!r}"]
    if t.chains is None:
        lines.append("CHAINS = None")
    else:
        c = t.chains
        lines += [f"# The leg chains of robot {c.robot!r} (from its URDF).", f"N_EL = {c.n_el.tolist()!r}",
                  f"K_XYZ = numpy.array({c.xyz.tolist()!r})", f"K_ROT = numpy.array({c.rot.tolist()!r})",
                  f"K_AXIS = numpy.array({c.axis.tolist()!r})", f"K_COL = {c.col.tolist()!r}",
                  "CHAINS = (N_EL, K_XYZ, K_ROT, K_AXIS, K_COL)"]
    for k, rows in enumerate(t.dynamics):
        body = ", ".join(printer.doprint(e.xreplace(subs)) for e in rows)
        lines += ["", "", f"def accel_{k}(s, nu):", f'    """ddxi ({l},) of phase {k}: {t.phase_names[k]}."""',
                  f"    return numpy.array([{body}], dtype=float)"]
    accels = ", ".join(f"accel_{k}" for k in range(len(t.dynamics)))
    lines += ["", "", f"_RUNTIME = Runtime(LATENT_DIM, PHASES, W_E, B_E, W_D, B_D, IN_MAP, [{accels}], LIMIT, EPS_T, "
              "GUARDS, CHAINS, SEQUENCE)",
              "encode, encode_input, decode = _RUNTIME.encode, _RUNTIME.encode_input, _RUNTIME.decode",
              "accel, rk4_step, guard_switch = _RUNTIME.accel, _RUNTIME.rk4_step, _RUNTIME.guard_switch",
              "predict_path = _RUNTIME.predict_path"]
    if t.chains is not None:
        lines.append("input_from_torques = _RUNTIME.input_from_torques")
    return head + files("symrom.export").joinpath("runtime", RUNTIME).read_text() + "\n".join(lines) + "\n"


def write(t: ExportTables, out: Path) -> list[Path]:
    """Write ``symrom_model.py`` into ``out``."""
    path = out / f"{PREFIX}.py"
    write_text_atomic(path, module_text(t))
    return [path]
