"""Planning command: ``jump`` (a pronk or froggy jump to a target planned with a model, executed in simulation,
open or closed loop, in a nominal or disturbed world)."""

from pathlib import Path
from typing import Annotated

import typer

from symrom.cli.common import ENGINE_HELP, Command, Force, app, console, guarded, say, warn


@app.command("jump", cls=Command)
@guarded
def jump_cmd(
    target_x: Annotated[float, typer.Option(
        "--target-x", help="Forward landing distance from the start of the push, m.")],
    out: Annotated[Path, typer.Option("--out", help="Output directory (landing.json, trajectory.json).")],
    model_path: Annotated[Path | None, typer.Argument(
        help="The planner's model: model.json (learned) or an aSLIP params.json (aslip, from symrom aslip); "
             "point-mass needs none.")] = None,
    robot: Annotated[str | None, typer.Option("--robot", help="Robot: go1, a1, laikago or a description PATH.toml "
                                                 "(default: the learned model's robot, else go1).")] = None,
    target_z: Annotated[float | None, typer.Option(
        "--target-z", help="Apex height of the base, m (default: at least the motion's nominal apex).")] = None,
    planner: Annotated[str, typer.Option("--planner", help="learned, point-mass or aslip.")] = "learned",
    guards: Annotated[str, typer.Option("--guards", help="height (lift-off and touchdown heights) "
                                        "or learned (the model's own contact switches; learned planner).")] = "height",
    engine: Annotated[str, typer.Option("--engine", help=ENGINE_HELP)] = "pybullet",
    control: Annotated[str | None, typer.Option(
        "--control", help="plan (the push planned once, open loop) or mpc (re-planned from the measured state at "
                          "--replan-hz); default: plan on the model's own robot, mpc on another robot "
                          "of its build.")] = None,
    replan_hz: Annotated[float, typer.Option(
        "--replan-hz", help="How often mpc re-plans the rest of the push, Hz (100 or faster).")] = 100.0,
    motion: Annotated[str | None, typer.Option(
        "--motion", help="pronk or froggy (default: the model's; point-mass and aslip: pronk).")] = None,
    payload: Annotated[float, typer.Option("--payload", help="A load fixed to the base, kg (a disturbance).")] = 0.0,
    friction: Annotated[float | None, typer.Option(
        "--friction", help="The ground's friction coefficient (a disturbance; default the engine's).")] = None,
    motor_scale: Annotated[float, typer.Option(
        "--motor-scale", help="Torque each motor delivers per unit of its command (a disturbance).")] = 1.0,
    disturbance_gain: Annotated[float | None, typer.Option(
        "--disturbance-gain", help="mpc: estimate what the model lacks of the world, taking up this share (0-1) of "
                                   "each re-plan's missed acceleration (default 0: none).")] = None,
    closest: Annotated[bool, typer.Option(
        "--closest", help="Plan the closest reachable jump to a target out of reach (else refused).")] = False,
    trajectory: Annotated[bool, typer.Option(
        "--trajectory/--no-trajectory", help="Also write trajectory.json.")] = True,
    force: Force = False,
) -> None:
    """Plan a jump to a target with a model (CasADi/IPOPT) and execute it in simulation, open or closed loop."""
    import importlib.util

    from symrom.atomic import check_output_file

    if importlib.util.find_spec("casadi") is None:
        raise ValueError("symrom jump plans with CasADi and IPOPT, which are not installed: "
                         "pip install 'symrom[export]'")
    from symrom.plan.jump import JumpRequest, OutOfReach, run_jump

    check_output_file(out, force, inputs=() if model_path is None else (model_path,))
    req = JumpRequest(target_x, target_z, robot, planner, model_path, guards, engine, control, motion, payload,
                      friction, motor_scale, closest, replan_hz, disturbance_gain)
    with console.status(f"planning and simulating a jump to x = {target_x} m ({engine})"):
        try:
            result = run_jump(req, out, trajectory=trajectory, force=force)
        except OutOfReach as e:
            raise ValueError(f"{e}; --closest plans the closest reachable jump") from None
    ex = result.execution
    if result.apex_rule == "at least reachable" and result.apex_floor is not None:
        warn(f"no plan holds the apex at the motion's nominal height within the torque limits; held at or above "
             f"{result.apex_floor:.3f} m instead (--target-z sets it)")
    if not result.reachable:
        warn(f"the target is out of the {planner} planner's reach; planned the closest reachable jump, "
             f"x = {ex.plan.landing_x:.3f} m, apex {ex.plan.apex_z:.3f} m")
    if not ex.upright:
        r = ex.rest
        warn(f"the robot fell after landing: at the end its base is {r['z']:.3f} m high, roll {r['roll']:+.2f} rad, "
             f"pitch {r['pitch']:+.2f} rad")
    loop = ""
    if ex.replans is not None and ex.replans.solve_time_s:
        times = sorted(ex.replans.solve_time_s)
        loop = f", {len(times)} re-plans ({1e3 * times[len(times) // 2]:.2f} ms median)"
    say(f"{planner} {result.control} ({1e3 * ex.plan.solve_time_s:.1f} ms plan{loop}): "
        f"landed at x = {ex.landing_x:.3f} m "
        f"for a target of {target_x:.3f} m (error {100 * result.error_x:+.1f} cm), apex {ex.apex_z:.3f} m; "
        f"{out / 'landing.json'}")
