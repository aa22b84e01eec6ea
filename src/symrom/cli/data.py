"""Data commands: ``generate`` (simulate jumps), ``import`` (robot logs), ``show`` (render a
jump), ``forces`` (torque-derived against the engine's ground force)."""

from pathlib import Path
from typing import Annotated

import typer

from symrom.cli.common import (
    ENGINE_HELP,
    WORKERS_HELP,
    Address,
    BackendName,
    Command,
    Force,
    app,
    console,
    flag_text,
    guarded,
    note,
    progress_bar,
    say,
    start_backend,
    warn,
)

_IMPORT_HELP = """Import robot logs into a checked dataset file.

LOGS: CSV files (Go1 hardware or plain layout), ROS 1 bags, ROS 2 bag
folders (sqlite3 or mcap storage) or MCAP files; the kind is read from
the content. Several files are consecutive jumps.

\b
CSV plain layout, SI units: jump (optional), t (s), fr_hx ... rl_kn,
  x y z (m), roll pitch yaw (rad, ZYX), d_<name>, dd_<name> (optional),
  tau_<joint> (N m), c_fr c_fl c_rr c_rl (0/1).
CSV hardware layout: Time; <leg>.<joint> Position|Velocity|
  Acceleration|Torque; Body linear|angular Position|Velocity|
  Acceleration x|y|z; <leg> Foot.
Bags (--topics or --mapping change the topics):
  joints=/joint_states: sensor_msgs/msg/JointState, matched by the
    URDF joint names, URDF sign convention;
  base=/odom: nav_msgs/msg/Odometry, pose in the world frame,
    twist in the base frame (ROS convention);
  contacts=/foot_contacts (optional): 4 values FR FL RR RL in data;
    without it, from the legs' vertical forces and foot heights.

Every log is checked against the robot (ranges; torque limits by
--torques) and against physics (velocities vs positions, stale rows,
vertical momentum vs weight, stance feet on the ground). A recording
holding several flights is cut into one jump per flight. --repair
first repairs what physics determines per jump: a wrong clock or
wrong velocities (the flight falls at g), a contact lag, a torque
gain (the weight), a base-height offset (the feet in contact).
Details: docs/import.md."""


@app.command("generate", cls=Command)
@guarded
def generate_cmd(
    robot: Annotated[str, typer.Option("--robot", help="go1, a1 or the path of a robot description file (.toml).")],
    motion: Annotated[str, typer.Option(
        "--motion", help="pronk (convex MPC) or froggy (Cartesian PD); both scale to any robot.")],
    jumps: Annotated[int, typer.Option("--jumps", help="Number of jumps.")],
    out: Annotated[Path, typer.Option("--out", help="Output dataset file (HDF5).")],
    noise: Annotated[bool, typer.Option("--noise", help="Noisy variant: start pose, readings, CoM pushes.")] = False,
    proxy: Annotated[bool, typer.Option("--proxy", help="Hardware-like robot (source=proxy; pronk, and froggy "
                                        "with a real froggy's long rear-only push).")] = False,
    log_faults: Annotated[str | None, typer.Option("--log-faults", help="Log the jumps with a real robot's "
                                                      "log faults: clock (a slow, wobbling loop) or velocities "
                                                      "(velocities off); both with torques off, a height "
                                                      "offset and a contact lag, drawn once from the seed.")] = None,
    randomize: Annotated[bool, typer.Option("--randomize", help="Domain-randomised source jumps: motion, "
                                            "masses, latency, friction, contact, joint damping, armature, "
                                            "friction loss and torque sensing drawn per jump (pronk).")] = False,
    engine: Annotated[str, typer.Option("--engine", help=ENGINE_HELP)] = "pybullet",
    mpc_solver: Annotated[str | None, typer.Option(
        "--mpc-solver", help="QP solver of pronk's MPC: osqp (ADMM, to 1e-3) or daqp (active set, exact, "
                             "faster); default: the engine's (osqp in PyBullet, daqp in MuJoCo).")] = None,
    split: Annotated[str | None, typer.Option(
        "--split", help="train,val,test counts (12,2,1) or fractions (0.8,0.1,0.1) of "
                        "the jumps; default: the motion's paper split, scaled.")] = None,
    workers: Annotated[int | None, typer.Option("--workers", help=WORKERS_HELP.format(local=1))] = None,
    seed: Annotated[int, typer.Option("--seed", help="Random seed.")] = 0,
    resume: Annotated[bool, typer.Option("--resume", help="Continue an interrupted run (OUT.parts).")] = False,
    backend: BackendName = "local",
    address: Address = None,
    force: Force = False,
) -> None:
    """Simulate jumps (PyBullet or MuJoCo), check them and write a dataset file."""
    import json

    from symrom.atomic import check_writable
    from symrom.data.io import check_dataset_path
    from symrom.execution import check_workers
    from symrom.robots import get_robot
    from symrom.sim.generation.generate import (
        GenerateConfig,
        NoiseConfig,
        check_config,
        check_output,
        generate,
        run_record_path,
    )

    check_dataset_path(out)
    check_output(out, resume, force)  # fail before connecting or drawing the progress bar
    check_writable(out)
    check_workers(workers)
    splits = None
    if split is not None and jumps >= 1:
        from symrom.data.importers import split_counts  # the import's modules only for --split

        splits = split_counts(split, jumps)
    config = check_config(GenerateConfig(robot, motion, jumps, seed=seed, proxy=proxy, randomize=randomize,
                                         noise=NoiseConfig() if noise else None, engine=engine,
                                         mpc_solver=mpc_solver, log_faults=log_faults,
                                         splits=splits))
    runner = start_backend(backend, workers, address)
    label = f"{get_robot(config.robot).name} {motion} ({engine})"
    with progress_bar(label, total=jumps) as bar:
        retries, lost = [0], [0]

        def _progress(done: int, total: int, info: dict) -> None:
            retries[0] += int(info.get("retries", 0))
            lost[0] += int(info.get("worker_retries", 0))
            extra = f" ({info['resumed']} resumed)" if info.get("resumed") else ""
            extra += f", {lost[0]} lost to dying workers" if lost[0] else ""
            bar.update(completed=done, total=total,
                       description=f"{label}: jump {done}/{total}, {retries[0]} retries{extra}")

        ds = generate(config, out, resume=resume, force=force, progress_callback=_progress, backend=runner)
    counts = {s: int((ds.split == s).sum()) for s in ("train", "val", "test")}
    record = json.loads(run_record_path(out).read_text())
    lost_note = (f"; {record['worker_retries']} attempt(s) lost to dying workers, run again"
                 if record["worker_retries"] else "")
    say(f"data: {out}  ({ds.n_jumps} jumps, {ds.n_samples} samples, {ds.generator['retries']} retries; "
        f"split {counts}){lost_note}\nrun record: {run_record_path(out)}")


@app.command("import", cls=Command, help=_IMPORT_HELP)
@guarded
def import_cmd(
    logs: Annotated[list[Path], typer.Argument(
        help="Log files: CSV, ROS 1 bag, ROS 2 bag folder or MCAP; several are concatenated as consecutive jumps.")],
    robot: Annotated[str, typer.Option(
        "--robot", help="Robot of the logs: go1, a1 or a robot description file (.toml); its URDF gives the wrench.")],
    out: Annotated[Path, typer.Option("--out", help="Output dataset file (HDF5).")],
    motion: Annotated[str, typer.Option(
        "--motion", help="Motion (pronk, froggy): its registry entry sets the phase rule.")] = "pronk",
    source: Annotated[str, typer.Option("--source", help="Source attribute of the dataset.")] = "hardware",
    split: Annotated[str | None, typer.Option(
        "--split", help="train,val,test counts (12,2,1) or fractions (0.8,0.1,0.1) of "
                        "the jumps after segmentation; default all train.")] = None,
    diff: Annotated[str, typer.Option(
        "--diff", help="savgol or central: differentiation where a log has no accelerations.")] = "savgol",
    diff_window: Annotated[float, typer.Option(
        "--diff-window", help="Differentiation (savgol) window, s: 0.018 is "
                              "9 samples at 500 Hz, 19 at 1 kHz.")] = 0.018,
    lenient: Annotated[bool, typer.Option(
        "--lenient", help="Report implausible values and failed physical checks "
                          "per file instead of refusing the import.")] = False,
    torques: Annotated[str, typer.Option(
        "--torques", help="measured or commanded: what the torque columns hold (commanded ones must stay within "
                          "the motor limit; measured ones within 1.25 x it); stored in the dataset.")] = "measured",
    physics: Annotated[bool, typer.Option(
        "--physics/--no-physics", help="Check the logs against physics (time scale, "
                                       "vertical momentum, stance foot height).")] = True,
    segment: Annotated[str, typer.Option(
        "--segment", help="auto: cut a jump holding several flights into one jump "
                          "per flight; off: keep jumps as logged.")] = "auto",
    retime_stale: Annotated[bool, typer.Option(
        "--retime-stale", help="Replace stale (repeated) rows by interpolation between "
                               "the fresh rows, each kept at its own time.")] = False,
    topics: Annotated[str | None, typer.Option(
        "--topics", help="Bag topics: joints=/joint_states,base=/odom,contacts=/foot_contacts (any subset).")] = None,
    mapping: Annotated[Path | None, typer.Option(
        "--mapping", help="TOML file with a [topics] table (joints, base, contacts); --topics overrides it.")] = None,
    dt: Annotated[float | None, typer.Option(
        "--dt", help="Sample period of the dataset, s (default: the coarsest "
                     "jump's period); other jumps are resampled.")] = None,
    max_gap: Annotated[float, typer.Option(
        "--max-gap", help="Longest gap (missing samples) bridged by "
                          "interpolation, s; longer ones are refused.")] = 0.01,
    no_resample: Annotated[bool, typer.Option(
        "--no-resample", help="Refuse jumps off the dataset's time grid instead of resampling them.")] = False,
    positions: Annotated[str, typer.Option(
        "--positions", help="auto, absolute or rebased: base positions that start at 0 in "
                            "each jump get their height back from the feet.")] = "auto",
    repair: Annotated[bool, typer.Option(
        "--repair", help="Repair each jump from physics before the checks: clock or velocities (by "
                         "the flight), contact lag, torque gain (by the weight), height offset (by "
                         "the feet); a fault the data cannot determine is refused.")] = False,
    period: Annotated[float | None, typer.Option(
        "--period", help="CSV logs without a time column: the nominal period of their rows, s (e.g. "
                         "0.002); with --repair the true clock is found from the flight.")] = None,
    force: Force = False,
) -> None:
    from symrom.data.bags import load_mapping, parse_topics
    from symrom.data.checks import PlausibilityLimits
    from symrom.data.consistency import ConsistencyLimits
    from symrom.data.importers import import_into
    from symrom.data.repair import RepairLimits
    from symrom.data.timebase import TimeBase

    time_base = TimeBase(dt=dt, max_gap=max_gap, resample=not no_resample)
    by_role = {**(load_mapping(mapping) if mapping else {}), **parse_topics(topics)}
    with console.status(f"importing {len(logs)} log file(s)"):
        ds, report = import_into(out, logs, force=force, robot=robot, motion=motion, source=source, split=split,
                                 diff_method=diff, lenient=lenient, time_base=time_base, positions=positions,
                                 limits=PlausibilityLimits(torques=torques),
                                 physics=ConsistencyLimits() if physics else None, segment=segment,
                                 retime=retime_stale, diff_window=diff_window, topics=by_role or None,
                                 repair=RepairLimits() if repair else None, period=period)
    for is_warning, line in report.messages():
        (warn if is_warning else note)(flag_text(line))
    say(f"dataset: {out}  ({ds.summary()})")


@app.command("show", cls=Command)
@guarded
def show_cmd(
    data: Annotated[Path, typer.Argument(help="Dataset file (HDF5).")],
    out: Annotated[Path, typer.Option("--out", help="Output directory for the PNG frames.")],
    jump: Annotated[int, typer.Option("--jump", help="Jump index.")] = 0,
    frames: Annotated[int, typer.Option("--frames", help="Number of frames.")] = 8,
    engine: Annotated[str, typer.Option("--engine", help=ENGINE_HELP + " MuJoCo needs OpenGL (EGL).")] = "pybullet",
    force: Force = False,
) -> None:
    """Render frames of one logged jump (replayed in PyBullet or MuJoCo) as PNG files."""
    from symrom.atomic import check_writable
    from symrom.data.io import read_dataset
    from symrom.sim.diagnostics.render import render_jump
    from symrom.sim.engines.registry import check_engine

    check_engine(engine)
    if out.exists() and any(out.glob(f"jump_{jump:04d}_t*.png")) and not force:
        raise FileExistsError(f"{out} already holds frames of jump {jump}; pass --force to overwrite them")
    check_writable(out, inside=True)
    ds = read_dataset(data)
    with console.status(f"rendering jump {jump}"):
        paths = render_jump(ds, jump, out, n_frames=frames, engine=engine)
    say(f"frames: {len(paths)} PNG in {out}")


@app.command("forces", cls=Command)
@guarded
def forces_cmd(
    data: Annotated[list[Path], typer.Argument(help="Simulated dataset files (HDF5) with contact_force.")],
) -> None:
    """The torque-derived ground force (the input u's) against the engine's own contact force."""
    from symrom.data.io import read_dataset
    from symrom.robots import get_robot
    from symrom.sim.diagnostics.forces import AXES, force_error

    for path in data:
        r = force_error(read_dataset(path))
        say(f"{path}: {get_robot(r.robot).name}, {r.engine}, {r.samples} samples, weight {r.weight:.1f} N")
        for name in AXES:
            a = r.axes[name]
            say(f"  F{name}: RMS error {a.rms:7.2f} N, peak error {a.peak:7.2f} N, correlation {a.corr:5.3f}, "
                f"peak torque-derived {a.peak_torque:7.1f} N vs engine {a.peak_engine:7.1f} N")
