"""symrom runtime (Python, NumPy only): encoding, decoding, RK4, the guards, free prediction and
the input map of an exported model, over the model's tables.

Each export's ``symrom_model.py`` holds a copy of this code, then the model's tables and
per-phase dynamics, and binds its functions to them (``Runtime``). q (18): the 12 joint angles
(rad), then x y z (m) and roll pitch yaw (rad); u (18): joint torques (N m), then the CoM
wrench (N, N m). The latent state is s = [xi (l), dxi (l)], the latent inputs nu (l). The
arithmetic is symrom's, in its order, so that the numbers agree with it to rounding.
"""

import numpy


class Runtime:
    """The functions of one model, over its tables.

    latent_dim l; phases: the P phase names; W_E (l, 18), B_E (l,), W_D (18, l), B_D (18,):
    the encoder and decoder; IN_MAP (18, l): nu = u @ IN_MAP; accel_phase: per phase a function
    (s (2l,), nu (l,)) -> ddxi (l,); limit (2l,): the bound on |s| of free prediction; eps_t: s,
    the rounding allowance of the guards' dwell test; guards: rows (source, target, dwell s,
    bias, [(column of z = [s, nu], weight), ...]); chains: the robot's leg chains (n_el (4,),
    xyz (4, E, 3) m, rot (4, E, 3, 3), axis (4, E, 3), col (4, E)), None without the input map;
    sequence: the phase indices of one jump of the motion, in order (empty: none). Along it a
    free prediction keeps its stage (its place in the sequence): from stage i only guards into
    a phase later in the sequence fire, and a switch moves to that phase's first place after i.
    """

    def __init__(self, latent_dim, phases, W_E, B_E, W_D, B_D, IN_MAP, accel_phase, limit, eps_t, guards,
                 chains=None, sequence=()):
        self.l, self.phases = latent_dim, list(phases)
        self.W_E, self.B_E, self.W_D, self.B_D, self.IN_MAP = W_E, B_E, W_D, B_D, IN_MAP
        self.accel_phase, self.limit, self.eps_t, self.guards = list(accel_phase), limit, eps_t, list(guards)
        self.chains, self.sequence = chains, list(sequence)

    def encode(self, q, dq):
        """q, dq (18,) -> s (2l,)."""
        return numpy.concatenate([self.W_E @ q + self.B_E, self.W_E @ dq])

    def encode_input(self, u):
        """u (18,) -> nu (l,)."""
        return u @ self.IN_MAP

    def decode(self, s):
        """s (2l,) (or xi (l,)) -> q (18,)."""
        return self.W_D @ s[:self.l] + self.B_D

    def accel(self, phase, s, nu):
        """ddxi (l,) in phase index ``phase``."""
        for k, f in enumerate(self.accel_phase):
            if phase == k:
                return f(s, nu)
        raise ValueError(f"unknown phase {phase}; phases are 0..{len(self.phases) - 1}")

    def rk4_step(self, phase, s, nu, h):
        """s after one classical Runge-Kutta step of h s, nu and phase held."""
        def field(z):
            return numpy.concatenate([z[self.l:], self.accel(phase, z, nu)])

        k1 = field(s)
        k2 = field(s + h / 2 * k1)
        k3 = field(s + h / 2 * k2)
        k4 = field(s + h * k3)
        return s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    def guard_switch(self, phase, k_in, dt, s, nu, stage=-1):
        """The phase after sample s (2l,), nu (l,) in ``phase`` entered k_in samples (dt s) ago:
        the target of the firing guard with the largest value, else ``phase``; at ``stage`` of
        the sequence only guards into a later phase of it (-1: any guard)."""
        z = numpy.concatenate([s, nu])
        best, best_v = phase, -numpy.inf
        for source, target, dwell, bias, terms in self.guards:
            if phase != source or not k_in * dt + self.eps_t >= dwell:
                continue
            if stage >= 0 and target not in self.sequence[stage + 1:]:
                continue
            total = 0.0  # a clock (no terms) fires once its dwell has passed
            for c, w in terms:
                total = total + w * z[c]
            v = bias + total
            if v >= 0 and v > best_v:
                best, best_v = target, v
        return best

    def predict_path(self, q0, dq0, u, dt, phases=None, phase0=0, substeps=2):
        """q, dq (n, 18) and phases (n,) from q0, dq0 (18,) with inputs u (n, 18) held over each
        sample; phases: a schedule of phase indices, or None for the guards from phase0 (at its
        first place in the sequence). NaN from a divergence."""
        n = len(u)
        q, dq = numpy.full((n, 18), numpy.nan), numpy.full((n, 18), numpy.nan)
        out = numpy.zeros(n, dtype=int)
        s, phase, k_enter = self.encode(q0, dq0), phase0, 0
        stage = self.sequence.index(phase0) if phase0 in self.sequence else -1
        for k in range(n):
            if not numpy.all(numpy.abs(s) <= self.limit):
                out[k:] = phase
                break
            q[k], dq[k] = self.decode(s), self.W_D @ s[self.l:]
            nu = self.encode_input(u[k])
            if phases is None:
                nxt = self.guard_switch(phase, k - k_enter, dt, s, nu, stage)
                if nxt != phase:
                    if stage >= 0:
                        stage = stage + 1 + self.sequence[stage + 1:].index(nxt)
                    phase, k_enter = nxt, k
            else:
                phase = int(phases[k])
            out[k] = phase
            if k == n - 1:
                break
            for _ in range(substeps):
                s = self.rk4_step(phase, s, nu, dt / substeps)
        return q, dq, out

    def _leg(self, k, qj):
        """Foot (3,) and Jacobian (3, 3) of leg k, base frame."""
        n_el, xyz, rot, axis, col = self.chains
        R, p, axes, origins = numpy.eye(3), numpy.zeros(3), {}, {}
        for e in range(n_el[k]):
            p = p + R @ xyz[k, e]
            R = R @ rot[k, e]
            c = col[k][e]
            if c < 0:
                continue
            a = axis[k, e]
            axes[c], origins[c] = R @ a, p.copy()
            K = numpy.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
            R = R @ (numpy.eye(3) + numpy.sin(qj[c]) * K + (1 - numpy.cos(qj[c])) * (K @ K))
        return p, numpy.stack([numpy.cross(axes[c], p - origins[c]) for c in range(3 * k, 3 * k + 3)], axis=1)

    def input_from_torques(self, q, tau, contact, foot_pos=None):
        """The input map: u (18,) from q (18,), torques tau (12,) N m, contact flags (4,) and the
        feet foot_pos (4, 3) world m (None: from the kinematics)."""
        if self.chains is None:
            raise ValueError("this model was exported without its robot's legs: it has no input map")
        R, base = _rpy(*q[15:18]), q[12:15]
        f, m = numpy.zeros(3), numpy.zeros(3)
        for k in range(4):
            pb, J = self._leg(k, q[:12])
            p = base + R @ pb if foot_pos is None else numpy.asarray(foot_pos)[k]
            if not contact[k]:
                continue
            F = R @ -numpy.linalg.solve(J.T, tau[3 * k:3 * k + 3])
            f, m = f + F, m + numpy.cross(p - base, F)
        return numpy.concatenate([tau, f, m])


def _rpy(r, p, y):
    """The rotation (3, 3) of ZYX Euler angles roll r, pitch p, yaw y (rad)."""
    cr, sr, cp, sp, cy, sy = numpy.cos(r), numpy.sin(r), numpy.cos(p), numpy.sin(p), numpy.cos(y), numpy.sin(y)
    return numpy.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                        [-sp, cp * sr, cp * cr]])
