"""Reference models a learned model is compared with, each a ``Rollable``: the aSLIP
(``aslip``) and Newton's law on the measured ground force (``newton``), as it is and with
its gains fitted (``AffineForce``).

One idiom makes each: ``Baseline.fit(ds, rows=None, m=None)`` (``Newton.fit``,
``AffineForce.fit``, ``ASlip.fit``), fitted on the train split; ``to_dict()`` is its
``params.json`` (one format for every baseline, ``PARAMS_VERSION``) and ``from_params``
reads one back. ``fit_baseline`` makes the baselines by their names in a run
(``BASELINES``).
"""

from __future__ import annotations

from symrom.rollout.system import Rollable

# The baselines of a run by name: (title, how it is made).
BASELINES: dict[str, str] = {
    "aslip": "aSLIP (residual fit)",
    "aslip_rollout": "aSLIP (rollout fit)",
    "newton": "Newton, b'' = g + F/m",
    "newton_fitted": "Newton fitted, b'' = c + A F/m",
}


def fit_baseline(name: str, ds, rows=None, m: float | None = None):
    """The baseline ``name`` (``BASELINES``) fitted on ``rows`` (N,) bool of ``ds`` (default: its
    train split), mass ``m`` kg (default: the robot's)."""
    from symrom.baselines.aslip import ASlip
    from symrom.baselines.newton import AffineForce, Newton

    if name == "newton":
        return Newton.fit(ds, rows, m)
    if name == "newton_fitted":
        return AffineForce.fit(ds, rows, m)
    if name in ("aslip", "aslip_rollout"):
        return ASlip.fit(ds, rows, m, objective="rollout" if name == "aslip_rollout" else "residual")
    raise ValueError(f"baseline {name!r}: not one of {', '.join(BASELINES)}")


def from_params(params: dict) -> Rollable | None:
    """The baseline a ``params.json`` describes (``model``: ``aslip`` with k_s, l_0, m, or
    ``newton`` with m, ``affine_force`` with m, A, c, c_f); files without ``model`` but with the
    aSLIP's three numbers are an aSLIP. None if the parameters describe neither."""
    from symrom.baselines.aslip import ASlip, ASlipParams
    from symrom.baselines.newton import AffineForce, Newton

    kind = params.get("model", "aslip" if all(k in params for k in ("k_s", "l_0", "m")) else None)
    source = str(params.get("source", "given"))
    try:
        if kind == "aslip":
            return ASlip(ASlipParams(*(float(params[k]) for k in ("k_s", "l_0", "m"))), source,
                         tuple(params.get("stages", ())))
        if kind == "newton":
            return Newton(float(params["m"]), source)
        if kind == "affine_force":
            return AffineForce(float(params["m"]), params["A"], params["c"], params["c_f"], source)
    except (KeyError, TypeError, ValueError):
        return None
    return None
