"""The sim-to-real section: per target, the source as it is on the target's jumps as logged and as
repaired, fine-tuned on the repaired jumps and trained on them alone, side by side on the
target's test jumps (``summary.json``'s ``sim2real``), what the repair found beside what the
logger planted, and the targets checked.

``sim2real_rows`` gives the table's cells once; ``sim2real_blocks`` makes the report's
section of them, ``sim2real_markdown`` the text the CLI prints.
"""

from __future__ import annotations

from symrom.report.document import Para, Table

COLUMNS = (("logged", "as logged: source as is"), ("source", "repaired: source as is"),
           ("fine_tuned", "repaired + fine-tuned"), ("target_alone", "repaired: target alone"),
           ("chosen", "repaired: chosen on val"))
HEADER = ["target", "model", "full x RMSE [m]", "full z RMSE [m]", "flight z acc. [m/s^2] (data)",
          "vs -g", "diverged", "drifted"]
CHECKS = (("source_z", "source z RMSE <= {source_z_le} m"),
          ("fine_tuned_z", "fine-tuned z RMSE <= {fine_tuned_z_le} m"),
          ("not_above_source", "fine-tuned not above the source"),
          ("flight_gravity", "fine-tuned flight gravity within {gravity_within:.0%}"),
          ("vs_target_alone", "fine-tuned x and z <= {scratch_ratio_le}x target alone"))


def _num(v, spec: str = ".2e") -> str:
    return "-" if v is None else format(v, spec)


def sim2real_rows(targets: dict[str, dict]) -> list[list[str]]:
    """Cells of the side-by-side table: one row per target and column of ``COLUMNS``."""
    rows = []
    for name, t in targets.items():
        for key, label in COLUMNS:
            if key not in t:  # a run made before the targets were logged with faults
                continue
            e = t.get(key) or {}
            what = label + (f" ({t['source_model']})" if key in ("logged", "source", "fine_tuned") else "")
            if key == "fine_tuned":
                what += f", {t.get('method', '')}" + (f" (prior weight {t['prior_weight']:g})"
                                                       if t.get("prior_weight") is not None else "")
            if key == "chosen":
                what += f" ({t.get('chosen_source')}, {t.get('chosen_method')})"
            if "refused" in e:
                rows.append([name, what, f"refused: {e['refused']}", "", "", "", "", ""])
                continue
            acc = ("-" if e.get("flight_acc") is None
                   else f"{e['flight_acc']:.2f} ({e['flight_acc_data']:.2f})")
            rows.append([name, what, _num(e.get("x_rmse")), _num(e.get("z_rmse")), acc,
                         _num(e.get("flight_ratio"), ".3f"), str(e.get("diverged_jumps", "-")),
                         str(e.get("drifted_jumps", "-"))])
    return rows


def _faults(f: dict) -> str:
    """A target's log faults as planted (``generator.log_faults``), in words."""
    clock = f"loop {f['clock']:.3f}x its period" + (f" +- {100 * f['clock_wobble']:.1f} %" if f["clock_wobble"] else "")
    sensor = "" if f.get("sensor_scale") is None else f" (its sensor x {f['sensor_scale']:.3f} under it)"
    return (f"{clock}, velocities x {f['velocity_gain']:.3f}, torques x {f['torque_gain']:.3f}{sensor}, "
            f"z {1e3 * f['height_offset']:+.1f} mm, contacts {f['contact_lag']} row(s) late")


def repair_lines(targets: dict[str, dict]) -> list[str]:
    """One line per target: the log faults its logger planted and what the repair found (medians
    and ranges over its jumps; the repair knows nothing of the planted ones)."""
    out = []
    for name, t in targets.items():
        r = t.get("repair")
        if r is None:
            continue
        f = r["found"]

        def rng(key: str, scale: float = 1.0, spec: str = ".3f") -> str:
            v = f.get(key)
            if v is None:
                return "-"
            m, lo, hi = (scale * v[k] for k in ("median", "min", "max"))
            return format(m, spec) + ("" if lo == hi else f" ({format(lo, spec)}..{format(hi, spec)})")

        findings = ", ".join(f"{n} {k}" for k, n in f["findings"].items())
        found = (f"repaired {f['changed']} of {f['jumps']} jumps ({findings}): duration x {rng('clock_scale')}, "
                 f"velocities / {rng('velocity_gain')}, torques / {rng('torque_gain')}, "
                 f"z {rng('height_offset', 1e3, '+.1f')} mm, contact lag {rng('contact_lag', 1.0, '.0f')} row(s)")
        planted = "logged without faults" if r["planted"] is None else "planted: " + _faults(r["planted"])
        out.append(f"{name}: {planted}; {found}")
    return out


def check_lines(targets: dict[str, dict]) -> list[str]:
    """One line per target: each sim-to-real target met or not."""
    out = []
    for name, t in targets.items():
        c = t.get("checks", {})
        parts = [f"{text.format(**c)}: {'-' if c.get(k) is None else 'met' if c[k] else 'NOT met'}"
                 for k, text in CHECKS]
        rx, rz = c.get("scratch_ratio_x"), c.get("scratch_ratio_z")
        ratios = "" if rx is None or rz is None else f"; fine-tuned / target alone: x {rx:.2f}, z {rz:.2f}"
        out.append(f"{name} ({t.get('engine')}, {t['jumps']['train']} train / {t['jumps']['val']} val / "
                   f"{t['jumps']['test']} test jumps; source chosen on val: {t['source_model']}{ratios}): "
                   + "; ".join(parts))
    return out


def sim2real_blocks(targets: dict[str, dict]) -> list:
    """The report's blocks: the table and the targets' lines."""
    return [Para("Each target is logged as a real robot's logs are (a slow or wobbling loop, or velocities off; "
                 "a torque sensor reading part of the load; a height offset; a contact lag) and imported "
                 "through the repair from physics, which knows nothing of them. On its test jumps: the source "
                 "whose default fine-tuning scores best on the target's val jumps, as it is, on the jumps as "
                 "logged and as repaired; fine-tuned on the target's 12 repaired train jumps by the default "
                 "method, as `symrom finetune` does it (its prior weight raised while the val score rises); a "
                 "model trained on those jumps alone with the same settings; the candidate chosen on val among "
                 "every source and fine-tuning (the experiment's model). Flight z acceleration: the model's "
                 "decoded mean on the test flight rows (the data's own beside it), and its ratio to -g."),
            Table(HEADER, sim2real_rows(targets), caption="Sim-to-real, side by side"),
            *(Para(line) for line in repair_lines(targets)),
            *(Para(line) for line in check_lines(targets))]


def sim2real_markdown(targets: dict[str, dict]) -> str:
    """The table and the targets' lines as Markdown text."""
    lines = ["| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
    lines += ["| " + " | ".join(r) + " |" for r in sim2real_rows(targets)]
    return "\n".join(lines + [""] + repair_lines(targets) + check_lines(targets))
