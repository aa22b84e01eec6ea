"""The C export: the model's tables and per-phase dynamics, generated, with the static runtime.

Four files: ``symrom_model.h`` (the model's sizes and names, then the runtime's
declarations), ``symrom_model.c`` (the tables as ``static const`` arrays and one
function per phase, written term by term by sympy's C printer, every double
exact; it includes the runtime, so it is the one file to compile) and the
runtime ``symrom_runtime.h``, ``symrom_runtime.c`` as the package holds them
(``runtime/``). C99 and math.h only; clean under ``-std=c99 -Wall -Wextra
-pedantic``.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

import numpy as np
import sympy

from symrom.atomic import write_text_atomic
from symrom.export.tables import ExportTables

PREFIX = "symrom_model"
RUNTIME = ("symrom_runtime.h", "symrom_runtime.c")


def runtime_text(name: str) -> str:
    """The text of one of the package's runtime files (``runtime/``)."""
    return files("symrom.export").joinpath("runtime", name).read_text()


def _init(a) -> str:
    """A C initializer of an array, rows in braces, every double exact (repr), integers as such."""
    a = np.asarray(a)
    if a.ndim == 1:
        return "{" + ", ".join(repr(float(v)) if a.dtype.kind == "f" else str(int(v)) for v in a) + "}"
    return "{" + ", ".join(_init(r) for r in a) + "}"


def _array(ctype: str, name: str, a) -> str:
    dims = "".join(f"[{n}]" for n in np.shape(a))
    return f"static const {ctype} {name}{dims} = {_init(a)};"


def header(t: ExportTables) -> str:
    """``symrom_model.h``: the model's hash, phases and sizes, then the runtime's declarations."""
    phases = ", ".join(f"{k}: {n}" for k, n in enumerate(t.phase_names))
    return f"""/* symrom model, exported: the encoder, the decoder and the latent dynamics.
 * model sha256: {t.model_sha256}
 * latent dimension: {t.latent_dim}; phases (index: name): {phases}
 * q (18): fr_hx fr_hy fr_kn fl_... rl_kn, x y z (m), roll pitch yaw (rad); u (18): joint torques (N m)
 * then the CoM wrench (N, N m). The latent state is s = [xi (l), dxi (l)].
 * Compile symrom_model.c (it includes the runtime, symrom_runtime.c); the functions are declared
 * in symrom_runtime.h. */
#ifndef SYMROM_MODEL_H
#define SYMROM_MODEL_H
#define SYMROM_LATENT_DIM {t.latent_dim}
#define SYMROM_N_PHASES {len(t.phase_names)}
#define SYMROM_MODEL_SHA256 "{t.model_sha256}"
#define SYMROM_PHASES "{", ".join(t.phase_names)}"
#define SYMROM_N_GUARDS {len(t.guards)}
#define SYMROM_N_SEQUENCE {len(t.sequence)} /* phases of one jump of the motion (0: no sequence) */
#define SYMROM_HAS_INPUT_MAP {int(t.chains is not None)}
#define SYMROM_EPS_T {t.eps_t!r} /* s, rounding allowance of the guards' dwell test */
#include "symrom_runtime.h"
#endif
"""


def _guards(t: ExportTables) -> list[str]:
    """The guard tables: at least one row (C has no empty arrays), rows padded to K terms."""
    G, K = max(len(t.guards), 1), max([1] + [len(g.terms) for g in t.guards])
    col, weight = np.zeros((G, K), dtype=np.int64), np.zeros((G, K))
    source, target, n_terms = (np.zeros(G, dtype=np.int64) for _ in range(3))
    dwell, bias = np.zeros(G), np.zeros(G)
    for i, g in enumerate(t.guards):
        source[i], target[i], n_terms[i], dwell[i], bias[i] = g.source, g.target, len(g.terms), g.dwell, g.bias
        for k, (c, w) in enumerate(g.terms):
            col[i, k], weight[i, k] = c, w
    names = "; ".join(f"{i}: {t.phase_names[g.source]} -> {t.phase_names[g.target]}" for i, g in enumerate(t.guards))
    return [f"/* The guards ({names or 'none; one row of zeros'}). */",
            _array("int", "GUARD_SOURCE", source), _array("int", "GUARD_TARGET", target),
            _array("int", "GUARD_N_TERMS", n_terms), _array("double", "GUARD_DWELL", dwell),
            _array("double", "GUARD_BIAS", bias), _array("int", "GUARD_COL", col),
            _array("double", "GUARD_WEIGHT", weight),
            "/* The phases of one jump of the motion, in order (" + (", ".join(t.phase_names[k] for k in t.sequence)
            or "none; one entry, unused") + "): free prediction takes each transition once. */",
            _array("int", "SEQUENCE", np.array(t.sequence or (0,), dtype=np.int64))]


def source(t: ExportTables) -> str:
    """``symrom_model.c``: the tables, the per-phase dynamics, then the runtime (included)."""
    l = t.latent_dim
    subs = ({v: sympy.Symbol(f"s[{i}]") for i, v in enumerate(t.state)}
            | {v: sympy.Symbol(f"nu[{i}]") for i, v in enumerate(t.inputs)})
    lines = [f"/* symrom model sha256: {t.model_sha256}; phases: {', '.join(t.phase_names)} */",
             "#include <math.h>", f'#include "{PREFIX}.h"', "",
             _array("double", "W_E", t.W_e), _array("double", "B_E", t.B_e), _array("double", "W_D", t.W_d),
             _array("double", "B_D", t.B_d), _array("double", "IN_MAP", t.input_map),
             _array("double", "SYMROM_LIMIT", t.limit), "", *_guards(t), ""]
    for k, rows in enumerate(t.dynamics):
        lines.append(f"/* ddxi of phase {k}: {t.phase_names[k]} */")
        lines.append(f"static void accel_{k}(const double s[{2 * l}], const double nu[{l}], double ddxi[{l}]) {{")
        lines.append("    (void)s; (void)nu;  /* a phase's terms may read neither */")
        lines += [f"    ddxi[{j}] = {sympy.ccode(e.xreplace(subs))};" for j, e in enumerate(rows)]
        lines.append("}")
    lines.append("typedef void (*symrom_accel_fn)(const double *s, const double *nu, double *ddxi);")
    lines.append(f"static const symrom_accel_fn ACCEL_PHASE[{len(t.dynamics)}] = "
                 f"{{{', '.join(f'accel_{k}' for k in range(len(t.dynamics)))}}};")
    if t.chains is not None:
        c = t.chains
        lines += ["", f"/* The leg chains of robot {c.robot!r} (from its URDF). */",
                  _array("int", "N_EL", c.n_el), _array("double", "K_XYZ", c.xyz), _array("double", "K_ROT", c.rot),
                  _array("double", "K_AXIS", c.axis), _array("int", "K_COL", c.col)]
    lines += ["", '#include "symrom_runtime.c"', ""]
    return "\n".join(lines)


def write(t: ExportTables, out: Path) -> list[Path]:
    """Write the C export into ``out``: the header, the model's source, the runtime's two files."""
    paths = [out / f"{PREFIX}.h", out / f"{PREFIX}.c"] + [out / name for name in RUNTIME]
    for path, text in zip(paths, [header(t), source(t)] + [runtime_text(name) for name in RUNTIME]):
        write_text_atomic(path, text)
    return paths
