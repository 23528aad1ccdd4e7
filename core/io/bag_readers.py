"""Reading pose streams from ROS 1 bags (.bag) and ROS 2 bags (a directory with .db3 or .mcap
files, or one such file) with the pure-Python `rosbags` package: no ROS installation needed.

`read_bag_poses(path, topic)` returns a `handeye.io.pose_readers.PoseStack` in metres with the
messages' header stamps (seconds) as `stamps`. A topic spec is one of

- ``/topic`` of type geometry_msgs/PoseStamped, geometry_msgs/TransformStamped,
  geometry_msgs/PoseWithCovarianceStamped or nav_msgs/Odometry: the message's pose;
- ``/tf:PARENT,CHILD`` (a tf2_msgs/TFMessage topic, then ``:``, then two frame ids): the pose of
  CHILD in PARENT, T_PARENT_CHILD, chained through the tf tree (``/tf_static`` is read too when
  the bag has it). Where the chain holds several moving links, the one with the most messages
  gives the stamps and the others are interpolated at them (SLERP; never extrapolated).

Why a module of its own: bags are how ROS cells record, and turning one into a time-stamped pose
stream (types, tf chains, error messages listing what the bag holds) is one job; the streams then
go through `handeye.streams` like any pose file. Errors are one-line `InputError`s naming what
the bag has.

A damaged bag is bad input, not a bug: a storage file cut short (an interrupted recording or copy)
is refused before reading by `_truncation` (a .db3 shorter than its SQLite header says, an .mcap
without its end marker, a ROS 1 bag shorter than the index position its header records), and
whatever rosbags or its storage libraries raise on damaged content (`_damaged_bag_errors`) becomes
an InputError naming the bag.
"""

from __future__ import annotations

import contextlib
import dataclasses
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from handeye.base.errors import InputError
from handeye.geometry.se3 import make_pose
from handeye.io.input_files import check_not_looping
from handeye.io.pose_readers import PoseStack

#: message types read as one pose per message, and where the pose sits in the message
POSE_TYPES = {
    "geometry_msgs/msg/PoseStamped": "pose",
    "geometry_msgs/msg/TransformStamped": "transform",
    "geometry_msgs/msg/PoseWithCovarianceStamped": "pose.pose",
    "nav_msgs/msg/Odometry": "pose.pose",
}
TF_TYPE = "tf2_msgs/msg/TFMessage"
BAG_SUFFIXES = (".bag", ".db3", ".mcap")
#: the first bytes of an SQLite file, the last 8 bytes of an MCAP file, the first line of a ROS 1 bag
SQLITE_MAGIC = b"SQLite format 3\x00"
MCAP_MAGIC = b"\x89MCAP0\r\n"
ROS1_MAGIC = b"#ROSBAG V2.0\n"


def is_bag(path: str | Path) -> bool:
    """Whether `path` names a ROS bag: a .bag / .db3 / .mcap file or a directory with metadata.yaml.
    InputError when `path` is a symbolic link that loops: it names nothing, and the CLI asks this
    first of every input path."""
    p = Path(path)
    check_not_looping(p, "file")
    return p.suffix.lower() in BAG_SUFFIXES or (p.is_dir() and (p / "metadata.yaml").is_file())


def parse_topic(spec: str) -> tuple[str, tuple[str, str] | None]:
    """``/topic`` -> (topic, None); ``/tf:PARENT,CHILD`` -> (topic, (parent, child))."""
    topic, sep, frames = str(spec).partition(":")
    if not topic.strip():
        raise InputError(f"topic {spec!r}: expected /TOPIC or /TF_TOPIC:PARENT,CHILD")
    if not sep:
        return topic.strip(), None
    parts = [_frame(p) for p in frames.split(",")]
    if len(parts) != 2 or not all(parts):
        raise InputError(f"topic {spec!r}: a tf chain is written /tf:PARENT,CHILD (two frame ids), e.g. "
                         "/tf:base_link,tool0")
    return topic.strip(), (parts[0], parts[1])


def read_bag_poses(path: str | Path, topic: str) -> PoseStack:
    """The poses of `topic` (see the module docstring for the spec) in the bag at `path`, sorted
    by header stamp, metres, format ``xyz-quat-xyzw``."""
    p, src, paths = _bag(path)
    name, frames = parse_topic(topic)
    with _open_bag(paths, src) as (reader, available):
        if name not in available:
            raise InputError(f"{src} has no topic {name!r}; it has {_listing(available)}")
        wanted = available[name]
        if frames is None and wanted not in POSE_TYPES:
            hint = f"; for tf write {name}:PARENT,CHILD" if wanted == TF_TYPE else ""
            raise InputError(f"{src}: topic {name!r} is a {wanted}, not one of {', '.join(POSE_TYPES)}{hint}; "
                             f"the bag has {_listing(available)}")
        if frames is not None and wanted != TF_TYPE:
            raise InputError(f"{src}: topic {name!r} is a {wanted}, not a {TF_TYPE}; /TOPIC:PARENT,CHILD is for "
                             f"tf topics; the bag has {_listing(available)}")
        topics = [name] + (["/tf_static"] if frames is not None and available.get("/tf_static") == TF_TYPE
                           and name != "/tf_static" else [])
        conns = [c for c in reader.connections if c.topic in topics]
        messages = [(c.topic, reader.deserialize(raw, c.msgtype)) for c, _, raw in reader.messages(connections=conns)]
    source = f"{src} {topic}"
    if frames is None:
        stamps, T = _pose_messages([m for _, m in messages], POSE_TYPES[wanted], source)
    else:
        stamps, T = _tf_chain(messages, name, frames, source)
    if len(stamps) == 0:
        raise InputError(f"{source}: no poses (the topic has no messages)")
    order = np.argsort(stamps, kind="stable")
    stamps, T = stamps[order], T[order]
    stamps.setflags(write=False)
    T.setflags(write=False)
    return PoseStack(T, "m", "xyz-quat-xyzw", None, stamps, None, source)


def _bag(path: str | Path) -> tuple[Path, str, list[Path]]:
    """(the bag's path, its name for messages, what rosbags' reader opens: a ROS 2 bag's folder
    when given its .db3/.mcap file beside metadata.yaml), after the checks every reader makes:
    InputError for a missing, looping or truncated bag."""
    p = Path(path)
    src = repr(str(p))
    check_not_looping(p, "bag")
    if not p.exists():
        raise InputError(f"bag not found: {src}")
    why = _truncation(p)
    if why:
        raise InputError(f"{src} is truncated: {why}; record or copy the bag again")
    paths = [p.parent] if p.suffix.lower() in (".db3", ".mcap") and (p.parent / "metadata.yaml").is_file() else [p]
    return p, src, paths


JOINT_STATE = "sensor_msgs/msg/JointState"


def read_bag_joints(path: str | Path, topic: str) -> Any:
    """The joint readings of a ``sensor_msgs/JointState`` `topic` in the bag at `path`: a
    (q (m, n) radians, the joints' names ordered as the first message names them, the header
    stamps (m,) seconds), sorted by stamp, for `handeye.io.joint_files.read_joints`. Every message must name the same joints
    (in any order) with a position each."""
    p, src, paths = _bag(path)
    name = str(topic).strip()
    with _open_bag(paths, src) as (reader, available):
        if available.get(name) != JOINT_STATE:
            what = f"is a {available[name]}" if name in available else "is not in it"
            raise InputError(f"{src}: topic {name!r} {what}; the joint readings are a {JOINT_STATE} topic; the bag "
                             f"has {_listing(available)}")
        conns = [c for c in reader.connections if c.topic == name]
        messages = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=conns)]
    source = f"{src} {name}"
    if not messages:
        raise InputError(f"{source}: no joint readings (the topic has no messages)")
    joints = tuple(str(j) for j in messages[0].name)
    if len(joints) < 2 or len(set(joints)) < len(joints):
        raise InputError(f"{source}: message 1 names the joints {list(joints)}; expected two or more distinct names")
    q = np.empty((len(messages), len(joints)))
    for k, m in enumerate(messages):
        names, position = [str(j) for j in m.name], np.asarray(m.position, dtype=float)
        if sorted(names) != sorted(joints) or len(position) != len(names):
            raise InputError(f"{source}: message {k + 1} names joints {names} with {len(position)} positions; every "
                             f"message must give a position to each of {list(joints)}")
        q[k] = position[[names.index(j) for j in joints]]
    if not np.all(np.isfinite(q)):
        raise InputError(f"{source}: a joint position is NaN or inf")
    stamps = np.array([_stamp(m.header) for m in messages], dtype=float)
    order = np.argsort(stamps, kind="stable")
    q, stamps = q[order], stamps[order]
    q.setflags(write=False)
    stamps.setflags(write=False)
    return q, joints, stamps


# ----------------------------------------------------------------------------- damaged bags


@contextlib.contextmanager
def _open_bag(paths: list[Path], src: str) -> Iterator[tuple[Any, dict[str, str]]]:
    """(the rosbags reader of the bag at `paths`, its topics and their message types) for the
    block; whatever a damaged bag makes rosbags raise in it (`_damaged_bag_errors`) becomes one
    InputError naming `src`, and the block's own InputErrors pass as they are."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    try:
        with AnyReader(paths, default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            yield reader, {c.topic: c.msgtype for c in reader.connections}
    except InputError:
        raise
    except _damaged_bag_errors() as exc:
        reason = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise InputError(f"{src} could not be read as a ROS bag (damaged?): {reason}") from None


def _damaged_bag_errors() -> tuple[type[BaseException], ...]:
    """What reading a damaged bag raises, found by truncating and corrupting bags of each storage:
    rosbags' own errors (opening, ROS 1 / ROS 2 readers, deserialisation), its sqlite library's
    (apsw: "database disk image is malformed"), and plain Python errors of its parsers on garbage:
    struct.error, EOFError, IndexError, KeyError, ValueError (UnicodeDecodeError), TypeError (a
    garbled QoS profile read as text), OverflowError (a length field beyond ssize_t),
    AssertionError (its consistency asserts), MemoryError (a damaged 64-bit length field makes it
    ask for terabytes, refused at once). Only the readers' blocks over an open bag (`_open_bag`) catch them."""
    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as Ros1ReaderError
    from rosbags.rosbag2 import ReaderError as Ros2ReaderError
    from rosbags.serde import SerdeError

    errors: list[type[BaseException]] = [
        AnyReaderError, Ros1ReaderError, Ros2ReaderError, SerdeError, OSError, EOFError, struct.error, IndexError,
        KeyError, ValueError, TypeError, OverflowError, AssertionError, MemoryError]
    try:
        import apsw  # rosbags' sqlite3 storage since 0.10
        errors.append(apsw.Error)
    except ImportError:  # pragma: no cover - older rosbags use the standard library's sqlite3
        import sqlite3
        errors.append(sqlite3.Error)
    return tuple(errors)


def _truncation(path: Path) -> str | None:
    """Why a storage file of the bag at `path` (a file, or a ROS 2 bag directory) is cut short,
    or None when none looks so (what cannot be told here is left to the reader)."""
    files = sorted(path.glob("*.db3")) + sorted(path.glob("*.mcap")) if path.is_dir() else [path]
    for file in files:
        size = file.stat().st_size
        with open(file, "rb") as fh:
            head = fh.read(100)
            fh.seek(max(size - len(MCAP_MAGIC), 0))
            tail = fh.read()
        why = None
        suffix = file.suffix.lower()
        if suffix == ".db3" and head.startswith(SQLITE_MAGIC):
            why = _sqlite_truncation(head, size)
        elif suffix == ".mcap" and tail != MCAP_MAGIC:
            why = f"{size} bytes that do not end with the MCAP end marker"
        elif suffix == ".bag" and head.startswith(ROS1_MAGIC):
            why = _ros1_truncation(head, size)
        if why:
            return f"{file.name} holds {why}" if file != path else why
    return None


def _sqlite_truncation(head: bytes, size: int) -> str | None:
    """The SQLite header (first 100 bytes) records the page size (offset 16) and, when valid
    (offset 92 equals offset 24), the page count (offset 28): the file holds them all."""
    page_size = int.from_bytes(head[16:18], "big")
    page_size = 65536 if page_size == 1 else page_size
    pages = int.from_bytes(head[28:32], "big")
    if len(head) < 100 or head[24:28] != head[92:96] or pages == 0 or size >= pages * page_size:
        return None
    return f"{size} bytes, but its SQLite header records {pages} pages of {page_size} bytes ({pages * page_size} bytes)"


def _ros1_truncation(head: bytes, size: int) -> str | None:
    """The bag header record after the magic line holds fields ``<len>name=value``; index_pos
    (8 bytes) is where the index starts, which the file must reach."""
    try:
        (length,) = struct.unpack_from("<I", head, len(ROS1_MAGIC))
        fields, at = {}, len(ROS1_MAGIC) + 4
        end = at + length
        while at < min(end, len(head)):
            (n,) = struct.unpack_from("<I", head, at)
            name, _, value = head[at + 4:at + 4 + n].partition(b"=")
            fields[name] = value
            at += 4 + n
        (index_pos,) = struct.unpack("<Q", fields[b"index_pos"])
    except (struct.error, KeyError):
        return None  # not the header rosbags expects: it will say so
    if size >= index_pos:
        return None
    return f"{size} bytes, but its header records the index at byte {index_pos}"


# ----------------------------------------------------------------------------- helpers


def _frame(frame_id: str) -> str:
    """ROS 1 frame ids may start with '/'; tf2 drops it."""
    return str(frame_id).strip().lstrip("/")


def _listing(available: dict[str, str]) -> str:
    return ", ".join(f"{t} ({m})" for t, m in sorted(available.items())) or "no topics"


def _stamp(header: Any) -> float:
    return float(header.stamp.sec) + 1e-9 * float(header.stamp.nanosec)


def _pose(obj: Any, source: str, k: int) -> np.ndarray:
    """4x4 from a geometry_msgs Pose (position, orientation) or Transform (translation, rotation)."""
    t = obj.position if hasattr(obj, "position") else obj.translation
    q = obj.orientation if hasattr(obj, "orientation") else obj.rotation
    quat = np.array([q.x, q.y, q.z, q.w], dtype=float)
    xyz = np.array([t.x, t.y, t.z], dtype=float)
    if not (np.all(np.isfinite(quat)) and np.all(np.isfinite(xyz))):
        raise InputError(f"{source}: message {k + 1} holds NaN or inf")
    with np.errstate(over="ignore"):  # components near 1e308 (a damaged message): norm inf, refused below
        norm = np.linalg.norm(quat)
    if abs(norm - 1.0) > 1e-3:
        raise InputError(f"{source}: message {k + 1} has a quaternion of norm {norm:.3g}, not 1")
    return make_pose(Rotation.from_quat(quat).as_matrix(), xyz)


def _pose_messages(msgs: list[Any], field: str, source: str) -> tuple[np.ndarray, np.ndarray]:
    stamps = np.array([_stamp(m.header) for m in msgs], dtype=float)
    poses = []
    for k, m in enumerate(msgs):
        obj = m
        for attr in field.split("."):
            obj = getattr(obj, attr)
        poses.append(_pose(obj, source, k))
    return stamps, np.array(poses).reshape(-1, 4, 4)


@dataclasses.dataclass
class _Link:
    static: bool
    stamps: list[float] = dataclasses.field(default_factory=list)
    poses: list[np.ndarray] = dataclasses.field(default_factory=list)


def _tf_chain(messages: list[tuple[str, Any]], topic: str, frames: tuple[str, str],
              source: str) -> tuple[np.ndarray, np.ndarray]:
    """T_parent_child at the stamps of the chain's busiest moving link."""
    from handeye.geometry.resample import resample_poses

    links: dict[tuple[str, str], _Link] = {}
    parent_of: dict[str, str] = {}
    for tp, msg in messages:
        for tr in msg.transforms:
            a, b = _frame(tr.header.frame_id), _frame(tr.child_frame_id)
            link = links.setdefault((a, b), _Link(static=tp == "/tf_static"))
            link.stamps.append(_stamp(tr.header))
            link.poses.append(_pose(tr.transform, source, len(link.poses)))
            parent_of.setdefault(b, a)
    parent, child = frames
    known = sorted(set(parent_of) | set(parent_of.values()))
    for f in frames:
        if f not in known:
            raise InputError(f"{source}: frame {f!r} is not in the tf tree of {topic}; its frames are "
                             f"{', '.join(known) or '(none)'}")
    chain = []  # links from child up to parent
    frame = child
    while frame != parent:
        if frame not in parent_of or len(chain) > len(parent_of):
            raise InputError(f"{source}: no tf chain from {parent!r} down to {child!r} (the root above "
                             f"{child!r} is {frame!r}); the tree's links (parent>child) are "
                             + ", ".join(f"{a}>{b}" for a, b in sorted(links)))
        chain.append((parent_of[frame], frame))
        frame = parent_of[frame]
    chain.reverse()
    moving = [k for k in chain if not links[k].static]
    if not moving:  # a static chain: one pose, at the stamp of its latest link
        T = np.eye(4)
        for k in chain:
            T = T @ links[k].poses[-1]
        return np.array([max(links[k].stamps[-1] for k in chain)]), T[None]
    ref = max(moving, key=lambda k: len(links[k].stamps))
    order = np.argsort(links[ref].stamps, kind="stable")
    stamps = np.asarray(links[ref].stamps)[order]
    keep = np.ones(len(stamps), bool)
    parts = {}
    for k in moving:
        s, P = np.asarray(links[k].stamps), np.array(links[k].poses)
        o = np.argsort(s, kind="stable")
        s, P = s[o], P[o]
        first = np.concatenate([[True], np.diff(s) > 0])
        s, P = s[first], P[first]
        if len(s) < 2:
            raise InputError(f"{source}: the moving link {k[0]}>{k[1]} has {len(s)} distinct stamp(s); "
                             "at least 2 are needed to interpolate it")
        res = resample_poses(s, P, stamps, max_gap=np.inf)
        full = np.full((len(stamps), 4, 4), np.nan)
        full[res.kept] = res.poses
        parts[k] = full
        keep[np.setdiff1d(np.arange(len(stamps)), res.kept)] = False
    T = np.broadcast_to(np.eye(4), (len(stamps), 4, 4)).copy()
    for k in chain:
        T = T @ (parts[k] if k in parts else links[k].poses[-1])
    return stamps[keep], T[keep]
