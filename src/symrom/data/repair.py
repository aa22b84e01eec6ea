"""Logs repaired from physics: per jump, what the robot description and the laws of motion
determine about a log's faults, estimated with its uncertainty and applied where it departs
from "nothing to repair" by more than ``RepairLimits.z`` uncertainties. Never a learned model.

``repair_log`` repairs a ``RawLog`` in place, jump by jump, in this order (each step uses
what the ones before it repaired):

1. the time base (``repair_clock.estimate_clock``): a wrong clock (a uniform scale, or a
   smooth monotone warp where the rate changes within the jump) told from wrong velocities
   by the ballistic flight, and where one jump's flight fits both alike, by the flights of
   the file's jumps together (``repair_clock.file_kind``: one logger, one kind of fault);
   the rows' times and each velocity group are repaired, and a log's own accelerations of
   a repaired jump are dropped (differentiated again by the import from the repaired
   velocities);
2. the contact flags (``repair_body.contact_lag``): a logger's lag of the flags behind the
   feet's heights and speeds, moved back;
3. the torque gain (``repair_body.estimate_gain``) from the weight and the vertical
   momentum, and the base-height offset (``repair_body.estimate_height``) from the feet in
   contact; flags derived from the forces and heights (a bag without a contact topic) are
   derived again from the repaired torques and heights, and the two estimated once more.

A fault the data cannot determine (no flight to tell a clock from velocities, no foot down
to weigh the robot with, dynamic rows a factor 1.3 off the quasi-static ones' gain) is left
as logged where the jump passes the import's consistency check as it is, and refused
otherwise (``RepairError``, one line naming the file, jump and figures); ``lenient`` keeps
it as logged and records the line instead. So is a rate that changes faster than the
windows resolve. Each jump's estimates are one ``JumpRepair`` (its ``line`` is the import's
report of it; ``repairs_record`` the dataset's, ``generator["repairs"]``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from symrom.data.consistency import ConsistencyLimits, time_scale, vertical_impulse
from symrom.data.rawlog import RawLog
from symrom.data.repair_body import (
    BodyPose,
    BodyState,
    ContactEstimate,
    GainEstimate,
    HeightEstimate,
    body_pose,
    body_state,
    contact_lag,
    estimate_gain,
    estimate_height,
    grounded,
    shift_flags,
)
from symrom.data.repair_clock import (
    VELOCITY_GROUPS,
    ClockEstimate,
    ClockFit,
    RepairError,
    RepairLimits,
    VelocityGain,
    estimate_clock,
    file_kind,
)
from symrom.names import BASE_POS

# 2: where one jump's flight fits a wrong clock and wrong velocities alike, the file's flights together decide
REPAIR_VERSION = 2
_Z = BASE_POS.start + 2
__all__ = ["REPAIR_VERSION", "JumpRepair", "RepairError", "RepairLimits", "repair_log", "repairs_record"]


@dataclass(frozen=True)
class JumpRepair:
    """The repair of one jump of a log: file (name), jump (the file's, after segmentation),
    rows; the estimates (``ClockEstimate``, ``VelocityGain`` per group, ``GainEstimate``,
    ``HeightEstimate`` (None: heights left as logged, ``positions="absolute"``),
    ``ContactEstimate``); accelerations: ``as logged`` or ``differentiated again`` (the log's
    own, dropped with a repaired clock or velocities); kept: the faults the data did not
    determine, left as logged (one line each)."""

    file: str
    jump: int
    rows: int
    clock: ClockEstimate
    velocities: tuple[VelocityGain, ...]
    gain: GainEstimate
    height: HeightEstimate | None
    contacts: ContactEstimate
    accelerations: str
    kept: tuple[str, ...] = ()

    @property
    def changed(self) -> bool:
        """Whether anything of the jump was changed."""
        return (self.clock.applied or any(v.applied for v in self.velocities) or self.gain.applied
                or (self.height is not None and self.height.applied) or self.contacts.applied)

    def to_dict(self) -> dict:
        return {"file": self.file, "jump": self.jump, "rows": self.rows, "changed": self.changed,
                "clock": self.clock.to_dict(), "velocities": [v.to_dict() for v in self.velocities],
                "gain": self.gain.to_dict(), "height": None if self.height is None else self.height.to_dict(),
                "contacts": self.contacts.to_dict(), "accelerations": self.accelerations, "kept": list(self.kept),
                "line": self.line()}

    def line(self) -> str:
        """What was found and done, one line: 'FILE jump J: ...'."""
        c = self.clock
        parts = []
        flight = ("no flight" if c.flight_g is None
                  else f"flight {c.flight_g:.3f} +- {c.flight_g_sd:.3f} g")
        ratio = f"positions change {c.ratio:.4f} +- {c.ratio_sd:.4f} times as fast as the velocities integrate to"
        together = "; told by the file's flights together" if "flights together" in c.note else ""
        if c.finding == "clock":
            kind = f"a time warp, rate {c.rate_low:.3f}..{c.rate_high:.3f}" if c.warp else "a uniform scale"
            parts.append(f"clock wrong ({kind}{together}): duration x {c.scale:.4f} +- {c.scale_sd:.4f}, "
                         f"{flight} on it")
        elif c.finding == "clock and velocities":
            parts.append(f"clock and velocities wrong: duration x {c.scale:.4f} +- {c.scale_sd:.4f}, {flight} on it")
        elif c.finding == "velocities":
            parts.append(f"clock right ({flight}{together}), velocities wrong ({ratio})")
        elif c.finding == "undetermined":
            parts.append(f"time base undetermined ({ratio}; {c.note})")
        elif c.windows:
            parts.append(f"time base right (positions against velocities {c.ratio:.4f} +- {c.ratio_sd:.4f}, {flight})")
        else:
            parts.append(f"time base not determined ({c.note})")
        moved = [v for v in self.velocities if v.applied]
        if moved:
            parts.append("velocities / " + ", ".join(
                f"{v.gain:.4f} +- {v.sd:.4f} ({v.group}{'' if v.how == 'estimated' else ', ' + v.how})"
                for v in moved))
        g = self.gain
        if g.applied and g.kinds is not None:
            parts.append(f"torques / {g.kinds[1]:.3f} +- {g.kinds_sd[1]:.3f} (hx, hy), {g.kinds[2]:.3f} +- "
                         f"{g.kinds_sd[2]:.3f} (kn) ({g.note})")
        elif g.applied:
            parts.append(f"torques / {g.gain:.3f} +- {g.sd:.3f} ({g.note})")
        elif np.isfinite(g.gain):
            parts.append(f"torque gain {g.gain:.3f} +- {g.sd:.3f}")
        h = self.height
        if h is not None and h.applied:
            parts.append(f"z {'+' if h.offset >= 0 else '-'} {1e3 * abs(h.offset):.1f} +- {1e3 * h.sd:.1f} mm "
                         f"(the feet in contact sat {1e3 * abs(h.offset):.1f} mm "
                         f"{'below' if h.offset > 0 else 'above'} the ground)")
        elif h is not None and np.isfinite(h.offset):
            parts.append(f"feet on the ground ({1e3 * -h.offset:+.1f} +- {1e3 * h.sd:.1f} mm)")
        parts.append(self.contacts.note)
        if self.kept:
            parts.append("kept as logged: " + "; ".join(self.kept))
        head = f"{self.file} jump {self.jump}: " + ("" if self.changed else "nothing to repair: ")
        return head + "; ".join(parts)


def repairs_record(repairs: list[JumpRepair], limits: RepairLimits) -> dict:
    """The dataset's record of the repairs (``generator["repairs"]``): version, limits and
    one entry per jump, in the order of the files and their jumps."""
    return {"version": REPAIR_VERSION, "limits": limits.to_dict(), "jumps": [r.to_dict() for r in repairs]}


def _keep_or_refuse(reason: str, passes: bool, lenient: bool, kept: list[str]) -> None:
    """A fault the data do not determine: kept as logged where the jump passes the
    consistency check as it is (or with ``lenient``), refused otherwise."""
    if passes:
        kept.append(reason.split(": ", 1)[-1] + " (the jump passes the consistency check as logged)")
    elif lenient:
        kept.append(reason.split(": ", 1)[-1])
    else:
        raise RepairError(reason + "; the jump fails the consistency check as logged (lenient keeps it as logged)")


def repair_log(lg: RawLog, robot: str, limits: RepairLimits = RepairLimits(),
               physics: ConsistencyLimits | None = ConsistencyLimits(), lenient: bool = False,
               heights: bool = True) -> list[JumpRepair]:
    """Repair every jump of ``lg`` in place (module docstring); one ``JumpRepair`` per jump.

    robot: a built-in name or a description file; physics: the consistency limits a jump
    must meet as logged for an undetermined fault to be kept (None: always kept); lenient:
    keep undetermined faults and record them instead of refusing; heights: estimate the base
    height (False: z as logged, ``positions="absolute"``). Raises ``RepairError``.
    """
    physics_or_default = physics or ConsistencyLimits()
    derived = bool(lg.topics and str(lg.topics.get("contacts", "")).startswith("derived"))
    # each jump's bodies as logged, computed once for both passes of the clock and the repair
    bodies: dict[int, tuple[BodyPose, BodyState]] = {}

    def body_of(j: int) -> tuple[BodyPose, BodyState]:
        if j not in bodies:
            a, b = lg.bounds()[j]
            pose = body_pose(robot, lg.q[a:b])
            bodies[j] = pose, body_state(robot, lg.q[a:b], lg.dq[a:b], pose)
        return bodies[j]

    def clock_of(j: int, kind: tuple[str, str] | None = None) -> ClockFit | RepairError:
        a, b = lg.bounds()[j]
        state = body_of(j)[1]
        try:
            return estimate_clock(f"{lg.path}, jump {j}", lg.t[a:b], lg.q[a:b], lg.dq[a:b], lg.contact[a:b],
                                  state.com_z, limits, physics_or_default.min_motion,
                                  grounded(state, lg.contact[a:b], limits), kind)
        except RepairError as e:
            if not lenient:
                raise
            return e

    # the time base of every jump first: where one jump's flight cannot tell a wrong clock from
    # wrong velocities, the file's flights together may (one logger, one kind of fault)
    fits = [clock_of(j) for j in range(lg.n_jumps)]
    found, why = file_kind([f for f in fits if isinstance(f, ClockFit)], limits)
    if found is not None:
        fits = [clock_of(j, (found, why)) if isinstance(f, ClockFit) and f.clock.finding == "undetermined"
                and f.evidence is not None else f for j, f in enumerate(fits)]
    out = []
    for j, (a, b) in enumerate(lg.bounds()):
        where = f"{lg.path}, jump {j}"
        t, q, dq = lg.t[a:b].copy(), lg.q[a:b].copy(), lg.dq[a:b].copy()
        tau, contact = lg.tau[a:b].copy(), lg.contact[a:b].copy()
        kept: list[str] = []
        pose, state = body_of(j)
        del bodies[j]  # held no longer than its jump's repair
        fit = fits[j]
        if isinstance(fit, RepairError):  # lenient: kept as logged
            kept.append(str(fit).split(": ", 1)[-1])
            fit = None
        if fit is None:  # lenient: the time base kept as logged
            clock = ClockEstimate("undetermined", float("nan"), float("nan"), 0, "", 0.0, False, 1.0, 0.0, 1.0, 1.0,
                                  (), (), float("nan"), None, None, 0, False, "refused, kept as logged")
            velocities = tuple(VelocityGain(g, 1.0, float("nan"), 0, False, "undetermined") for g, _ in VELOCITY_GROUPS)
        else:
            clock, velocities = fit.clock, fit.velocities
            if fit.undetermined:
                passes = physics is None or not time_scale(where, t, q, dq, physics)
                _keep_or_refuse(fit.undetermined, passes, lenient, kept)
        retimed = clock.applied or any(v.applied for v in velocities)
        if clock.applied:
            t = fit.times
        for v, (_, cols) in zip(velocities, VELOCITY_GROUPS):
            if v.applied:
                dq[:, cols] = dq[:, cols] / v.gain
        if retimed:  # the same positions: only what the velocities give is computed again
            state = body_state(robot, q, dq, pose)

        # contacts: a logger's lag of the flags (logged flags only)
        lag, td, lo = (0, {}, {}) if derived else contact_lag(state, contact, limits)
        if lag:
            contact = shift_flags(contact, lag)

        gain, gain_why = estimate_gain(t, state, tau, contact, limits)
        height = estimate_height(state, contact, limits) if heights else None
        changed_flags = int(np.sum(contact != lg.contact[a:b]))
        if derived and (gain.applied or (height is not None and height.applied)):
            from symrom.data.bags import derived_contact

            for _ in range(2):  # flags from the repaired forces and heights, the estimates again
                q_fix = q.copy()
                if height is not None and height.applied:
                    q_fix[:, _Z] += height.offset
                tau_fix = tau / gain.per_joint() if gain.applied else tau
                contact = derived_contact(robot, q_fix, tau_fix)
                gain, gain_why = estimate_gain(t, state, tau, contact, limits)
                height = estimate_height(state, contact, limits) if heights else None
            changed_flags = int(np.sum(contact != lg.contact[a:b]))
        if gain_why:
            fz = None if physics is None else vertical_impulse(where, robot, t, q, dq, tau, contact, physics)
            _keep_or_refuse(f"{where}: {gain_why}", physics is None or not fz, lenient, kept)
        if gain.applied:
            tau = tau / gain.per_joint()
        if height is not None and height.applied:
            q[:, _Z] += height.offset
        if derived:
            note = (f"contacts derived again from the repaired forces and heights ({changed_flags} foot-rows changed)"
                    if changed_flags else "contacts derived from the forces and heights")
        elif lag:
            note = (f"contacts {abs(lag)} row{'s' if abs(lag) > 1 else ''} "
                    f"{'late' if lag > 0 else 'early'}, moved back ({changed_flags} foot-rows)")
        else:
            note = "contacts as logged (no lag)"
        contacts = ContactEstimate("derived" if derived else "logged", lag, dict(td), dict(lo), changed_flags,
                                   changed_flags > 0, note)

        # write back what changed
        if clock.applied:
            lg.t[a:b] = t
        if retimed:
            lg.dq[a:b] = dq
            if lg.ddq is not None:
                lg.ddq_dropped.add(j)
        if gain.applied:
            lg.tau[a:b] = tau
        if height is not None and height.applied:
            lg.q[a:b, _Z] = q[:, _Z]
        if contacts.applied:
            lg.contact[a:b] = contact
        out.append(JumpRepair(lg.path.name, j, int(b - a), clock, velocities, gain, height, contacts,
                              "differentiated again" if retimed and lg.ddq is not None else "as logged",
                              tuple(kept)))
    return out
