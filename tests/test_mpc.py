"""Convex single-rigid-body MPC on its own: hover, constraints, agreement with a dense solve."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import scipy.optimize

from symrom.sim.controllers.mpc import (
    MOVING,
    QP_SOLVERS,
    ConvexMPC,
    MPCConfig,
    condense,
    continuous_dynamics,
    discretize,
    srb_state,
)

MASS = 13.1
INERTIA = np.diag([0.05, 0.18, 0.20])
FEET = np.array([[0.19, -0.13, 0.0], [0.19, 0.13, 0.0], [-0.19, -0.13, 0.0], [-0.19, 0.13, 0.0]])


def _simulate(mpc: ConvexMPC, x: np.ndarray, ref_fn, contact_fn, t_end: float,
              dt: float = 0.001, every: int = 10):
    """Integrate the SRB model (explicit Euler, 1 kHz) under the MPC; returns states and forces."""
    xs, fs = [], []
    forces = np.zeros((4, 3))
    for i in range(int(round(t_end / dt))):
        t = i * dt
        r = FEET - x[3:6]
        if i % every == 0:
            h, sdt = mpc.config.horizon, mpc.config.dt
            x_ref = np.array([ref_fn(t + (k + 1) * sdt) for k in range(h)])
            contact = np.array([contact_fn(t + (k + 1) * sdt) for k in range(h)])
            forces = mpc.solve(x, x_ref, r, contact).forces
        Ac, Bc = continuous_dynamics(MASS, INERTIA, x[2], r)
        x = x + dt * (Ac @ x + Bc @ forces.ravel())
        xs.append(x.copy())
        fs.append(forces.copy())
    return np.array(xs), np.array(fs)


def test_discretisation_is_exact():
    Ac, Bc = continuous_dynamics(MASS, INERTIA, 0.3, FEET - [0.01, 0.0, 0.28])
    A, B = discretize(Ac, Bc, 0.025)
    M = np.zeros((25, 25))
    M[:13, :13], M[:13, 13:] = Ac, Bc
    E = scipy.linalg.expm(M * 0.025)
    np.testing.assert_allclose(A, E[:13, :13], atol=1e-12)
    np.testing.assert_allclose(B, E[:13, 13:], atol=1e-12)


@pytest.mark.parametrize("solver", QP_SOLVERS)
def test_planted_body_holds_a_standing_reference(solver):
    mpc = ConvexMPC(MASS, INERTIA, MPCConfig(solver=solver))
    x_stand = srb_state(np.zeros(3), np.array([0.0, 0.0, 0.28]), np.zeros(3), np.zeros(3))
    # start a little off: 2 cm low, tilted, drifting
    x0 = srb_state(np.array([0.03, -0.04, 0.02]), np.array([0.01, -0.01, 0.26]),
                   np.array([0.1, 0.0, 0.0]), np.array([0.05, 0.0, 0.0]))
    xs, fs = _simulate(mpc, x0, lambda t: x_stand, lambda t: np.ones(4), t_end=1.5)
    final = xs[-1]
    np.testing.assert_allclose(final[3:6], x_stand[3:6], atol=5e-3)
    np.testing.assert_allclose(final[0:3], 0.0, atol=5e-3)
    np.testing.assert_allclose(final[6:12], 0.0, atol=2e-2)
    # at rest the feet carry the weight
    assert fs[-1][:, 2].sum() == pytest.approx(MASS * 9.81, rel=0.02)
    assert np.median(mpc.solve_times) < 0.05


@pytest.mark.parametrize("solver", QP_SOLVERS)
def test_friction_pyramid_and_bounds_hold(solver):
    cfg = MPCConfig(mu=0.3, fz_max=120.0, solver=solver)
    mpc = ConvexMPC(MASS, INERTIA, cfg)
    x0 = srb_state(np.zeros(3), np.array([0.0, 0.0, 0.28]), np.zeros(3), np.zeros(3))
    # demand a hard sideways-forward lunge and a jump: constraints must bind
    x_ref = np.tile(x0, (cfg.horizon, 1))
    x_ref[:, 3], x_ref[:, 4], x_ref[:, 5] = 0.3, -0.2, 0.45
    x_ref[:, 9], x_ref[:, 10], x_ref[:, 11] = 2.0, -1.5, 2.0
    contact = np.ones((cfg.horizon, 4))
    contact[:, 1] = 0  # FL off the ground all along
    contact[5:, 2] = 0  # RR lifts halfway through
    res = mpc.solve(x0, x_ref, FEET - x0[3:6], contact)
    plan = res.plan
    assert res.status == "solved"
    fz = plan[..., 2]
    assert np.all(fz >= -1e-9) and np.all(fz <= cfg.fz_max + 1e-9)
    assert np.all(np.abs(plan[..., 0]) <= cfg.mu * fz + 1e-9)
    assert np.all(np.abs(plan[..., 1]) <= cfg.mu * fz + 1e-9)
    assert np.all(plan[:, 1] == 0.0) and np.all(plan[5:, 2] == 0.0)
    # the pyramid binds somewhere (the demand is beyond it)
    assert np.max(np.abs(plan[..., 0]) / np.maximum(fz, 1e-9)) > 0.95 * cfg.mu


@pytest.mark.parametrize("solver", QP_SOLVERS)
def test_solvers_match_a_dense_solve(solver):
    cfg = MPCConfig(horizon=3, dt=0.03, mu=0.5, fz_max=80.0, eps_abs=1e-8, eps_rel=1e-8,
                    max_iter=20000, solver=solver)
    mpc = ConvexMPC(MASS, INERTIA, cfg)
    x0 = srb_state(np.array([0.02, -0.05, 0.1]), np.array([0.0, 0.0, 0.27]),
                   np.array([0.2, -0.1, 0.0]), np.array([0.1, 0.0, -0.2]))
    x_ref = np.tile(srb_state(np.array([0.0, 0.0, 0.1]), np.array([0.05, 0.0, 0.30]),
                              np.zeros(3), np.array([0.8, 0.0, 0.6])), (3, 1))
    contact = np.ones((3, 4))
    contact[2, 0] = 0
    r = FEET - x0[3:6]
    res = mpc.solve(x0, x_ref, r, contact, yaw=0.1)
    H, g = mpc.condensed_qp(x0, x_ref, r, 0.1)
    # the same problem, dense, by scipy: friction rows and bounds as linear inequalities
    n = 36
    G = []
    for k in range(12):
        for comp in (0, 1):
            for s in (1.0, -1.0):
                row = np.zeros(n)
                row[3 * k + comp], row[3 * k + 2] = s, -cfg.mu
                G.append(row)
    G = np.array(G)
    c = contact.reshape(-1)
    bounds = []
    for k in range(12):
        bounds += [(None, None), (None, None), (0.0, cfg.fz_max * c[k])]
    dense = scipy.optimize.minimize(
        lambda u: 0.5 * u @ H @ u + g @ u, np.zeros(n), jac=lambda u: H @ u + g,
        method="SLSQP", bounds=bounds,
        constraints=[{"type": "ineq", "fun": lambda u: -G @ u, "jac": lambda u: -G}],
        options={"ftol": 1e-12, "maxiter": 1000})
    assert dense.success
    u = res.plan.reshape(-1)
    scale = np.max(np.abs(dense.x))
    np.testing.assert_allclose(u, dense.x, atol=2e-3 * scale)
    cost = lambda u: 0.5 * u @ H @ u + g @ u  # noqa: E731
    assert cost(u) == pytest.approx(cost(dense.x), rel=1e-4, abs=1e-6)


def _lunge(cfg: MPCConfig, rng: np.random.Generator):
    """A demanding problem: off-level start, a reference far away, some feet off the ground."""
    x0 = srb_state(rng.normal(0, 0.05, 3), np.array([0.0, 0.0, 0.27]) + rng.normal(0, 0.01, 3),
                   rng.normal(0, 0.2, 3), rng.normal(0, 0.2, 3))
    x_ref = np.tile(srb_state(np.zeros(3), np.array([0.2, 0.05, 0.4]), np.zeros(3),
                              np.array([1.5, 0.2, 1.8])), (cfg.horizon, 1))
    contact = np.ones((cfg.horizon, 4))
    contact[cfg.horizon // 2:, rng.integers(0, 4)] = 0.0
    contact[-2:] = 0.0
    return x0, x_ref, FEET - x0[3:6] + rng.normal(0, 0.01, (4, 3)), contact


def test_quick_condensed_form_is_the_condensed_qp():
    # H and g from the kept per-yaw parts (one compiled call) equal those stacked from A^i B
    mpc = ConvexMPC(MASS, INERTIA + 0.01 * np.ones((3, 3)), MPCConfig(solver="daqp"))
    rng = np.random.default_rng(3)
    for yaw in (0.0, 0.4, -1.2):
        x0, x_ref, r, _ = _lunge(mpc.config, rng)
        H, g = mpc.condensed_qp(x0, x_ref, r, yaw)
        H2, g2 = mpc.condensed_form(yaw).qp(mpc._input_map(r, yaw)[MOVING], x0, x_ref, mpc.config.alpha)
        np.testing.assert_allclose(H2, H, rtol=0, atol=1e-12 * np.abs(H).max())
        np.testing.assert_allclose(g2, g, rtol=0, atol=1e-12 * np.abs(g).max())
        assert np.array_equal(H2, H2.T)


def test_daqp_reaches_the_optimum_osqp_approaches():
    # the same QPs: DAQP's forces cost no more than OSQP's (which stop at 1e-3), the feet off the
    # ground carry exactly nothing, and a warm start from the last active set changes nothing
    rng = np.random.default_rng(7)
    osqp_mpc, daqp_mpc = ConvexMPC(MASS, INERTIA), ConvexMPC(MASS, INERTIA, MPCConfig(solver="daqp"))
    for _ in range(6):
        x0, x_ref, r, contact = _lunge(osqp_mpc.config, rng)
        a = osqp_mpc.solve(x0, x_ref, r, contact).plan.reshape(-1)
        res = daqp_mpc.solve(x0, x_ref, r, contact)
        b = res.plan.reshape(-1)
        assert res.status == "solved"
        H, g = osqp_mpc.condensed_qp(x0, x_ref, r, 0.0)
        cost = lambda u: 0.5 * u @ H @ u + g @ u  # noqa: E731
        assert cost(b) <= cost(a) + 1e-9 * abs(cost(a))
        assert np.all(res.plan[contact == 0.0] == 0.0)
        cold = ConvexMPC(MASS, INERTIA, MPCConfig(solver="daqp")).solve(x0, x_ref, r, contact).plan
        np.testing.assert_allclose(res.plan, cold, atol=1e-6 * np.abs(cold).max())


def test_unknown_solver_is_refused():
    with pytest.raises(ValueError, match="MPC solver must be one of"):
        MPCConfig(solver="qpoases")


def test_condensed_prediction_matches_stepping():
    Ac, Bc = continuous_dynamics(MASS, INERTIA, 0.0, FEET - [0, 0, 0.28])
    A, B = discretize(Ac, Bc, 0.02)
    Aqp, Bqp = condense(A, B, 4)
    rng = np.random.default_rng(0)
    x0 = np.append(rng.normal(size=12), 9.81)
    U = rng.normal(size=(4, 12))
    x, xs = x0, []
    for k in range(4):
        x = A @ x + B @ U[k]
        xs.append(x)
    np.testing.assert_allclose(Aqp @ x0 + Bqp @ U.ravel(), np.concatenate(xs), atol=1e-10)
