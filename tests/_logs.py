"""Robot logs made by the tests: simulated Go1 jumps written as CSV in the hardware and
plain layouts, at other rates, with jitter, gaps, unit mistakes or as rebased segments."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

from _simdata import reference_file, tmp_path
from symrom.data.io import read_dataset
from symrom.names import JOINT_NAMES, LEGS, Q_NAMES
from symrom.sim.generate import GenerateConfig, generate

# The published Go1 hardware layout, spelled out by hand.
HW_JOINTS = [n.replace("_", ".") for n in JOINT_NAMES]
HW_BODY = ["Body linear {} x", "Body linear {} y", "Body linear {} z",
           "Body angular {} x", "Body angular {} y", "Body angular {} z"]


def hw_columns(quantity: str) -> list[str]:
    return [f"{j} {quantity}" for j in HW_JOINTS] + [b.format(quantity) for b in HW_BODY]


@cache
def sim_go1():
    """Three simulated Go1 pronking jumps (500 Hz), shared with the simulation tests."""
    return read_dataset(reference_file("pronk"))


@cache
def proxy_go1(n_jumps: int = 6, seed: int = 11):
    """Hardware-like Go1 jumps (the proxy: other masses, latency, sensor noise), 500 Hz."""
    out = tmp_path("proxy.h5")
    return generate(GenerateConfig("go1", "pronk", n_jumps, seed=seed, proxy=True), out)


def jump(ds, j: int, rows: slice = slice(None)) -> dict[str, np.ndarray]:
    """Jump j of a dataset (optionally some of its rows, t restarted at 0) as log arrays."""
    a, b = ds.jump_bounds()[j]
    out = {k: getattr(ds, k)[a:b][rows].copy() for k in ("t", "q", "dq", "ddq", "tau", "contact")}
    out["t"] = out["t"] - out["t"][0]
    return out


def at_times(m: dict[str, np.ndarray], t_new: np.ndarray) -> dict[str, np.ndarray]:
    """The jump ``m`` sampled at other times (0 ... its end): continuous signals by a cubic
    spline through its samples (exact at them), contact flags by the previous sample."""
    t = m["t"]
    out = {"t": np.asarray(t_new, float)}
    for k in ("q", "dq", "ddq", "tau"):
        out[k] = CubicSpline(t, m[k], axis=0)(t_new)
    out["contact"] = m["contact"][np.clip(np.searchsorted(t, t_new + 1e-12, side="right") - 1, 0, len(t) - 1)]
    return out


def _cell(v: float, comma: bool) -> str:
    text = repr(float(v))
    return text.replace(".", ",") if comma else text


def write_hardware(path: Path, jumps: list[dict], accelerations: bool = True) -> Path:
    """The hardware layout: ';'-separated, decimal commas, Time restarting at every jump."""
    names = ["Time", *hw_columns("Position"), *hw_columns("Velocity")]
    if accelerations:
        names += hw_columns("Acceleration")
    names += [f"{j} Torque" for j in HW_JOINTS] + [f"{leg} Foot" for leg in LEGS]
    lines = [";".join(names)]
    for m in jumps:
        parts = [m["t"][:, None], m["q"], m["dq"]] + ([m["ddq"]] if accelerations else []) + [m["tau"]]
        table = np.concatenate(parts, axis=1)
        for row, flags in zip(table, m["contact"]):
            lines.append(";".join([_cell(v, True) for v in row] + [str(int(f)) for f in flags]))
    path.write_text("\n".join(lines) + "\n")
    return path


def write_plain(path: Path, jumps: list[dict], accelerations: bool = True) -> Path:
    """The plain layout: ',' and the dataset's names, with a jump column."""
    names = ["jump", "t", *Q_NAMES, *(f"d_{n}" for n in Q_NAMES)]
    if accelerations:
        names += [f"dd_{n}" for n in Q_NAMES]
    names += [f"tau_{n}" for n in JOINT_NAMES] + [f"c_{leg}" for leg in LEGS]
    lines = [",".join(names)]
    for j, m in enumerate(jumps):
        parts = [m["t"][:, None], m["q"], m["dq"]] + ([m["ddq"]] if accelerations else []) + [m["tau"]]
        table = np.concatenate(parts, axis=1)
        for row, flags in zip(table, m["contact"]):
            lines.append(",".join([str(j)] + [_cell(v, False) for v in row] + [str(int(f)) for f in flags]))
    path.write_text("\n".join(lines) + "\n")
    return path


def flight_segment(ds, j: int) -> dict[str, np.ndarray]:
    """The flight of jump j (no foot down) as a segment of its own, its base position
    rebased to 0 at the first sample, as some loggers write it; also ``z_true``."""
    a, b = ds.jump_bounds()[j]
    air = np.r_[0, (ds.contact[a:b].sum(axis=1) == 0).astype(int), 0]
    starts, stops = np.flatnonzero(np.diff(air) == 1), np.flatnonzero(np.diff(air) == -1)
    k = int(np.argmax(stops - starts))  # the jump's flight: its longest run without a foot down
    m = jump(ds, j, slice(int(starts[k]), int(stops[k])))
    m["z_true"] = m["q"][:, 14].copy()
    m["q"][:, 12:15] -= m["q"][0, 12:15]
    return m
