"""Planning command: ``jump`` (a pronk to a target planned with a model, executed in simulation)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from symrom.cli.common import ENGINE_HELP, Command, Force, app, console, guarded, say, warn


@app.command("jump", cls=Command)
@guarded
def jump_cmd(
    target_x: Annotated[float, typer.Option("--target-x", help="Forward landing distance from the start of the push, m.")],
    out: Annotated[Path, typer.Option("--out", help="Output directory (landing.json, trajectory.json).")],
    model_path: Annotated[Optional[Path], typer.Argument(
        help="The planner's model: model.json (learned) or an aSLIP params.json (aslip, from symrom aslip); "
             "point-mass needs none.")] = None,
    robot: Annotated[str, typer.Option("--robot", help="Robot: go1, a1, laikago or a description PATH.toml.")] = "go1",
    target_z: Annotated[Optional[float], typer.Option("--target-z", help="Apex height of the base, m (default: at least the pronk's nominal apex).")] = None,
    planner: Annotated[str, typer.Option("--planner", help="learned, point-mass or aslip.")] = "learned",
    guards: Annotated[str, typer.Option("--guards", help="height (lift-off and touchdown at the take-off height) "
                                        "or learned (the model's own contact switches; learned planner).")] = "height",
    engine: Annotated[str, typer.Option("--engine", help=ENGINE_HELP)] = "pybullet",
    trajectory: Annotated[bool, typer.Option("--trajectory/--no-trajectory", help="Also write trajectory.json.")] = True,
    force: Force = False,
) -> None:
    """Plan a pronk to a target with a model (CasADi/IPOPT) and execute it in simulation."""
    import importlib.util

    from symrom.atomic import check_output_file
    from symrom.sim.engines.registry import check_engine

    if importlib.util.find_spec("casadi") is None:
        raise ValueError("symrom jump plans with CasADi and IPOPT, which are not installed: pip install 'symrom[export]'")
    from symrom.plan.jump import PLANNERS, jump, make_planner, read_aslip_params, write_landing

    if planner not in PLANNERS:
        raise ValueError(f"--planner must be one of {', '.join(PLANNERS)}, got {planner!r}")
    check_engine(engine)
    if planner == "point-mass" and model_path is not None:
        raise ValueError(f"the point-mass planner uses no model: leave {model_path} out (or plan with --planner "
                         "learned or aslip)")
    if planner != "point-mass" and model_path is None:
        raise ValueError(f"the {planner} planner needs its model: "
                         + ("model.json" if planner == "learned" else "an aSLIP params.json (symrom aslip)"))
    check_output_file(out, force, inputs=() if model_path is None else (model_path,))
    model = aslip = None
    if planner == "learned":
        from symrom.model.persistence import load_model

        model = load_model(model_path)
    elif planner == "aslip":
        aslip = read_aslip_params(model_path)
    with console.status(f"building the {planner} planner"):
        built = make_planner(planner, robot, model=model, aslip=aslip, guards=guards)
    with console.status(f"planning and simulating a jump to x = {target_x} m ({engine})"):
        result = jump(built, target_x, target_z, engine=engine)
    write_landing(out, result, trajectory=trajectory, force=force)
    ex = result.execution
    if not result.reachable:
        warn(f"x = {target_x} m is out of the {planner} model's reach under the force, friction and stance bounds; "
             f"the closest plan lands at {ex.plan.landing_x:.3f} m")
    say(f"{planner} plan ({1e3 * ex.plan.solve_time_s:.1f} ms): landed at x = {ex.landing_x:.3f} m for a target of "
        f"{target_x:.3f} m (error {100 * result.error_x:+.1f} cm), apex {ex.apex_z:.3f} m; {out / 'landing.json'}")
