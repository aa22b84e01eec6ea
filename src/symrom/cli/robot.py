"""Robot description commands: ``robot init`` (a checked description from a robot model alone)
and ``robot show`` (a description as symrom reads it)."""

from pathlib import Path
from typing import Annotated

import typer

from symrom.cli.common import Command, Force, Group, app, guarded, out_console, say

robot_app = typer.Typer(cls=Group, add_completion=False, no_args_is_help=True, rich_markup_mode=None,
                        help="Robot descriptions: write one from a robot model, show one as symrom reads it.")
app.add_typer(robot_app, name="robot")


def parse_sets(items: list[str] | None) -> dict:
    """--set KEY=VALUE (VALUE in TOML: 0.3, [23.7, 23.7, 35.55], "go1") -> {KEY: value}."""
    import tomllib

    out = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        try:
            if not sep:
                raise tomllib.TOMLDecodeError("no '='")
            out[key.strip()] = tomllib.loads(f"v = {value.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            raise ValueError(f"--set {item!r}: expected KEY=VALUE with a TOML value, e.g. "
                             f"stance.knee=[-2.8, -0.3]") from None
    return out


@robot_app.command("init", cls=Command)
@guarded
def robot_init_cmd(
    model: Annotated[Path, typer.Argument(
        help="Robot model: an MJCF (.xml; e.g. a MuJoCo Menagerie model) or a URDF (.urdf).")],
    out: Annotated[Path, typer.Option("--out", help="Robot description to write (.toml).")],
    name: Annotated[str | None, typer.Option("--name", help="The robot's name (default: the model's).")] = None,
    sets: Annotated[list[str] | None, typer.Option(
        "--set", help="KEY=VALUE: a description key the model cannot give (stance.knee, stance.height, "
                      "stance.joints, limits.torque, actuators.*, name), VALUE in TOML; repeatable.")] = None,
    force: Force = False,
) -> None:
    """Write a checked robot description from a robot model alone."""
    from symrom.robots.init import RobotInitError, init_robot

    try:
        r = init_robot(model, out, name=name, overrides=parse_sets(sets), force=force)
    except RobotInitError as e:
        if e.key is None:
            raise
        raise RobotInitError(f"{e} (--set {e.key}=VALUE)", e.key) from None
    d = r.description
    say(f"wrote {r.path}: {d.name}, {d.mass:.3f} kg, feet {d.feet.kind if d.feet else 'link'}, "
        f"kinematics within {r.kinematics_error:.1e} m of MuJoCo's"
        + (f"; given: {', '.join(r.given)}" if r.given else ""))


@robot_app.command("show", cls=Command)
@guarded
def robot_show_cmd(
    robot: Annotated[str, typer.Argument(
        help="A built-in robot (go1, a1, laikago) or a robot description file (.toml).")],
) -> None:
    """Print a robot description as symrom reads it: legs, joints, feet, masses, limits, stance."""
    from rich.table import Table

    from symrom.robots.show import robot_summary

    s = robot_summary(robot)
    model = f"{s.model}" + (f" (URDF derived: {s.urdf})" if s.urdf_derived else "")
    for line in (f"{s.name}: {s.source} (format {s.format})", f"model: {model}",
                 f"base {s.base_link!r}; mass {s.mass:.3f} kg (base {s.base_mass:.3f} kg, legs "
                 f"{', '.join(f'{leg.mass:.3f}' for leg in s.legs)}); foot radius {s.foot_radius:g} m; "
                 f"leg length {s.leg_length:.4f} m; standing height {s.start_height:g} m"):
        say(line)
    table = Table("leg", "joint", "name", "sign", "range (rad)", "torque (N m)", "stance (rad)", "damping",
                  "armature", "friction")
    a = s.actuators
    for k, leg in enumerate(s.legs):
        for r, role in enumerate(("hx", "hy", "kn")):
            i = 3 * k + r
            table.add_row(leg.leg if r == 0 else "", role, leg.joints[r], f"{leg.signs[r]:+d}",
                          f"[{leg.lower[r]:.3g}, {leg.upper[r]:.3g}]", f"{leg.torque[r]:g}", f"{leg.stance[r]:+.4f}",
                          f"{a.damping[i]:g}", f"{a.armature[i]:g}", f"{a.friction_loss[i]:g}")
    out_console.print(table)
    legs = Table("leg", "foot", "hip (m, base frame)", "thigh (m)", "calf (m)", "knee range (rad)")
    for leg in s.legs:
        legs.add_row(leg.leg, leg.foot, "(" + ", ".join(f"{x:+.4f}" for x in leg.hip) + ")", f"{leg.thigh:.4f}",
                     f"{leg.calf:.4f}", f"[{leg.knee_range[0]:g}, {leg.knee_range[1]:g}]")
    out_console.print(legs)
