"""ROS 1 bags, ROS 2 bags and MCAP files -> the importer's per-file table (``importers.RawLog``).

A bag is read into the same table a CSV log gives, so everything after reading
(segmentation, checks, time base, wrench, phases) is shared. The topics, by
role (``DEFAULT_TOPICS``; ``--topics joints=/x,base=/y,contacts=/z`` or a
mapping file, ``load_mapping``, override them):

- ``joints``: ``sensor_msgs/msg/JointState``. Each of the robot's 12 URDF
  joints (the description's ``joint_names``) is matched by name in the
  message's ``name`` list, in any order; ``position`` (rad), ``velocity``
  (rad/s) and ``effort`` (N m) are in the URDF's sign convention and turned
  into symrom's by the description's ``joint_signs``. One table row per
  message: the joint loop sets the rows.
- ``base``: ``nav_msgs/msg/Odometry``, ROS convention: ``pose.pose`` the base
  in the world frame (position m, orientation quaternion x y z w -> roll,
  pitch, yaw, ZYX, unwrapped over the recording), ``twist.twist`` in the base
  (child) frame: the linear velocity is rotated into the world frame and the
  angular velocity turned into roll, pitch, yaw rates. Interpolated linearly
  to the joint rows' times (exact where the stamps coincide).
- ``contacts`` (optional): a message whose ``data`` holds 4 values in leg
  order FR FL RR RL (``std_msgs/msg/UInt8MultiArray``, ``Int8MultiArray``,
  ``Float32MultiArray`` ...), > 0.5 meaning the foot is down. Each message
  sets the joint row nearest to its time, if within half the joints' period
  (``nearest_rows``), and holds until the next one: a header-less message's time
  is when it was received, which trails the joints' header stamps, and the last
  message at or before a row would put every contact change one row late.
  Without the topic, a foot is down
  where the vertical force its leg's torques give (``preprocess``: through the
  leg Jacobian) exceeds ``CONTACT_FORCE`` of the robot's weight and, if the
  base position is absolute, its centre is within ``CONTACT_HEIGHT`` of one
  foot radius above the ground.

A message's time is its header stamp (the bag's receive time where the stamp
is zero). Joint rows outside the base (and contact) messages' time span are
dropped. A bag is one continuous recording: one jump, cut into jumps by the
segmentation (``segment``).
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path

import numpy as np

from symrom.names import BASE_NAMES, GRAVITY

DEFAULT_TOPICS = {"joints": "/joint_states", "base": "/odom", "contacts": "/foot_contacts"}
ROLES = tuple(DEFAULT_TOPICS)
CONTACT_FORCE = 0.1  # of the weight: a foot pushing less than this is in the air
CONTACT_HEIGHT = 0.03  # m: a foot centre farther than this above foot-radius height is in the air


def parse_topics(spec: str | None) -> dict[str, str]:
    """``joints=/a,base=/b,contacts=/c`` -> {role: topic}; ValueError naming a bad part."""
    out: dict[str, str] = {}
    if not spec:
        return out
    for part in spec.split(","):
        role, sep, topic = part.partition("=")
        role, topic = role.strip(), topic.strip()
        if not sep or role not in ROLES or not topic.startswith("/"):
            raise ValueError(f"topics={spec!r}: {part!r} is not ROLE=/topic with ROLE in {', '.join(ROLES)}")
        out[role] = topic
    return out


def load_mapping(path: str | os.PathLike) -> dict[str, str]:
    """Topics by role from a TOML mapping file: a ``[topics]`` table, e.g.
    ``joints = "/go1/joint_states"``; ValueError naming the file and key."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise ValueError(f"{path}: cannot read the topic mapping ({e})") from None
    topics = data.get("topics", {})
    bad = [k for k in topics if k not in ROLES] + [k for k in data if k != "topics"]
    if bad or not all(isinstance(v, str) and v.startswith("/") for v in topics.values()):
        raise ValueError(f"{path}: a topic mapping holds a [topics] table with {', '.join(ROLES)} = \"/topic\"; "
                         f"found {', '.join(bad) or topics}")
    return dict(topics)


class _Messages:
    """The messages of the wanted topics of one bag: {topic: [(t_ns, msg)]}, their types."""

    def __init__(self, path: Path, kind: str, topics: list[str]):
        self.by_topic: dict[str, list] = {t: [] for t in topics}
        self.types: dict[str, str] = {}
        self.available: dict[str, str] = {}
        if kind == "mcap":
            self._mcap(path, topics)
        else:
            self._rosbags(path, topics)

    def _keep(self, topic: str, receive_ns: int, msg) -> None:
        stamp = getattr(getattr(msg, "header", None), "stamp", None)
        ns = int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec) if stamp is not None else 0
        self.by_topic[topic].append((ns or int(receive_ns), msg))

    def _rosbags(self, path: Path, topics: list[str]) -> None:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            self.available = {c.topic: c.msgtype for c in reader.connections}
            conns = [c for c in reader.connections if c.topic in self.by_topic]
            for c in conns:
                self.types[c.topic] = c.msgtype
            if not conns:  # an empty list would mean every connection
                return
            for conn, ns, raw in reader.messages(connections=conns):
                self._keep(conn.topic, ns, reader.deserialize(raw, conn.msgtype))

    def _mcap(self, path: Path, topics: list[str]) -> None:
        from mcap.reader import make_reader
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore

        store = get_typestore(Stores.ROS2_HUMBLE)
        with open(path, "rb") as f:
            reader = make_reader(f)
            summary = reader.get_summary()
            if summary is not None:
                self.available = {ch.topic: summary.schemas[ch.schema_id].name if ch.schema_id in summary.schemas
                                  else "?" for ch in summary.channels.values()}
            for schema, channel, message in reader.iter_messages(topics=topics):
                name = schema.name if schema is not None else "?"
                if channel.message_encoding != "cdr":
                    raise ValueError(f"{path}: topic {channel.topic} is encoded as "
                                     f"{channel.message_encoding!r}; symrom reads ROS 2 (cdr) MCAP files")
                if name not in store.fielddefs and schema is not None:
                    store.register(get_types_from_msg(schema.data.decode(), name))
                self.types[channel.topic] = name
                self._keep(channel.topic, message.log_time, store.deserialize_cdr(message.data, name))


def quat_to_rpy(qxyzw: np.ndarray) -> np.ndarray:
    """Unit quaternions (n, 4) x y z w -> ZYX roll, pitch, yaw (n, 3) rad (R = Rz Ry Rx)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(qxyzw).as_euler("xyz")


def body_rates_to_euler(rpy: np.ndarray, omega_body: np.ndarray) -> np.ndarray:
    """Angular velocity in the base frame (n, 3) rad/s -> roll, pitch, yaw rates (n, 3)."""
    r, p = rpy[:, 0], rpy[:, 1]
    wx, wy, wz = omega_body.T
    cr, sr, cp, tp = np.cos(r), np.sin(r), np.cos(p), np.tan(p)
    return np.stack([wx + (sr * wy + cr * wz) * tp, cr * wy - sr * wz, (sr * wy + cr * wz) / cp], axis=1)


def read_bag(path: str | os.PathLike, robot: str, topics: dict[str, str] | None = None):
    """One bag (ROS 1 ``.bag``, ROS 2 bag folder, ``.mcap``) -> ``importers.RawLog`` (one jump;
    see the module docstring). ``topics``: {role: topic} over ``DEFAULT_TOPICS``."""
    from symrom.data.rawlog import LogError, RawLog, log_kind, sha256_file
    from symrom.robots import get_robot
    from symrom.robots.kinematics import rpy_to_matrix

    path = Path(path)
    kind = log_kind(path)
    topics = {**DEFAULT_TOPICS, **(topics or {})}
    desc = get_robot(robot)
    try:
        bag = _Messages(path, kind, list(topics.values()))
    except Exception as e:  # the readers' own errors: a damaged or unsupported file
        raise LogError(f"{path}: cannot read it as {kind} ({type(e).__name__}: {e})") from None

    def listing() -> str:
        return ", ".join(f"{t} ({m})" for t, m in sorted(bag.available.items())) or "none"

    for role in ("joints", "base"):
        if not bag.by_topic[topics[role]]:
            raise LogError(f"{path}: no message on the {role} topic {topics[role]} (topics={role}=/...); "
                           f"the bag holds {listing()}")

    # Joints: one row per message.
    jmsgs = sorted(bag.by_topic[topics["joints"]], key=lambda x: x[0])
    t_ns = np.array([ns for ns, _ in jmsgs], dtype=np.int64)
    signs = np.asarray(desc.joint_signs, dtype=float)
    q_j, dq_j, tau = (np.empty((len(jmsgs), 12)) for _ in range(3))
    order_cache: dict[tuple, list[int]] = {}
    for r, (_, m) in enumerate(jmsgs):
        names = tuple(m.name)
        if names not in order_cache:
            missing = [n for n in desc.joint_names if n not in names]
            if missing:
                raise LogError(f"{path}, {topics['joints']} message {r}: no joint named {', '.join(missing)} "
                               f"(the {desc.name} URDF's names); the message names {', '.join(names)}")
            order_cache[names] = [names.index(n) for n in desc.joint_names]
        idx = order_cache[names]
        for field, out in (("position", q_j), ("velocity", dq_j), ("effort", tau)):
            v = np.asarray(getattr(m, field), dtype=float)
            if v.size != len(names):
                raise LogError(f"{path}, {topics['joints']} message {r}: {v.size} {field} values for "
                               f"{len(names)} joint names (symrom needs position, velocity and effort)")
            out[r] = v[idx] * signs
    if np.any(np.diff(t_ns) <= 0):
        r = int(np.flatnonzero(np.diff(t_ns) <= 0)[0]) + 1
        raise LogError(f"{path}, {topics['joints']} message {r}: its stamp does not follow the previous one's")

    # Base: odometry, interpolated to the joint rows.
    bmsgs = sorted(bag.by_topic[topics["base"]], key=lambda x: x[0])
    tb = np.array([ns for ns, _ in bmsgs], dtype=np.int64)
    pos = np.array([[m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z] for _, m in bmsgs])
    quat = np.array([[m.pose.pose.orientation.x, m.pose.pose.orientation.y, m.pose.pose.orientation.z,
                      m.pose.pose.orientation.w] for _, m in bmsgs])
    v_b = np.array([[m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.linear.z] for _, m in bmsgs])
    w_b = np.array([[m.twist.twist.angular.x, m.twist.twist.angular.y, m.twist.twist.angular.z]
                    for _, m in bmsgs])
    rpy = quat_to_rpy(quat)
    R = rpy_to_matrix(rpy)
    v_w = np.einsum("nij,nj->ni", R, v_b)
    rates = body_rates_to_euler(rpy, w_b)
    rpy = np.unwrap(rpy, axis=0)
    base = np.concatenate([pos, rpy, v_w, rates], axis=1)  # (m, 12)
    lo, hi = tb[0], tb[-1]
    contact_src = bag.by_topic.get(topics["contacts"], [])
    if contact_src:
        cmsgs = sorted(contact_src, key=lambda x: x[0])
        tc = np.array([ns for ns, _ in cmsgs], dtype=np.int64)
        flags = np.array([np.asarray(m.data, dtype=float)[:4] for _, m in cmsgs])
        if flags.shape[1:] != (4,):
            raise LogError(f"{path}, {topics['contacts']}: a contact message holds {flags.shape[1:]} values, "
                           f"expected 4 (FR FL RR RL)")
        lo = max(lo, tc[0] - _half_period(t_ns))
    keep = (t_ns >= lo) & (t_ns <= hi)
    if keep.sum() < 2:
        raise LogError(f"{path}: the joint messages ({topics['joints']}) and the base messages "
                       f"({topics['base']}) do not overlap in time")
    t_ns, q_j, dq_j, tau = t_ns[keep], q_j[keep], dq_j[keep], tau[keep]
    rel = (t_ns - t_ns[0]) * 1e-9
    tb_rel = (tb - t_ns[0]) * 1e-9
    at = np.stack([np.interp(rel, tb_rel, col) for col in base.T], axis=1)
    q = np.concatenate([q_j, at[:, 0:6]], axis=1)
    dq = np.concatenate([dq_j, at[:, 6:12]], axis=1)
    if contact_src:
        k = nearest_rows(t_ns, tc)
        contact = (flags[k] > 0.5).astype(np.uint8)
        how = f"topic {topics['contacts']}"
    else:
        contact = derived_contact(robot, q, tau)
        how = "derived from the legs' vertical forces and foot heights"
    n = len(rel)
    names = {"q": tuple(f"{topics['joints']} {j} position" for j in desc.joint_names)
             + tuple(f"{topics['base']} {b}" for b in BASE_NAMES),
             "dq": tuple(f"{topics['joints']} {j} velocity" for j in desc.joint_names)
             + tuple(f"{topics['base']} d{b}" for b in BASE_NAMES),
             "tau": tuple(f"{topics['joints']} {j} effort" for j in desc.joint_names)}
    used = {"joints": topics["joints"], "base": topics["base"], "contacts": how}
    return RawLog(path=path, layout=f"{kind} bag" if kind != "mcap" else "mcap", sha256=sha256_file(path),
                  jump=np.zeros(n, np.int32), t=rel, q=q, dq=dq, ddq=None, tau=tau, contact=contact,
                  lines=None, columns=names, topics=used)


def _half_period(t_ns: np.ndarray) -> int:
    """Half the median step of the joint rows' stamps (ns)."""
    return int(np.median(np.diff(t_ns)) // 2) if t_ns.size > 1 else 0


def nearest_rows(t_ns: np.ndarray, tc: np.ndarray) -> np.ndarray:
    """For each joint row (stamps t_ns (n,) ns, increasing), the index of the contact message
    (times tc (m,) ns, increasing) that holds there: each message sets the row nearest to
    its time if within half the rows' median period (of two messages nearest one row, the
    nearer; ties: the later), and holds until the next message sets a row. Rows before the
    first message set take the first message."""
    half = _half_period(t_ns)
    right = np.clip(np.searchsorted(t_ns, tc), 0, t_ns.size - 1)
    left = np.clip(right - 1, 0, t_ns.size - 1)
    row = np.where(np.abs(t_ns[left] - tc) < np.abs(t_ns[right] - tc), left, right)
    dist = np.abs(t_ns[row] - tc)
    sets = np.full(t_ns.size, -1)
    best = np.full(t_ns.size, np.iinfo(np.int64).max)
    for m in np.flatnonzero(dist <= half):
        if dist[m] <= best[row[m]]:
            sets[row[m]], best[row[m]] = m, dist[m]
    held = np.maximum.accumulate(np.where(sets >= 0, sets, -1))
    first = sets[sets >= 0][0] if (sets >= 0).any() else 0
    return np.where(held >= 0, held, first)


def derived_contact(robot: str, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Contact flags (n, 4) where no contact topic was logged (module docstring)."""
    from symrom.data.preprocess import foot_positions_world, ground_reaction_forces
    from symrom.robots import get_robot

    desc = get_robot(robot)
    fz = ground_reaction_forces(robot, q, tau, np.ones((q.shape[0], 4)))[:, :, 2]
    down = fz > CONTACT_FORCE * desc.mass * GRAVITY
    z = foot_positions_world(robot, q)[:, :, 2] - desc.foot_radius
    if np.median(q[:, 14]) > 0.5 * desc.start_height:  # an absolute base height: the feet's height counts
        down &= z < CONTACT_HEIGHT
    return down.astype(np.uint8)

