"""How the landing errors of a jump benchmark run follow the target: a straight line, or scatter.

Reads a result of ``benchmarks/bench_jump.py --out FILE`` and, per planner, control and world,
fits error_x = a target_x + b (least squares over the jumps that landed) and prints the median
|error|, the slope a (m of error per m of target), the signed mean and the median and largest
|residual| about the line, in cm. A small residual beside a large median error says the errors
are one systematic bias along the targets (a plan that leaves out something the execution does
every time), not scatter from jump to jump.

    python benchmarks/jump_error_lines.py benchmarks/results/jump_lines_go1_mujoco.json
"""

from __future__ import annotations

import argparse
import json

import numpy as np


def error_lines(result: dict) -> list[dict]:
    """One row per planner/control/world of ``result['results']``: median |error|, slope, signed
    mean, and the median and largest |residual| about the fitted line (errors in m)."""
    rows = []
    for key, setup in result["results"].items():
        landed = [j for j in setup["jumps"] if j.get("error_x") is not None and np.isfinite(j["error_x"])]
        if len(landed) < 3:
            rows.append({"setup": key, "jumps": len(landed)})
            continue
        t = np.array([j["target_x"] for j in landed])
        e = np.array([j["error_x"] for j in landed])
        slope, offset = np.polyfit(t, e, 1)
        r = np.abs(e - (slope * t + offset))
        rows.append({"setup": key, "jumps": len(landed), "median_abs": float(np.median(np.abs(e))),
                     "slope": float(slope), "mean": float(e.mean()), "residual_median": float(np.median(r)),
                     "residual_max": float(r.max())})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("result", help="a bench_jump.py --out JSON file")
    args = ap.parse_args()
    with open(args.result) as f:
        rows = error_lines(json.load(f))
    print("| planner/control/world | jumps | median \\|error\\| | slope | signed mean | \\|residual\\| median (max) |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        if "slope" not in r:
            print(f"| {r['setup']} | {r['jumps']} | - | - | - | - |")
            continue
        print(f"| {r['setup']} | {r['jumps']} | {100 * r['median_abs']:.2f} cm | {r['slope']:+.3f} | "
              f"{100 * r['mean']:+.2f} cm | {100 * r['residual_median']:.2f} cm ({100 * r['residual_max']:.2f} cm) |")


if __name__ == "__main__":
    main()
