"""What the exports add around the dynamics: the input map, the guards and free prediction.

The input map is ``symrom.data.preprocess.input_from_torques`` written out for
each target: the leg chains of the model's robot (``LegKinematics.chain_arrays``:
fixed origin transforms, revolute joints by Rodrigues' formula) give the feet
and the leg Jacobians J_k (base frame); per foot in contact the ground force
is F_k = R (-(J_k^T)^-1 tau_k), R the base orientation (ZYX Euler angles); and
u = [tau, sum F_k, sum (p_k - b) x F_k] with b the base position and p_k the
foot (given, or b + R p_k(base frame) from the kinematics). A model whose
robot has no description (planted data) is exported without it.

The guards are written term by term, in the order ``Guard.value`` sums them,
and the dwell test is ``guards.dwell_ok``'s, so that a switch falls on the same
sample in every target.
"""

from __future__ import annotations

import numpy as np

from symrom.model.guards import EPS_T
from symrom.model.hybrid import HybridModel


def robot_chains(model: HybridModel) -> tuple[np.ndarray, ...] | None:
    """The leg chains of the model's robot (``LegKinematics.chain_arrays``), or None if the
    model records no robot with a description."""
    from symrom.robots import RobotDescriptionError, leg_kinematics

    robot = model.provenance.data.robot
    if robot is None:
        return None
    try:
        return leg_kinematics(robot).chain_arrays()
    except (RobotDescriptionError, FileNotFoundError, KeyError):
        return None


def guard_terms(model: HybridModel) -> list[tuple[int, int, float, float, list[tuple[int, float]]]]:
    """Per guard: (source index, target index, dwell s, bias, [(column of z, weight)])."""
    l, names = model.latent_dim, model.phase_names
    return [(names.index(g.source), names.index(g.target), float(g.min_dwell_s), float(g.bias),
             list(zip(g.indices(l).tolist(), g.weights.tolist()))) for g in model.guards or []]


# ------------------------------------------------------------------ C
def c_declarations() -> str:
    return """/* The phase after sample s, nu in `phase`, entered k_in samples (dt s each) ago: the target of the
 * firing guard with the largest value, else `phase`. */
int symrom_guard_switch(int phase, int k_in, double dt, const double s[2 * SYMROM_LATENT_DIM],
                        const double nu[SYMROM_LATENT_DIM]);
/* Predict n samples every dt s from q0, dq0 (18) with inputs u (n x 18, row-major) held over each
 * sample, substeps RK4 steps per sample. predict_phases 0: phases (n) is the schedule (read);
 * 1: the guards decide from phase0, entered at sample 0, and phases (n) receives them. q, dq
 * (n x 18) receive the path, NaN from a divergence (|s_i| beyond SYMROM_LIMIT[i]). Returns the
 * first diverged sample, -1 if none, -2 for an unknown phase in the schedule. */
int symrom_predict_path(int n, double dt, int substeps, const double q0[18], const double dq0[18],
                        const double *u, int predict_phases, int phase0, int *phases, double *q, double *dq);
#if SYMROM_HAS_INPUT_MAP
/* The input map: u (18) from q (18), joint torques tau (12) N m, contact flags (4, nonzero: in
 * contact) and the feet foot_pos (4 x 3, world, m; NULL: from the robot's kinematics). Returns 0,
 * or -1 if a leg in contact is singular. */
int symrom_input(const double q[18], const double tau[12], const int contact[4], const double *foot_pos,
                 double u[18]);
#endif
"""


def _c_init(a) -> str:
    a = np.asarray(a)
    if a.ndim == 1:
        return "{" + ", ".join(repr(float(v)) if a.dtype.kind == "f" else str(int(v)) for v in a) + "}"
    return "{" + ", ".join(_c_init(r) for r in a) + "}"


def c_source(model: HybridModel, bound: float) -> str:
    """C of the guards, free prediction and (with a robot) the input map; after the dynamics."""
    l = model.latent_dim
    limit = bound * model.yardstick
    cases = []
    for i, (src, tgt, dwell, bias, terms) in enumerate(guard_terms(model)):
        sum_ = " + ".join(f"{w!r} * z[{c}]" for c, w in terms)
        cases.append(f"    if (phase == {src} && k_in * dt + {EPS_T!r} >= {dwell!r}) {{  /* {model.phase_names[src]} -> "
                     f"{model.phase_names[tgt]} */\n        v = {bias!r} + ({sum_});\n"
                     f"        if (v >= 0.0 && v > best_v) {{ best = {tgt}; best_v = v; }}\n    }}")
    text = f"""
static const double SYMROM_LIMIT[2 * L] = {_c_init(limit)};

int symrom_guard_switch(int phase, int k_in, double dt, const double s[2 * L], const double nu[L]) {{
    double z[3 * L], v, best_v = -INFINITY;
    int best = phase;
    (void)v; (void)k_in; (void)dt;
    for (int i = 0; i < 2 * L; i++) z[i] = s[i];
    for (int i = 0; i < L; i++) z[2 * L + i] = nu[i];
{chr(10).join(cases)}
    return best;
}}

int symrom_predict_path(int n, double dt, int substeps, const double q0[18], const double dq0[18],
                        const double *u, int predict_phases, int phase0, int *phases, double *q, double *dq) {{
    double s[2 * L], nu[L];
    int phase = phase0, k_enter = 0, div = -1;
    symrom_encode(q0, dq0, s);
    for (int k = 0; k < n; k++) {{
        int ok = 1;
        for (int i = 0; i < 2 * L; i++) if (!(fabs(s[i]) <= SYMROM_LIMIT[i])) ok = 0;
        if (!ok) {{ div = k; break; }}
        symrom_decode(s, q + 18 * k);
        for (int c = 0; c < 18; c++) {{
            double a = 0.0;
            for (int i = 0; i < L; i++) a += W_D[c][i] * s[L + i];
            dq[18 * k + c] = a;
        }}
        symrom_encode_input(u + 18 * k, nu);
        if (predict_phases) {{
            int next = symrom_guard_switch(phase, k - k_enter, dt, s, nu);
            if (next != phase) {{ phase = next; k_enter = k; }}
            phases[k] = phase;
        }} else {{
            phase = phases[k];
            if (phase < 0 || phase >= SYMROM_N_PHASES) return -2;
        }}
        if (k == n - 1) break;
        for (int r = 0; r < substeps; r++) symrom_rk4_step(phase, s, nu, dt / substeps);
    }}
    if (div >= 0) {{
        for (int k = div; k < n; k++) {{
            for (int c = 0; c < 18; c++) q[18 * k + c] = dq[18 * k + c] = NAN;
            if (predict_phases) phases[k] = phase;
        }}
    }}
    return div;
}}
"""
    chains = robot_chains(model)
    if chains is None:
        return text
    n_el, xyz, rot, axis, col = chains
    E = xyz.shape[1]
    return text + f"""
/* The leg chains of robot {model.provenance.data.robot!r} (from its URDF). */
static const int N_EL[4] = {_c_init(n_el)};
static const double K_XYZ[4][{E}][3] = {_c_init(xyz)};
static const double K_ROT[4][{E}][3][3] = {_c_init(rot)};
static const double K_AXIS[4][{E}][3] = {_c_init(axis)};
static const int K_COL[4][{E}] = {_c_init(col)};

/* Feet (base frame, m) and leg Jacobians d foot / d q_leg (base frame) of joint angles qj (12). */
static void legs(const double qj[12], double pos[4][3], double J[4][3][3]) {{
    for (int k = 0; k < 4; k++) {{
        double R[3][3] = {{{{1, 0, 0}}, {{0, 1, 0}}, {{0, 0, 1}}}}, T[3][3], p[3] = {{0, 0, 0}}, ax[3][3], org[3][3];
        for (int e = 0; e < N_EL[k]; e++) {{
            for (int a = 0; a < 3; a++)
                p[a] += R[a][0] * K_XYZ[k][e][0] + R[a][1] * K_XYZ[k][e][1] + R[a][2] * K_XYZ[k][e][2];
            for (int a = 0; a < 3; a++)
                for (int b = 0; b < 3; b++)
                    T[a][b] = R[a][0] * K_ROT[k][e][0][b] + R[a][1] * K_ROT[k][e][1][b] + R[a][2] * K_ROT[k][e][2][b];
            for (int a = 0; a < 3; a++) for (int b = 0; b < 3; b++) R[a][b] = T[a][b];
            int c = K_COL[k][e];
            if (c < 0) continue;
            int j = c - 3 * k;
            double u0 = K_AXIS[k][e][0], u1 = K_AXIS[k][e][1], u2 = K_AXIS[k][e][2];
            for (int a = 0; a < 3; a++) {{
                ax[j][a] = R[a][0] * u0 + R[a][1] * u1 + R[a][2] * u2;
                org[j][a] = p[a];
            }}
            double s = sin(qj[c]), cq = cos(qj[c]), v = 1.0 - cq;
            double G[3][3] = {{{{cq + v * u0 * u0, v * u0 * u1 - s * u2, v * u0 * u2 + s * u1}},
                              {{v * u1 * u0 + s * u2, cq + v * u1 * u1, v * u1 * u2 - s * u0}},
                              {{v * u2 * u0 - s * u1, v * u2 * u1 + s * u0, cq + v * u2 * u2}}}};
            for (int a = 0; a < 3; a++)
                for (int b = 0; b < 3; b++) T[a][b] = R[a][0] * G[0][b] + R[a][1] * G[1][b] + R[a][2] * G[2][b];
            for (int a = 0; a < 3; a++) for (int b = 0; b < 3; b++) R[a][b] = T[a][b];
        }}
        for (int a = 0; a < 3; a++) pos[k][a] = p[a];
        for (int j = 0; j < 3; j++) {{
            double d0 = p[0] - org[j][0], d1 = p[1] - org[j][1], d2 = p[2] - org[j][2];
            J[k][0][j] = ax[j][1] * d2 - ax[j][2] * d1;
            J[k][1][j] = ax[j][2] * d0 - ax[j][0] * d2;
            J[k][2][j] = ax[j][0] * d1 - ax[j][1] * d0;
        }}
    }}
}}

/* x = A^-1 b by Gaussian elimination with partial pivoting; -1 if A is singular. */
static int solve3(const double A_in[3][3], const double b_in[3], double x[3]) {{
    double A[3][4];
    for (int i = 0; i < 3; i++) {{ for (int j = 0; j < 3; j++) A[i][j] = A_in[i][j]; A[i][3] = b_in[i]; }}
    for (int c = 0; c < 3; c++) {{
        int p = c;
        for (int r = c + 1; r < 3; r++) if (fabs(A[r][c]) > fabs(A[p][c])) p = r;
        if (A[p][c] == 0.0) return -1;
        for (int j = 0; j < 4; j++) {{ double t = A[c][j]; A[c][j] = A[p][j]; A[p][j] = t; }}
        for (int r = c + 1; r < 3; r++) {{
            double f = A[r][c] / A[c][c];
            for (int j = c; j < 4; j++) A[r][j] -= f * A[c][j];
        }}
    }}
    for (int i = 2; i >= 0; i--) {{
        double a = A[i][3];
        for (int j = i + 1; j < 3; j++) a -= A[i][j] * x[j];
        x[i] = a / A[i][i];
    }}
    return 0;
}}

int symrom_input(const double q[18], const double tau[12], const int contact[4], const double *foot_pos,
                 double u[18]) {{
    double pos[4][3], J[4][3][3], R[3][3];
    double r = q[15], pi = q[16], y = q[17];
    double cr = cos(r), sr = sin(r), cp = cos(pi), sp = sin(pi), cy = cos(y), sy = sin(y);
    R[0][0] = cy * cp; R[0][1] = cy * sp * sr - sy * cr; R[0][2] = cy * sp * cr + sy * sr;
    R[1][0] = sy * cp; R[1][1] = sy * sp * sr + cy * cr; R[1][2] = sy * sp * cr - cy * sr;
    R[2][0] = -sp; R[2][1] = cp * sr; R[2][2] = cp * cr;
    legs(q, pos, J);
    for (int c = 0; c < 12; c++) u[c] = tau[c];
    for (int c = 12; c < 18; c++) u[c] = 0.0;
    for (int k = 0; k < 4; k++) {{
        double p[3], JT[3][3], x[3], F[3], d[3];
        for (int a = 0; a < 3; a++)
            p[a] = foot_pos ? foot_pos[3 * k + a]
                            : q[12 + a] + R[a][0] * pos[k][0] + R[a][1] * pos[k][1] + R[a][2] * pos[k][2];
        if (!contact[k]) continue;
        for (int a = 0; a < 3; a++) for (int b = 0; b < 3; b++) JT[a][b] = J[k][b][a];
        if (solve3(JT, tau + 3 * k, x)) return -1;
        for (int a = 0; a < 3; a++) F[a] = -(R[a][0] * x[0] + R[a][1] * x[1] + R[a][2] * x[2]);
        for (int a = 0; a < 3; a++) d[a] = p[a] - q[12 + a];
        u[12] += F[0]; u[13] += F[1]; u[14] += F[2];
        u[15] += d[1] * F[2] - d[2] * F[1];
        u[16] += d[2] * F[0] - d[0] * F[2];
        u[17] += d[0] * F[1] - d[1] * F[0];
    }}
    return 0;
}}
"""


# ------------------------------------------------------------------ CasADi
def casadi_extras(model: HybridModel, fns: dict, ca) -> None:
    """Add to the CasADi functions ``fns``: ``guard_switch`` (s, nu, phase, k_in, dt -> phase),
    per guard ``guard_<source>_<target>`` (s, nu -> g), and with a robot ``input``
    (q, tau, contact, foot_pos -> u) and ``input_kinematics`` (q, tau, contact -> u, the feet
    from the kinematics)."""
    l = model.latent_dim
    s, nu = ca.SX.sym("s", 2 * l), ca.SX.sym("nu", l)
    phase, k_in, dt = ca.SX.sym("phase"), ca.SX.sym("k_in"), ca.SX.sym("dt")
    z = ca.vertcat(s, nu)
    best, best_v = phase, ca.SX(-np.inf)
    for (src, tgt, dwell, bias, terms), g in zip(guard_terms(model), model.guards or []):
        v = bias + sum((w * z[c] for c, w in terms[1:]), terms[0][1] * z[terms[0][0]])
        name = f"guard_{g.source}_{g.target}"
        fns[name] = ca.Function(name, [s, nu], [v], ["s", "nu"], ["g"])
        fire = ca.logic_and(ca.logic_and(phase == src, k_in * dt + EPS_T >= dwell),
                            ca.logic_and(v >= 0, v > best_v))
        best = ca.if_else(fire, tgt, best)
        best_v = ca.if_else(fire, v, best_v)
    fns["guard_switch"] = ca.Function("guard_switch", [s, nu, phase, k_in, dt], [best],
                                      ["s", "nu", "phase", "k_in", "dt"], ["phase_next"])
    chains = robot_chains(model)
    if chains is None:
        return
    n_el, xyz, rot, axis, col = chains
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
                c = int(col[k, e])
                if c < 0:
                    continue
                u_ = axis[k, e]
                axes[c], origins[c] = Rk @ ca.DM(u_), p
                K = ca.DM([[0, -u_[2], u_[1]], [u_[2], 0, -u_[0]], [-u_[1], u_[0], 0]])
                Rk = Rk @ (ca.DM.eye(3) + ca.sin(q[c]) * K + (1 - ca.cos(q[c])) * (K @ K))
            J = ca.horzcat(*[ca.cross(axes[c], p - origins[c]) for c in range(3 * k, 3 * k + 3)])
            F = R @ (-ca.solve(J.T, tau[3 * k:3 * k + 3])) * contact[k]
            pk = (base + R @ p) if foot is None else foot[3 * k:3 * k + 3]
            f, m = f + F, m + ca.cross(pk - base, F)
        return ca.vertcat(tau, f, m)

    fns["input"] = ca.Function("input", [q, tau, contact, feet], [wrench(feet)],
                               ["q", "tau", "contact", "foot_pos"], ["u"])
    fns["input_kinematics"] = ca.Function("input_kinematics", [q, tau, contact], [wrench(None)],
                                          ["q", "tau", "contact"], ["u"])


# ------------------------------------------------------------------ Python
def python_source(model: HybridModel, bound: float) -> str:
    """NumPy source of ``guard_switch``, ``predict_path`` and (with a robot) ``input_from_torques``,
    appended to the Python export (which defines encode, decode, accel, rk4_step)."""
    limit = bound * model.yardstick
    cases = []
    for src, tgt, dwell, bias, terms in guard_terms(model):
        sum_ = " + ".join(f"{w!r} * z[{c}]" for c, w in terms)
        cases.append(f"    if phase == {src} and k_in * dt + {EPS_T!r} >= {dwell!r}:  # "
                     f"{model.phase_names[src]} -> {model.phase_names[tgt]}\n"
                     f"        v = {bias!r} + ({sum_})\n"
                     f"        if v >= 0 and v > best_v:\n            best, best_v = {tgt}, v")
    text = f'''

LIMIT = numpy.array({limit.tolist()!r})


def guard_switch(phase, k_in, dt, s, nu):
    """The phase after sample s (2l,), nu (l,) in ``phase`` entered k_in samples (dt s) ago."""
    z = numpy.concatenate([s, nu])
    best, best_v = phase, -numpy.inf
{chr(10).join(cases) if cases else "    pass"}
    return best


def predict_path(q0, dq0, u, dt, phases=None, phase0=0, substeps=2):
    """q, dq (n, 18) and phases (n,) from q0, dq0 (18,) with inputs u (n, 18) held over each
    sample; phases: a schedule of phase indices, or None for the guards from phase0. NaN from
    a divergence."""
    n = len(u)
    q, dq = numpy.full((n, 18), numpy.nan), numpy.full((n, 18), numpy.nan)
    out = numpy.zeros(n, dtype=int)
    s, phase, k_enter = encode(q0, dq0), phase0, 0
    for k in range(n):
        if not numpy.all(numpy.abs(s) <= LIMIT):
            out[k:] = phase
            break
        q[k], dq[k] = decode(s), W_D @ s[LATENT_DIM:]
        nu = encode_input(u[k])
        if phases is None:
            nxt = guard_switch(phase, k - k_enter, dt, s, nu)
            if nxt != phase:
                phase, k_enter = nxt, k
        else:
            phase = int(phases[k])
        out[k] = phase
        if k == n - 1:
            break
        for _ in range(substeps):
            s = rk4_step(phase, s, nu, dt / substeps)
    return q, dq, out
'''
    chains = robot_chains(model)
    if chains is None:
        return text
    n_el, xyz, rot, axis, col = chains
    return text + f'''

# The leg chains of robot {model.provenance.data.robot!r} (from its URDF).
N_EL = {n_el.tolist()!r}
K_XYZ = numpy.array({xyz.tolist()!r})
K_ROT = numpy.array({rot.tolist()!r})
K_AXIS = numpy.array({axis.tolist()!r})
K_COL = {col.tolist()!r}


def _rpy(r, p, y):
    cr, sr, cp, sp, cy, sy = numpy.cos(r), numpy.sin(r), numpy.cos(p), numpy.sin(p), numpy.cos(y), numpy.sin(y)
    return numpy.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                        [-sp, cp * sr, cp * cr]])


def _leg(k, qj):
    """Foot (3,) and Jacobian (3, 3) of leg k, base frame."""
    R, p, axes, origins = numpy.eye(3), numpy.zeros(3), {{}}, {{}}
    for e in range(N_EL[k]):
        p = p + R @ K_XYZ[k, e]
        R = R @ K_ROT[k, e]
        c = K_COL[k][e]
        if c < 0:
            continue
        a = K_AXIS[k, e]
        axes[c], origins[c] = R @ a, p.copy()
        K = numpy.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
        R = R @ (numpy.eye(3) + numpy.sin(qj[c]) * K + (1 - numpy.cos(qj[c])) * (K @ K))
    return p, numpy.stack([numpy.cross(axes[c], p - origins[c]) for c in range(3 * k, 3 * k + 3)], axis=1)


def input_from_torques(q, tau, contact, foot_pos=None):
    """The input map: u (18,) from q (18,), torques tau (12,) N m, contact flags (4,) and the
    feet foot_pos (4, 3) world m (None: from the kinematics)."""
    R, base = _rpy(*q[15:18]), q[12:15]
    f, m = numpy.zeros(3), numpy.zeros(3)
    for k in range(4):
        pb, J = _leg(k, q[:12])
        p = base + R @ pb if foot_pos is None else numpy.asarray(foot_pos)[k]
        if not contact[k]:
            continue
        F = R @ -numpy.linalg.solve(J.T, tau[3 * k:3 * k + 3])
        f, m = f + F, m + numpy.cross(p - base, F)
    return numpy.concatenate([tau, f, m])
'''
