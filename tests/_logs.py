"""Robot logs made by the tests: simulated Go1 (and A1 froggy) jumps written as CSV in the
hardware and plain layouts, at other rates, on a drifting clock, with jitter, gaps, unit
mistakes or as rebased segments, and as ROS bags."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
from _simdata import reference_file, shared
from scipy.interpolate import CubicSpline

from symrom.data.io import read_dataset
from symrom.names import JOINT_NAMES, LEGS, Q_NAMES
from symrom.sim.generation.generate import GenerateConfig, generate

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
    return read_dataset(shared(f"proxy_{n_jumps}_{seed}.h5", lambda out: generate(
        GenerateConfig("go1", "pronk", n_jumps, seed=seed, proxy=True), out)))


@cache
def sim_a1_froggy():
    """Three simulated A1 froggy jumps (500 Hz), shared with the simulation tests."""
    return read_dataset(reference_file("froggy"))


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


def on_clock(m: dict[str, np.ndarray], rate, dt: float = 0.002) -> dict[str, np.ndarray]:
    """The jump ``m`` logged by a loop whose rate drifts: row k is written at t = k dt but
    taken at the true time T_k, T_k+1 - T_k = dt rate((k + 1/2) dt) (``rate``: true s per
    logged s, of the logged time); also ``t_true`` (the T_k). Samples as ``at_times``."""
    T = [0.0]
    while T[-1] + dt * rate((len(T) - 0.5) * dt) <= m["t"][-1]:
        T.append(T[-1] + dt * rate((len(T) - 0.5) * dt))
    out = at_times(m, np.array(T))
    out["t_true"], out["t"] = out["t"], np.arange(len(T)) * dt
    return out


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
            lines.append(";".join([repr(v).replace(".", ",") for v in row.tolist()] + [str(int(f)) for f in flags]))
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
            lines.append(",".join([str(j), *map(repr, row.tolist()), *(str(int(f)) for f in flags)]))
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


# ----------------------------------------------------------------- bags

def _euler_to_body_rates(rpy: np.ndarray, rates: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw rates (n, 3) -> angular velocity in the base frame (ZYX angles)."""
    r, p = rpy[:, 0], rpy[:, 1]
    dr, dp, dy = rates.T
    return np.stack([dr - np.sin(p) * dy,
                     np.cos(r) * dp + np.sin(r) * np.cos(p) * dy,
                     -np.sin(r) * dp + np.cos(r) * np.cos(p) * dy], axis=1)


ROS_TOPICS = {"joints": "/joint_states", "base": "/odom", "contacts": "/foot_contacts"}


def ros_messages(m: dict, robot: str = "go1", t0_ns: int = 1_700_000_000_000_000_000,
                 contacts: bool = True, store=None, topics: dict | None = None, contact_delay: float = 0.0):
    """The jump ``m`` as ROS 2 messages: [(topic, msgtype, stamp_ns, msg)], joints in the URDF's
    names and signs, odometry with its twist in the base frame, contact flags as UInt8MultiArray
    (no header: their time is when they are written, ``contact_delay`` s after the joints')."""
    from rosbags.typesys import Stores, get_typestore
    from scipy.spatial.transform import Rotation

    from symrom.robots import get_robot

    ts = store or get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    desc = get_robot(robot)
    signs = np.asarray(desc.joint_signs, float)
    rpy = m["q"][:, 15:18]
    R = Rotation.from_euler("xyz", rpy)  # extrinsic x, y, z = R_z R_y R_x
    quat = R.as_quat()  # x y z w
    v_body = R.inv().apply(m["dq"][:, 12:15])
    w_body = _euler_to_body_rates(rpy, m["dq"][:, 15:18])
    Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
    Vec, Pt, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"]
    tp = {**ROS_TOPICS, **(topics or {})}
    out = []
    for i, t in enumerate(m["t"]):
        ns = t0_ns + int(round(t * 1e9))
        hdr = Header(stamp=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id="")
        js = T["sensor_msgs/msg/JointState"](
            header=hdr, name=list(desc.joint_names)[::-1],  # any order: matched by name
            position=(m["q"][i, :12] / signs)[::-1].copy(), velocity=(m["dq"][i, :12] / signs)[::-1].copy(),
            effort=(m["tau"][i] / signs)[::-1].copy())
        pose = T["geometry_msgs/msg/PoseWithCovariance"](
            pose=T["geometry_msgs/msg/Pose"](position=Pt(x=m["q"][i, 12], y=m["q"][i, 13], z=m["q"][i, 14]),
                                             orientation=Q(x=quat[i, 0], y=quat[i, 1], z=quat[i, 2], w=quat[i, 3])),
            covariance=np.zeros(36))
        twist = T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](linear=Vec(x=v_body[i, 0], y=v_body[i, 1], z=v_body[i, 2]),
                                               angular=Vec(x=w_body[i, 0], y=w_body[i, 1], z=w_body[i, 2])),
            covariance=np.zeros(36))
        odom = T["nav_msgs/msg/Odometry"](header=hdr, child_frame_id="base", pose=pose, twist=twist)
        out.append((tp["joints"], "sensor_msgs/msg/JointState", ns, js))
        out.append((tp["base"], "nav_msgs/msg/Odometry", ns, odom))
        if contacts:
            layout = T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
            c = T["std_msgs/msg/UInt8MultiArray"](layout=layout, data=m["contact"][i].astype(np.uint8))
            out.append((tp["contacts"], "std_msgs/msg/UInt8MultiArray", ns + int(round(contact_delay * 1e9)), c))
    return out


def write_ros1(path: Path, m: dict, **kw) -> Path:
    """The jump as a ROS 1 bag."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    msgs = ros_messages(m, store=get_typestore(Stores.ROS2_HUMBLE), **kw)
    with Writer(path) as w:
        conns = {}
        for topic, typ, ns, msg in msgs:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, typ, typestore=ts)
            w.write(conns[topic], ns, ts.serialize_ros1(_to_store(msg, ts), typ))
    return path


def _to_store(msg, ts):
    """A ROS 2 message rebuilt with another typestore's classes (ROS 1 headers hold a seq)."""
    import dataclasses

    cls = ts.types[msg.__msgtype__]
    kw = {}
    for f in dataclasses.fields(cls):
        if f.name == "seq":
            kw[f.name] = 0
            continue
        v = getattr(msg, f.name)
        kw[f.name] = _to_store(v, ts) if hasattr(v, "__msgtype__") else (
            [_to_store(x, ts) for x in v] if isinstance(v, list) and v and hasattr(v[0], "__msgtype__") else v)
    return cls(**kw)


def write_ros2(path: Path, m: dict, storage: str = "sqlite3", **kw) -> Path:
    """The jump as a ROS 2 bag folder (sqlite3 or mcap storage)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conns = {}
        for topic, typ, ns, msg in ros_messages(m, store=ts, **kw):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, typ, typestore=ts)
            w.write(conns[topic], ns, ts.serialize_cdr(msg, typ))
    return path
