/* symrom runtime (C99, math.h only): encoding, decoding, RK4, the guards, free prediction and
 * the input map of an exported model, over the model's tables.
 *
 * Each export's symrom_model.c includes this file after the tables it emits (l latents, P
 * phases, G guards of at most K terms, chains of at most E elements):
 *   W_E[l][18], B_E[l], W_D[18][l], B_D[18]: the encoder xi = W_E q + B_E and decoder
 *     q = W_D xi + B_D; IN_MAP[18][l]: nu = IN_MAP^T u;
 *   SYMROM_LIMIT[2l]: the bound on |s| of free prediction;
 *   ACCEL_PHASE[P]: per phase, its latent dynamics ddxi (l) from s (2l) and nu (l);
 *   GUARD_SOURCE, GUARD_TARGET, GUARD_N_TERMS (int), GUARD_DWELL (s), GUARD_BIAS [G],
 *     GUARD_COL (int, columns of z = [s, nu]) and GUARD_WEIGHT [G][K]: guard g fires in its
 *     source after its dwell when GUARD_BIAS[g] + sum_i GUARD_WEIGHT[g][i] z[GUARD_COL[g][i]] >= 0
 *     (at least one row: C has no empty arrays; SYMROM_N_GUARDS counts the real ones);
 *   with SYMROM_HAS_INPUT_MAP, the leg chains of the robot: N_EL[4] elements per leg,
 *     K_XYZ[4][E][3] m, K_ROT[4][E][3][3], K_AXIS[4][E][3], K_COL[4][E] (joint column in the
 *     12 angles, -1 for a fixed element).
 * The arithmetic is symrom's, in its order, so that the numbers agree with it to rounding. */
#include <math.h>

#include "symrom_model.h"

enum { L = SYMROM_LATENT_DIM };

void symrom_encode(const double q[18], const double dq[18], double s[2 * L]) {
    for (int i = 0; i < L; i++) {
        double a = B_E[i], b = 0.0;
        for (int c = 0; c < 18; c++) { a += W_E[i][c] * q[c]; b += W_E[i][c] * dq[c]; }
        s[i] = a; s[L + i] = b;
    }
}

void symrom_encode_input(const double u[18], double nu[L]) {
    for (int i = 0; i < L; i++) {
        double a = 0.0;
        for (int c = 0; c < 18; c++) a += u[c] * IN_MAP[c][i];
        nu[i] = a;
    }
}

void symrom_decode(const double s[2 * L], double q[18]) {
    for (int c = 0; c < 18; c++) {
        double a = B_D[c];
        for (int i = 0; i < L; i++) a += W_D[c][i] * s[i];
        q[c] = a;
    }
}

int symrom_accel(int phase, const double s[2 * L], const double nu[L], double ddxi[L]) {
    if (phase < 0 || phase >= SYMROM_N_PHASES) return -1;
    ACCEL_PHASE[phase](s, nu, ddxi);
    return 0;
}

static int field(int phase, const double s[2 * L], const double nu[L], double ds[2 * L]) {
    for (int i = 0; i < L; i++) ds[i] = s[L + i];
    return symrom_accel(phase, s, nu, ds + L);
}

int symrom_rk4_step(int phase, double s[2 * L], const double nu[L], double h) {
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
}

/* The first place after `stage` of the phase sequence holding phase `target`, -1 if none (stage -1:
 * no sequence, any target goes and the stage stays -1). */
static int later_stage(int stage, int target) {
    if (stage < 0) return -1;
    for (int j = stage + 1; j < SYMROM_N_SEQUENCE; j++) if (SEQUENCE[j] == target) return j;
    return -1;
}

/* symrom_guard_switch at `stage` of the phase sequence: only guards into a later phase of it fire
 * (stage -1: any guard). */
static int guard_switch_at(int stage, int phase, int k_in, double dt, const double s[2 * L], const double nu[L]) {
    double z[3 * L], best_v = -INFINITY;
    int best = phase;
    for (int i = 0; i < 2 * L; i++) z[i] = s[i];
    for (int i = 0; i < L; i++) z[2 * L + i] = nu[i];
    for (int g = 0; g < SYMROM_N_GUARDS; g++) {
        if (phase != GUARD_SOURCE[g] || !(k_in * dt + SYMROM_EPS_T >= GUARD_DWELL[g])) continue;
        if (stage >= 0 && later_stage(stage, GUARD_TARGET[g]) < 0) continue;
        double sum = 0.0; /* a clock (no terms) fires once its dwell has passed */
        for (int i = 0; i < GUARD_N_TERMS[g]; i++) sum += GUARD_WEIGHT[g][i] * z[GUARD_COL[g][i]];
        double v = GUARD_BIAS[g] + sum;
        if (v >= 0.0 && v > best_v) { best = GUARD_TARGET[g]; best_v = v; }
    }
    return best;
}

int symrom_guard_switch(int phase, int k_in, double dt, const double s[2 * L], const double nu[L]) {
    return guard_switch_at(-1, phase, k_in, dt, s, nu);
}

int symrom_predict_path(int n, double dt, int substeps, const double q0[18], const double dq0[18],
                        const double *u, int predict_phases, int phase0, int *phases, double *q, double *dq) {
    double s[2 * L], nu[L];
    int phase = phase0, k_enter = 0, div = -1, stage = -1;
    for (int j = 0; j < SYMROM_N_SEQUENCE; j++) if (SEQUENCE[j] == phase0) { stage = j; break; }
    symrom_encode(q0, dq0, s);
    for (int k = 0; k < n; k++) {
        int ok = 1;
        for (int i = 0; i < 2 * L; i++) if (!(fabs(s[i]) <= SYMROM_LIMIT[i])) ok = 0;
        if (!ok) { div = k; break; }
        symrom_decode(s, q + 18 * k);
        for (int c = 0; c < 18; c++) {
            double a = 0.0;
            for (int i = 0; i < L; i++) a += W_D[c][i] * s[L + i];
            dq[18 * k + c] = a;
        }
        symrom_encode_input(u + 18 * k, nu);
        if (predict_phases) {
            int next = guard_switch_at(stage, phase, k - k_enter, dt, s, nu);
            if (next != phase) { stage = later_stage(stage, next); phase = next; k_enter = k; }
            phases[k] = phase;
        } else {
            phase = phases[k];
            if (phase < 0 || phase >= SYMROM_N_PHASES) return -2;
        }
        if (k == n - 1) break;
        for (int r = 0; r < substeps; r++) symrom_rk4_step(phase, s, nu, dt / substeps);
    }
    if (div >= 0) {
        for (int k = div; k < n; k++) {
            for (int c = 0; c < 18; c++) q[18 * k + c] = dq[18 * k + c] = NAN;
            if (predict_phases) phases[k] = phase;
        }
    }
    return div;
}

#if SYMROM_HAS_INPUT_MAP
/* Feet (base frame, m) and leg Jacobians d foot / d q_leg (base frame) of joint angles qj (12). */
static void legs(const double qj[12], double pos[4][3], double J[4][3][3]) {
    for (int k = 0; k < 4; k++) {
        double R[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, T[3][3], p[3] = {0, 0, 0}, ax[3][3], org[3][3];
        for (int e = 0; e < N_EL[k]; e++) {
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
            for (int a = 0; a < 3; a++) {
                ax[j][a] = R[a][0] * u0 + R[a][1] * u1 + R[a][2] * u2;
                org[j][a] = p[a];
            }
            double s = sin(qj[c]), cq = cos(qj[c]), v = 1.0 - cq;
            double G[3][3] = {{cq + v * u0 * u0, v * u0 * u1 - s * u2, v * u0 * u2 + s * u1},
                              {v * u1 * u0 + s * u2, cq + v * u1 * u1, v * u1 * u2 - s * u0},
                              {v * u2 * u0 - s * u1, v * u2 * u1 + s * u0, cq + v * u2 * u2}};
            for (int a = 0; a < 3; a++)
                for (int b = 0; b < 3; b++) T[a][b] = R[a][0] * G[0][b] + R[a][1] * G[1][b] + R[a][2] * G[2][b];
            for (int a = 0; a < 3; a++) for (int b = 0; b < 3; b++) R[a][b] = T[a][b];
        }
        for (int a = 0; a < 3; a++) pos[k][a] = p[a];
        for (int j = 0; j < 3; j++) {
            double d0 = p[0] - org[j][0], d1 = p[1] - org[j][1], d2 = p[2] - org[j][2];
            J[k][0][j] = ax[j][1] * d2 - ax[j][2] * d1;
            J[k][1][j] = ax[j][2] * d0 - ax[j][0] * d2;
            J[k][2][j] = ax[j][0] * d1 - ax[j][1] * d0;
        }
    }
}

/* x = A^-1 b by Gaussian elimination with partial pivoting (A_in is not changed); -1 if A is
 * singular. */
static int solve3(double A_in[3][3], const double b_in[3], double x[3]) {
    double A[3][4];
    for (int i = 0; i < 3; i++) { for (int j = 0; j < 3; j++) A[i][j] = A_in[i][j]; A[i][3] = b_in[i]; }
    for (int c = 0; c < 3; c++) {
        int p = c;
        for (int r = c + 1; r < 3; r++) if (fabs(A[r][c]) > fabs(A[p][c])) p = r;
        if (A[p][c] == 0.0) return -1;
        for (int j = 0; j < 4; j++) { double t = A[c][j]; A[c][j] = A[p][j]; A[p][j] = t; }
        for (int r = c + 1; r < 3; r++) {
            double f = A[r][c] / A[c][c];
            for (int j = c; j < 4; j++) A[r][j] -= f * A[c][j];
        }
    }
    for (int i = 2; i >= 0; i--) {
        double a = A[i][3];
        for (int j = i + 1; j < 3; j++) a -= A[i][j] * x[j];
        x[i] = a / A[i][i];
    }
    return 0;
}

int symrom_input(const double q[18], const double tau[12], const int contact[4], const double *foot_pos,
                 double u[18]) {
    double pos[4][3], J[4][3][3], R[3][3];
    double r = q[15], pi = q[16], y = q[17];
    double cr = cos(r), sr = sin(r), cp = cos(pi), sp = sin(pi), cy = cos(y), sy = sin(y);
    R[0][0] = cy * cp; R[0][1] = cy * sp * sr - sy * cr; R[0][2] = cy * sp * cr + sy * sr;
    R[1][0] = sy * cp; R[1][1] = sy * sp * sr + cy * cr; R[1][2] = sy * sp * cr - cy * sr;
    R[2][0] = -sp; R[2][1] = cp * sr; R[2][2] = cp * cr;
    legs(q, pos, J);
    for (int c = 0; c < 12; c++) u[c] = tau[c];
    for (int c = 12; c < 18; c++) u[c] = 0.0;
    for (int k = 0; k < 4; k++) {
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
    }
    return 0;
}
#endif
