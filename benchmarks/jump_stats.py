"""Statistics of the jumps in a dataset file: the numbers to hold against hardware.

Per jump: longest contiguous flight (s), start and apex base height (m), forward
travel (m), peak upward base speed (m/s), peak |torque| of hip abduction, hip
flexion and knee (N m), samples; for a motion with a partial phase (froggy: some feet
down before the flight), its length (s) and the body's pitch at its most nose-up and
nose-down (rad, positive nose down). Prints median (min-max) over jumps as Markdown.

    python benchmarks/jump_stats.py data/go1_pronk.h5
"""

from __future__ import annotations

import argparse

import numpy as np

from symrom.data import read_dataset
from symrom.names import BASE_POS


def longest_run(mask: np.ndarray) -> int:
    best = run = 0
    for m in mask:
        run = run + 1 if m else 0
        best = max(best, run)
    return best


def jump_stats(path: str) -> dict[str, np.ndarray]:
    ds = read_dataset(path)
    flight = ds.phase_names.index("flight")
    rows = {k: [] for k in ("flight_s", "start_z_m", "crouch_z_m", "apex_z_m", "travel_m",
                            "peak_vz_mps", "peak_tau_hx", "peak_tau_hy", "peak_tau_kn", "samples")}
    partial = ds.phase_names.index("partial") if "partial" in ds.phase_names else None
    if partial is not None:
        rows |= {"partial_s": [], "pitch_nose_up_rad": [], "pitch_nose_down_rad": []}
    for a, b in ds.jump_bounds():
        pos, vel, tau = ds.q[a:b, BASE_POS], ds.dq[a:b, BASE_POS], np.abs(ds.tau[a:b])
        if partial is not None:
            rows["partial_s"].append(float(np.sum(ds.phase[a:b] == partial)) * ds.dt)
            rows["pitch_nose_up_rad"].append(-ds.q[a:b, 16].min())
            rows["pitch_nose_down_rad"].append(ds.q[a:b, 16].max())
        rows["flight_s"].append(longest_run(ds.phase[a:b] == flight) * ds.dt)
        rows["start_z_m"].append(pos[0, 2])
        rows["crouch_z_m"].append(pos[: np.argmax(pos[:, 2]), 2].min() if np.argmax(pos[:, 2]) else pos[0, 2])
        rows["apex_z_m"].append(pos[:, 2].max())
        rows["travel_m"].append(pos[-1, 0] - pos[0, 0])
        rows["peak_vz_mps"].append(vel[:, 2].max())
        for i, j in enumerate(("hx", "hy", "kn")):
            rows[f"peak_tau_{j}"].append(tau[:, i::3].max())
        rows["samples"].append(b - a)
    return {k: np.asarray(v, float) for k, v in rows.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data", nargs="+")
    args = ap.parse_args()
    for path in args.data:
        stats = jump_stats(path)
        n = len(stats["samples"])
        print(f"\n{path} ({n} jumps)\n\n| quantity | median | min - max |\n|---|---|---|")
        for k, v in stats.items():
            print(f"| {k} | {np.median(v):.3g} | {v.min():.3g} - {v.max():.3g} |")


if __name__ == "__main__":
    main()
