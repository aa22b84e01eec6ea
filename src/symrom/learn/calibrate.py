"""Calibration: fine-tuning that adapts what a few new jumps determine and keeps the rest.

With a dozen jumps, relearning every coefficient (fine-tuning ``acceleration``) or
refining all of them on rollouts (``rollout``) fits the new jumps with equations
that lose the source's physics (a flight phase falling at 4 m/s^2). ``calibrate``
keeps the encoder, every phase's term support (but for two calibration terms,
below) and every coefficient of the source, and fits per phase k and latent
equation j at most three numbers:

    ddxi_j = Theta Xi_kj + (g_kj - 1) * Theta_in Xi_kj,in + o_kj + d_kj * dxi_j

- g_kj, a gain on the equation's input terms (every active term holding a
  latent input nu): joint gains, a torque scale or reflected rotor inertia
  change how strongly the drive accelerates the latent state;
- o_kj, added to the equation's constant (a torque bias, a different preload);
- d_kj, added to the coefficient of the equation's own velocity dxi_j (joint
  damping).

The gain exists only where the source's equation has input terms. The offset and
the damping exist in every equation of every non-flight phase (``terms="every"``,
the default): where the source's equation lacks the constant ``1`` or its own
velocity ``dxi_j``, the term is added to the support as a calibration term
(``offset_added``, ``damping_added`` in the record; it shows in the equations). On
one robot a torque bias and joint damping act in every stance equation, and a
source trained on simulation may have neither in an equation (its forward
equation was the input alone), so they could not be fitted otherwise; chosen on
the sim-to-real targets' val jumps (docs/results.md). ``terms="support"`` fits
them only where the source has the term, adding nothing. The parameters are
the least squares fit to the new rows' latent accelerations (the encoder is the
source's, so these are the data's own), pulled towards the source (g = 1,
o = d = 0) by a ridge of ``prior_weight`` times each column's sum of squares.
It is closed form, and works for any source: refined or not, any encoder,
any library.

The flight phase (a phase named ``flight``) holds gravity, a physical constant:
it is kept bit for bit unless the new rows clearly contradict it. The statistic
is the decoded base vertical acceleration residual of the source's flight
equations on the new flight rows, r = (W_d (ddxi - ddxi_source))_z, averaged per
jump: its mean m over the jumps and standard error se. The data contradict the
source when |m| > ``FLIGHT_TOLERANCE`` g (5 %, the accuracy the physics asks
for) and |m| > ``FLIGHT_T`` se (3: not a few noisy jumps); only then is the
flight phase calibrated too. ``flight_gravity`` reports the outcome: the mean
over the new flight rows of the model's decoded base acceleration in z, m/s^2
(about -g for a model that kept its physics), beside the data's own.
"""

from __future__ import annotations

import numpy as np

from symrom.data.dataset import Dataset
from symrom.model.autoencoder import LinearAutoencoder
from symrom.model.hybrid import HybridModel, ModelDataError
from symrom.names import FLIGHT_PHASE, GRAVITY, Q_NAMES

FLIGHT_TOLERANCE = 0.05  # of g: the flight residual that would move gravity by more than 5 %
FLIGHT_T = 3.0  # standard errors (over jumps) the flight residual must also exceed
CALIBRATION_TERMS = ("support", "every")  # where an offset and a damping are fitted (``calibrate``)
Z = Q_NAMES.index("z")


class CalibrationError(ModelDataError):
    """The source has nothing calibration can adapt; the message names what would work."""


def input_terms(model: HybridModel) -> np.ndarray:
    """(p,) bool: the library terms that hold a latent input nu."""
    return np.array(["nu" in name for name in model.library.feature_names])


def _phase_rows(model: HybridModel, ds: Dataset, rows: np.ndarray, name: str) -> np.ndarray:
    return rows & (ds.phase == ds.phase_names.index(name)) if name in ds.phase_names else np.zeros_like(rows)


def latent_terms(model: HybridModel, ae: LinearAutoencoder, ds: Dataset,
                 rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Theta (N, p), dxi (N, l) and the latent accelerations ddxi (N, l) of ``rows``."""
    xi, dxi, nu = ae.encode(ds.q[rows]), ae.encode_derivative(ds.dq[rows]), ae.encode_input(ds.u[rows])
    return model.library.transform(xi, dxi, nu), dxi, ae.encode_derivative(ds.ddq[rows])


def flight_residual(model: HybridModel, ae: LinearAutoencoder, ds: Dataset, rows: np.ndarray) -> dict | None:
    """The flight test (module docstring) on ``rows``: ``mean`` and ``se`` (m/s^2) of the
    per-jump decoded z acceleration residual, ``jumps``, ``contradicted`` and the limits;
    None when the model has no flight phase or the rows hold none."""
    if FLIGHT_PHASE not in model.phase_names:
        return None
    r = _phase_rows(model, ds, rows, FLIGHT_PHASE)
    if not r.any():
        return None
    theta, _, ddxi = latent_terms(model, ae, ds, r)
    resid = (ddxi - theta @ model.Xi[model.phase_names.index(FLIGHT_PHASE)]) @ ae.W_d[Z]  # (N,) m/s^2
    jumps = ds.jump[r]
    per_jump = np.array([resid[jumps == j].mean() for j in np.unique(jumps)])
    m = float(per_jump.mean())
    se = float(per_jump.std(ddof=1) / np.sqrt(per_jump.size)) if per_jump.size > 1 else float("inf")
    limit = FLIGHT_TOLERANCE * GRAVITY
    # se None for a single jump (no spread to judge by; the model file holds no infinity)
    return {"mean": m, "se": se if np.isfinite(se) else None, "jumps": int(per_jump.size), "limit": limit,
            "t_limit": FLIGHT_T, "contradicted": bool(abs(m) > limit and abs(m) > FLIGHT_T * se)}


def flight_gravity(model: HybridModel, ds: Dataset, rows: np.ndarray) -> dict | None:
    """On the flight rows among ``rows``: the mean decoded base z acceleration of ``model``'s
    flight equations (``model``, m/s^2), of the data (``data``) and the model's as a fraction
    of -g (``ratio``, 1 = gravity kept); None without flight rows."""
    if FLIGHT_PHASE not in model.phase_names:
        return None
    r = _phase_rows(model, ds, rows, FLIGHT_PHASE)
    if not r.any():
        return None
    theta, _, _ = latent_terms(model, model.autoencoder, ds, r)
    acc = float(np.mean(theta @ model.Xi[model.phase_names.index(FLIGHT_PHASE)] @ model.autoencoder.W_d[Z]))
    return {"model": acc, "data": float(np.mean(ds.ddq[r, Z])), "ratio": -acc / GRAVITY}


def calibrate(model: HybridModel, ae: LinearAutoencoder, ds: Dataset, rows: np.ndarray,
              prior_weight: float, terms: str = "every") -> tuple[np.ndarray, np.ndarray, dict]:
    """The calibrated coefficients Xi (P, p, l) and support mask (P, p, l) of ``model`` on
    ``rows`` (N,) bool of ``ds``, with the (kept) encoder of ``ae``, and the record: per phase
    its rows, whether it was calibrated and its ``gain``, ``offset`` and ``damping`` per latent
    equation (None where the equation lacks the term), ``offset_added`` and ``damping_added``
    (the calibration terms, below); the flight test; ``terms``; ``parameters``, how many
    were fitted.

    terms: ``support``, an offset and a damping only where the source's equation has the
    constant ``1`` and its own velocity ``dxi_j``; ``every``, both in every equation of every
    calibrated non-flight phase, the term added to the support where the source lacks it (a
    calibration term: a torque bias and joint damping act in every contact equation)."""
    if terms not in CALIBRATION_TERMS:
        raise ValueError(f"calibration terms must be one of {CALIBRATION_TERMS}, got {terms!r}")
    names = model.library.feature_names
    inputs = input_terms(model)
    one = names.index("1") if "1" in names else None
    flight = flight_residual(model, ae, ds, rows)
    Xi, mask = model.Xi.copy(), model.mask.copy()
    record: dict = {"phases": {}, "flight_test": flight}
    fitted = 0
    for k, name in enumerate(model.phase_names):
        r = _phase_rows(model, ds, rows, name)
        entry: dict = {"rows": int(r.sum()), "calibrated": False}
        record["phases"][name] = entry
        if not r.any():
            entry["why"] = "no rows"
            continue
        if name == FLIGHT_PHASE and not (flight and flight["contradicted"]):
            entry["why"] = "gravity kept: the rows do not contradict the source's flight equations"
            continue
        theta, dxi, ddxi = latent_terms(model, ae, ds, r)
        gains, offs, damping, added, added_d = [], [], [], [], []
        every = terms == "every" and name != FLIGHT_PHASE
        for j in range(model.latent_dim):
            act = model.mask[k, :, j]
            cols, kinds = [], []
            if (act & inputs).any():
                cols.append(theta[:, act & inputs] @ model.Xi[k, act & inputs, j])
                kinds.append("gain")
            add = every and one is not None and not act[one]
            if one is not None and (act[one] or add):
                cols.append(np.ones(theta.shape[0]))
                kinds.append("offset")
            vel = f"dxi{j + 1}"
            add_d = every and vel in names and not act[names.index(vel)]
            if vel in names and (act[names.index(vel)] or add_d):
                cols.append(dxi[:, j])
                kinds.append("damping")
            found = {"gain": None, "offset": None, "damping": None}
            if cols:
                X = np.column_stack(cols)
                y = ddxi[:, j] - theta @ model.Xi[k, :, j]
                gram = X.T @ X
                keep = np.diag(gram) > 1e-12 * max(np.diag(gram).max(), 1e-300)  # a column that never moves
                p = np.zeros(len(cols))
                if keep.any():
                    G = gram[np.ix_(keep, keep)]
                    p[keep] = np.linalg.solve(G + prior_weight * np.diag(np.diag(G)), X[:, keep].T @ y)
                new = {"offset": add, "damping": add_d}
                for kind, v, moves in zip(kinds, p, keep):  # a term to add that never moves here is not added
                    found[kind] = None if new.get(kind) and not moves else float(v)
                if found["gain"] is not None:
                    Xi[k, act & inputs, j] *= 1.0 + found["gain"]
                    found["gain"] = 1.0 + found["gain"]
                if found["offset"] is not None:
                    Xi[k, one, j] += found["offset"]
                    mask[k, one, j] = True
                if found["damping"] is not None:
                    Xi[k, names.index(vel), j] += found["damping"]
                    mask[k, names.index(vel), j] = True
                fitted += sum(v is not None for v in found.values())
            gains.append(found["gain"])
            offs.append(found["offset"])
            damping.append(found["damping"])
            added.append(bool(add and found["offset"] is not None))
            added_d.append(bool(add_d and found["damping"] is not None))
        entry.update(calibrated=True, gain=gains, offset=offs, damping=damping, offset_added=added,
                     damping_added=added_d)
    record["terms"] = terms
    record["parameters"] = fitted
    return Xi, mask, record


def nothing_to_adapt() -> CalibrationError:
    """The refusal when calibration would change nothing (no parameter, decoder kept)."""
    return CalibrationError(
        "calibration has nothing to adapt: the fine-tuning rows hold no phase whose equations have an input "
        "term, a constant or their own velocity term (a flight phase keeps its gravity), and the decoder is "
        "kept; refit the decoder (not refit_decoder=False), or use method='calibrate_rollout' (the non-flight "
        "phases refined on rollouts, the flight kept), method='acceleration' (every coefficient, pulled towards "
        "the source) or method='rollout'")
