/* symrom runtime (C99, math.h only): the functions of an exported model.
 *
 * Include symrom_model.h, which defines the model's sizes and includes this file; compile
 * symrom_model.c, which holds the model's tables and per-phase dynamics and includes
 * symrom_runtime.c. q (18): fr_hx fr_hy fr_kn fl_... rl_kn (rad), x y z (m), roll pitch yaw
 * (rad); u (18): joint torques (N m) then the CoM wrench (N, N m). The latent state is
 * s = [xi (l), dxi (l)], the latent inputs nu (l), l = SYMROM_LATENT_DIM; phase k is the k-th
 * name of SYMROM_PHASES. */
#ifndef SYMROM_RUNTIME_H
#define SYMROM_RUNTIME_H

#ifndef SYMROM_LATENT_DIM
#error "include symrom_model.h (it defines the model's sizes), not symrom_runtime.h"
#endif

void symrom_encode(const double q[18], const double dq[18], double s[2 * SYMROM_LATENT_DIM]);
void symrom_encode_input(const double u[18], double nu[SYMROM_LATENT_DIM]);
void symrom_decode(const double s[2 * SYMROM_LATENT_DIM], double q[18]);
/* ddxi (l) of phase `phase` (0 .. SYMROM_N_PHASES - 1); returns -1 for an unknown phase. */
int symrom_accel(int phase, const double s[2 * SYMROM_LATENT_DIM], const double nu[SYMROM_LATENT_DIM],
                 double ddxi[SYMROM_LATENT_DIM]);
/* One classical Runge-Kutta step of length h (s) of s in place, nu and phase held. */
int symrom_rk4_step(int phase, double s[2 * SYMROM_LATENT_DIM], const double nu[SYMROM_LATENT_DIM], double h);
/* The phase after sample s, nu in `phase`, entered k_in samples (dt s each) ago: the target of the
 * firing guard with the largest value, else `phase`. */
int symrom_guard_switch(int phase, int k_in, double dt, const double s[2 * SYMROM_LATENT_DIM],
                        const double nu[SYMROM_LATENT_DIM]);
/* Predict n samples every dt s from q0, dq0 (18) with inputs u (n x 18, row-major) held over each
 * sample, substeps RK4 steps per sample. predict_phases 0: phases (n) is the schedule (read);
 * 1: the guards decide from phase0, entered at sample 0, and phases (n) receives them; along the
 * motion's phase sequence (SEQUENCE, from phase0's first place in it) each transition is taken
 * once and no phase the jump has left is entered again. q, dq
 * (n x 18) receive the path, NaN from a divergence (|s_i| beyond the model's limit). Returns the
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

#endif
