"""Reference models a learned model is compared with, each a ``Rollable``: the aSLIP
(``aslip``) and Newton's law on the measured ground force (``newton``), as it is and with
its gains fitted (``affine_force``)."""

from __future__ import annotations

from symrom.rollout.system import Rollable


def from_params(params: dict) -> Rollable | None:
    """The baseline a ``params.json`` describes (``model``: ``aslip`` with k_s, l_0, m, or
    ``newton`` with m, ``affine_force`` with m, A, c, c_f); files without ``model`` but with the aSLIP's three numbers are an
    aSLIP. None if the parameters describe neither."""
    from symrom.baselines.aslip import ASlip, ASlipParams
    from symrom.baselines.newton import AffineForce, Newton

    kind = params.get("model", "aslip" if all(k in params for k in ("k_s", "l_0", "m")) else None)
    try:
        if kind == "aslip":
            return ASlip(ASlipParams(*(float(params[k]) for k in ("k_s", "l_0", "m"))))
        if kind == "newton":
            return Newton(float(params["m"]))
        if kind == "affine_force":
            return AffineForce(float(params["m"]), params["A"], params["c"], params["c_f"])
    except (KeyError, TypeError, ValueError):
        return None
    return None
