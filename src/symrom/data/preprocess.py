"""Preprocessing: accelerations by differentiation, ground-reaction forces, CoM wrench.

The ground-reaction force on foot k in contact is F_k = -(J_k^T)^-1 tau_k, with
J_k the leg Jacobian at the logged joint angles (from the URDF), rotated from
the base frame into the world frame. The CoM wrench is [sum F_k,
sum (p_k - b) x F_k], with b the base position standing for the CoM, and the
system input is u = [tau, wrench]. The torques the wrench is derived from are those
that reach the joints: the logged (motor) torques less the actuator effects the
robot's description states (``joint_torques``; none for the built-in robots).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from symrom.data.dataset import Dataset, jump_bounds, validate
from symrom.data.phases import label_phases
from symrom.names import BASE_POS, BASE_RPY, JOINTS, N_JOINTS, N_LEGS, leg_slice
from symrom.robots import get_robot, leg_kinematics
from symrom.robots.kinematics import rpy_to_matrix

DIFF_METHODS = ("savgol", "central")
DIFF_WINDOW = 0.018  # s: the Savitzky-Golay window, 9 samples at 500 Hz (importers.diff_samples)


def savgol_derivative(x: np.ndarray, window: int, polyorder: int, dt: float) -> np.ndarray:
    """Savitzky-Golay first derivative of ``x`` (n, d) along its rows, sampled every ``dt`` s:
    SciPy's ``savgol_filter(x, window, polyorder, deriv=1, delta=dt, axis=0, mode="interp")``
    to the last bit (``tests/test_preprocess.py``), without importing ``scipy.signal`` (a second
    of every process that builds a dataset) or ``scipy.ndimage``. ``polyorder < window <= n``.

    Inside, the derivative at each sample of the least-squares polynomial through the
    ``window`` samples centred on it (one correlation, SciPy's coefficients, its LAPACK solve);
    within ``window // 2`` samples of either end, the derivative of the polynomial fitted to
    the first or last ``window`` samples (scaled columns, as SciPy's polyfit)."""
    from scipy.linalg import lstsq

    x = np.asarray(x, dtype=float)
    n, half = x.shape[0], window // 2
    eps = np.finfo(float).eps
    # the coefficients: powers of the window's offsets (reversed, for a convolution), rows by power
    centre = half if window % 2 else half - 0.5  # an even window's centre falls between two samples
    offsets = np.arange(-centre, window - centre, dtype=float)[::-1]
    powers = offsets ** np.arange(polyorder + 1, dtype=float).reshape(-1, 1)
    unit = np.zeros(polyorder + 1)
    unit[1] = 1.0 / dt
    coeffs = lstsq(powers, unit, cond=eps * max(powers.shape))[0]
    out = np.empty_like(x)
    _correlate_inside(x, coeffs[::-1], 0 if window % 2 else -1, out)
    # the ends: one polynomial per column through the first / last window, its derivative there
    t = np.arange(window, dtype=float)
    vander = t[:, None] ** np.arange(polyorder, -1, -1, dtype=float)[None, :]
    scale = np.sqrt(np.sum(vander * vander, axis=0))
    vander = vander / scale
    slope = np.arange(polyorder, 0, -1, dtype=float).reshape(-1, 1)  # d/dt of each power, highest first
    for start, rows in ((0, slice(0, half)), (n - window, slice(n - half, n))):
        edge = x[start:start + window].reshape(window, -1)
        c = (lstsq(vander, edge, cond=window * eps)[0].T / scale).T
        c = c[:-1] * slope
        at = np.arange(rows.start - start, rows.stop - start, dtype=float).reshape(-1, 1)
        value = np.zeros_like(at)
        for row in c:  # Horner, highest power first
            value = value * at + row
        out[rows] = (value / dt).reshape((rows.stop - rows.start, *x.shape[1:]))
    return out


def _correlate_inside(x: np.ndarray, w: np.ndarray, origin: int, out: np.ndarray) -> None:
    """Rows of ``out`` (n, ...) whose window lies inside ``x`` (n, ...): the correlation of ``x``'s
    rows with the weights ``w`` (k,) centred at ``k // 2`` and shifted by ``origin`` (0, or -1 for an
    even ``k``: a convolution's centre), summed in the order and pairing of SciPy's
    ``ndimage.correlate1d`` so that every row is its result to the last bit. Whole rows at a time in
    NumPy: importing ``scipy.ndimage`` (and ``scipy.special`` with it) costs more than the sums.

    An odd ``w`` that reads the same backwards, or its negative, within one ulp of 1 (as SciPy
    tests it) pairs the samples either side of the centre before weighting them; any other sums
    the last tap first, then the rest in order. Other rows of ``out`` are left as they were."""
    k, n = w.size, x.shape[0]
    before, after = k // 2, k - k // 2 - 1
    lo, hi = before + origin, n - after + origin  # rows i with x[i - before - origin ... i + after - origin]
    if hi <= lo:
        return

    def tap(j: int) -> np.ndarray:  # sample j (-before..after) of every row's window
        return x[lo + j - origin:hi + j - origin]

    eps = np.finfo(float).eps
    pairing = 0
    if k % 2:
        mirror = [(w[before + i], w[before - i]) for i in range(1, before + 1)]
        if all(abs(a - b) <= eps for a, b in mirror):
            pairing = 1
        elif all(abs(a + b) <= eps for a, b in mirror):
            pairing = -1
    rows = out[lo:hi]
    if pairing:
        rows[...] = tap(0) * w[before]
        for j in range(-before, 0):
            pair = tap(j) + tap(-j) if pairing > 0 else tap(j) - tap(-j)
            rows += pair * w[before + j]
    else:
        rows[...] = tap(after) * w[before + after]
        for j in range(-before, after):
            rows += tap(j) * w[before + j]


def differentiate(x: np.ndarray, dt: float, jump: np.ndarray, method: str = "savgol",
                  window: int = 9, polyorder: int = 3) -> np.ndarray:
    """Time derivative of ``x`` (N, d) sampled every ``dt`` s, jump by jump.

    ``savgol``: the Savitzky-Golay derivative (``window`` samples, ``polyorder``;
    ``savgol_derivative``, SciPy's to the last bit), smooth and robust to sensor noise;
    ``central``: NumPy's second-order central differences (one-sided at the ends), no
    smoothing.
    """
    if method not in DIFF_METHODS:
        raise ValueError(f"unknown differentiation method {method!r}; choose from {DIFF_METHODS}")
    x = np.asarray(x, dtype=float)
    out = np.empty_like(x)
    for a, b in jump_bounds(jump):
        seg = x[a:b]
        n = b - a
        if method == "savgol" and n > polyorder + 1:
            w = min(window, n if n % 2 else n - 1)
            w = max(w, polyorder + 2 if (polyorder + 2) % 2 else polyorder + 3)
            out[a:b] = savgol_derivative(seg, w, polyorder, dt) if w <= n else np.gradient(seg, dt, axis=0)
        elif n > 1:
            out[a:b] = np.gradient(seg, dt, axis=0)
        else:
            out[a:b] = 0.0
    return out


def ground_reaction_forces(robot: str, q: np.ndarray, tau: np.ndarray,
                           contact: np.ndarray) -> np.ndarray:
    """World-frame GRF per foot: q (N, 18), tau (N, 12) N m, contact (N, 4) -> (N, 4, 3) N.

    Zero for feet not in contact. A singular leg (fully stretched) uses the
    least-squares inverse instead of failing.
    """
    J = leg_kinematics(robot).jacobians(q[:, JOINTS])  # (N, 4, 3, 3), base frame
    R = rpy_to_matrix(q[:, BASE_RPY])  # (N, 3, 3) base -> world
    F = np.zeros((q.shape[0], N_LEGS, 3))
    for k in range(N_LEGS):
        JT = np.swapaxes(J[:, k], 1, 2)
        tk = tau[:, leg_slice(k)]
        try:
            fb = -np.linalg.solve(JT, tk[..., None])[..., 0]
        except np.linalg.LinAlgError:
            fb = -np.einsum("nij,nj->ni", np.linalg.pinv(JT), tk)
        F[:, k] = np.einsum("nij,nj->ni", R, fb) * (np.asarray(contact)[:, k:k + 1] > 0)
    return F


def foot_positions_world(robot: str, q: np.ndarray) -> np.ndarray:
    """Feet in the world frame from the configuration: q (N, 18) -> (N, 4, 3) m."""
    pb = leg_kinematics(robot).foot_positions(q[:, JOINTS])
    R = rpy_to_matrix(q[:, BASE_RPY])
    return q[:, None, BASE_POS] + np.einsum("nij,nkj->nki", R, pb)


def com_wrench(robot: str, q: np.ndarray, tau: np.ndarray, contact: np.ndarray,
               foot_pos: np.ndarray | None = None) -> np.ndarray:
    """CoM wrench (N, 6): summed GRF (N, world) and its moment about the base (N m).

    q (N, 18), tau (N, 12) N m, contact (N, 4); ``foot_pos`` (N, 4, 3) m world
    if logged, else computed from the kinematics.
    """
    F = ground_reaction_forces(robot, q, tau, contact)
    p = foot_positions_world(robot, q) if foot_pos is None else foot_pos
    lever = p - q[:, None, BASE_POS]
    return np.concatenate([F.sum(axis=1), np.cross(lever, F).sum(axis=1)], axis=1)


def input_from_torques(robot: str, q: np.ndarray, tau: np.ndarray, contact: np.ndarray,
                       foot_pos: np.ndarray | None = None) -> np.ndarray:
    """The input map: u (N, 18) = [tau, CoM wrench] from q (N, 18), joint torques tau (N, 12)
    N m, contact flags (N, 4) and, if known, the feet (N, 4, 3) m world (else from the
    kinematics). The one definition of a model's input ``u``: datasets are built with it, and
    the exports carry it (``symrom.export``)."""
    q, tau = np.atleast_2d(np.asarray(q, dtype=float)), np.atleast_2d(np.asarray(tau, dtype=float))
    return np.concatenate([tau, com_wrench(robot, q, tau, np.atleast_2d(contact), foot_pos)], axis=1)


def joint_torques(robot: str, tau: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
    """The torques (N, 12) N m that reach the joints of ``robot``: the motors' tau (N, 12) less
    what the actuator effects its description states take at the joint speeds and
    accelerations of dq, ddq (N, 18) (``ActuatorEffects.losses``: damping, friction loss,
    armature). ``tau`` itself, the same array, for a robot that states none (the built-in
    robots): the ground force a motor's torque gives is that of what is left of it."""
    effects = get_robot(robot).actuators
    if effects.ideal:
        return tau
    return np.asarray(tau, float) - effects.losses(np.asarray(dq)[:, JOINTS], np.asarray(ddq)[:, JOINTS])


def _inputs(robot, q, dq, ddq, tau, contact, foot_pos) -> np.ndarray:
    """u (N, 18) of logged motor torques: [tau, the wrench of the joints' torques]."""
    u = input_from_torques(robot, q, joint_torques(robot, tau, dq, ddq), contact, foot_pos)
    u[:, :N_JOINTS] = tau
    return u


def assemble(*, robot: str, motion: str, source: str, jump: np.ndarray, t: np.ndarray,
             q: np.ndarray, dq: np.ndarray, tau: np.ndarray, contact: np.ndarray,
             ddq: np.ndarray | None = None, foot_pos: np.ndarray | None = None,
             split: np.ndarray | None = None, dt: float = 0.002,
             generator: dict[str, Any] | None = None, diff_method: str = "savgol",
             contact_force: np.ndarray | None = None) -> Dataset:
    """Build and validate a dataset from raw logs (arrays as in ``Dataset``).

    Missing ``ddq`` is obtained by differentiating ``dq``; phases come from the
    contact flags with the motion's rule; ``u = [tau, wrench]``, the wrench from the torques
    that reach the joints (``joint_torques``). Without
    ``split`` every jump is ``train``. ``contact_force`` (N, 4, 3) N: an engine's true
    ground forces, kept as a diagnostic (not in ``u``).
    """
    jump = np.asarray(jump, dtype=np.int32)
    contact = np.asarray(contact, dtype=np.uint8)
    generator = dict(generator or {})
    if ddq is None:
        ddq = differentiate(dq, dt, jump, diff_method)
        generator.setdefault("ddq", f"differentiated dq ({diff_method})")
    phase, phase_names = label_phases(contact, jump, motion)
    n_jumps = int(jump.max()) + 1 if jump.size else 0
    if split is None:
        split = np.array(["train"] * n_jumps, dtype=object)
    ds = Dataset(robot=robot, motion=motion, source=source, phase_names=phase_names,
                 jump=jump, t=np.asarray(t, float), q=np.asarray(q, float),
                 dq=np.asarray(dq, float), ddq=np.asarray(ddq, float), tau=np.asarray(tau, float),
                 contact=contact, u=_inputs(robot, q, dq, ddq, tau, contact, foot_pos), phase=phase,
                 split=np.asarray(split, dtype=object), foot_pos=foot_pos, dt=float(dt),
                 generator=generator, contact_force=contact_force)
    validate(ds)
    return ds
