"""handeye.io.bag_readers: pose streams from ROS 1 / ROS 2 bags written here with rosbags' own writers."""

from __future__ import annotations

import json

import numpy as np
import pytest

from handeye import InputError
from handeye.cli import main
from handeye.geometry.se3 import inverse, make_pose, so3_exp
from handeye.io.bag_readers import is_bag, parse_topic, read_bag_poses
from handeye.io.pose_readers import PoseStack
from handeye.io.pose_writers import write_poses

rosbags = pytest.importorskip("rosbags")
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

ROS1 = get_typestore(Stores.ROS1_NOETIC)  # a fresh store; noetic's lacks tf2_msgs, added as ROS defines it
ROS1.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
ROS2 = get_typestore(Stores.ROS2_HUMBLE)
POSE = "geometry_msgs/msg/PoseStamped"
TRANSFORM = "geometry_msgs/msg/TransformStamped"
COVARIANCE = "geometry_msgs/msg/PoseWithCovarianceStamped"
ODOMETRY = "nav_msgs/msg/Odometry"
TF = "tf2_msgs/msg/TFMessage"


def poses(n: int, seed: int = 0) -> np.ndarray:
    """n poses in metres, rotations of up to ~1 rad."""
    rng = np.random.default_rng(seed)
    return make_pose(so3_exp(rng.uniform(-0.6, 0.6, (n, 3))), rng.uniform(-1, 1, (n, 3)))


STAMPS = [(100, 0), (100, 10_000_000), (100, 20_000_000), (100, 999_999_999), (101, 5)]
SECONDS = np.array([s + 1e-9 * ns for s, ns in STAMPS])


class Messages:
    """Builds messages of one typestore (ROS 1 headers have a seq field, ROS 2 ones do not)."""

    def __init__(self, store):
        self.store, self.T = store, store.types

    def header(self, stamp, frame="base_link"):
        kw = {"seq": 0} if "seq" in self.T["std_msgs/msg/Header"].__dataclass_fields__ else {}
        return self.T["std_msgs/msg/Header"](stamp=self.T["builtin_interfaces/msg/Time"](sec=stamp[0], nanosec=stamp[1]),
                                             frame_id=frame, **kw)

    def _parts(self, T):
        from scipy.spatial.transform import Rotation

        x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
        q = self.T["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)
        return T[:3, 3], q

    def pose(self, T):
        t, q = self._parts(T)
        return self.T["geometry_msgs/msg/Pose"](position=self.T["geometry_msgs/msg/Point"](x=t[0], y=t[1], z=t[2]),
                                                orientation=q)

    def transform(self, stamp, parent, child, T):
        t, q = self._parts(T)
        tr = self.T["geometry_msgs/msg/Transform"](translation=self.T["geometry_msgs/msg/Vector3"](x=t[0], y=t[1], z=t[2]),
                                                   rotation=q)
        return self.T[TRANSFORM](header=self.header(stamp, parent), child_frame_id=child, transform=tr)

    def message(self, msgtype, stamp, T):
        if msgtype == POSE:
            return self.T[POSE](header=self.header(stamp), pose=self.pose(T))
        if msgtype == TRANSFORM:
            return self.transform(stamp, "base_link", "tool0", T)
        cov = self.T["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(T), covariance=np.zeros(36))
        if msgtype == COVARIANCE:
            return self.T[COVARIANCE](header=self.header(stamp), pose=cov)
        twist = self.T["geometry_msgs/msg/TwistWithCovariance"](
            twist=self.T["geometry_msgs/msg/Twist"](linear=self.T["geometry_msgs/msg/Vector3"](x=0, y=0, z=0),
                                                    angular=self.T["geometry_msgs/msg/Vector3"](x=0, y=0, z=0)),
            covariance=np.zeros(36))
        return self.T[ODOMETRY](header=self.header(stamp), child_frame_id="tool0", pose=cov, twist=twist)


def write_bag(path, kind: str, topics: dict[str, tuple[str, list]]):
    """A bag at `path`: kind 'ros1', 'sqlite3' or 'mcap'; topics: name -> (msgtype, [(stamp, message)])."""
    if kind == "ros1":
        with Writer1(path) as writer:
            for name, (msgtype, msgs) in topics.items():
                conn = writer.add_connection(name, msgtype, typestore=ROS1)
                for k, (stamp, msg) in enumerate(msgs):
                    writer.write(conn, stamp[0] * 10**9 + stamp[1] + k, ROS1.serialize_ros1(msg, msgtype))
        return path
    plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
    with Writer2(path, version=9, storage_plugin=plugin) as writer:
        for name, (msgtype, msgs) in topics.items():
            conn = writer.add_connection(name, msgtype, typestore=ROS2)
            for k, (stamp, msg) in enumerate(msgs):
                writer.write(conn, stamp[0] * 10**9 + stamp[1] + k, ROS2.serialize_cdr(msg, msgtype))
    return path


def store(kind):
    return Messages(ROS1 if kind == "ros1" else ROS2)


def bag_path(tmp_path, kind):
    return tmp_path / ("poses.bag" if kind == "ros1" else f"poses_{kind}")


@pytest.mark.parametrize("kind", ["ros1", "sqlite3", "mcap"])
@pytest.mark.parametrize("msgtype", [POSE, TRANSFORM, COVARIANCE, ODOMETRY])
def test_pose_topics_read_back_exactly(tmp_path, kind, msgtype):
    m, T = store(kind), poses(len(STAMPS))
    order = [2, 0, 4, 1, 3]  # recorded out of stamp order: read back sorted by header stamp
    path = write_bag(bag_path(tmp_path, kind), kind,
                     {"/robot/pose": (msgtype, [(STAMPS[i], m.message(msgtype, STAMPS[i], T[i])) for i in order])})
    assert is_bag(path)
    stack = read_bag_poses(path, "/robot/pose")
    assert stack.unit == "m" and stack.format == "xyz-quat-xyzw"
    np.testing.assert_array_equal(stack.stamps, SECONDS)
    np.testing.assert_allclose(stack.poses, T, atol=1e-15, rtol=0)
    if kind != "ros1":  # the storage file inside the bag directory names the bag too
        inner = next(p for p in path.iterdir() if p.suffix in (".db3", ".mcap"))
        np.testing.assert_array_equal(read_bag_poses(inner, "/robot/pose").stamps, SECONDS)


@pytest.mark.parametrize("kind", ["ros1", "sqlite3"])
def test_tf_chain_through_a_static_link_and_two_moving_ones(tmp_path, kind):
    m = store(kind)
    n = 6
    t = [(50, k * 100_000_000) for k in range(n)]  # 10 Hz
    base_arm, arm_tool = poses(n, 1), poses(2 * n, 2)
    tool_cam = poses(1, 3)[0]
    t_fast = [(50, k * 50_000_000) for k in range(2 * n)]  # 20 Hz
    tf = [(s, m.T[TF](transforms=[m.transform(s, "/base_link", "arm", base_arm[k])])) for k, s in enumerate(t)]
    tf += [(s, m.T[TF](transforms=[m.transform(s, "arm", "tool0", arm_tool[k]),
                                   m.transform(s, "map", "odom", np.eye(4))])) for k, s in enumerate(t_fast)]
    static = [((50, 0), m.T[TF](transforms=[m.transform((50, 0), "tool0", "camera", tool_cam)]))]
    path = write_bag(bag_path(tmp_path, kind), kind, {"/tf": (TF, tf), "/tf_static": (TF, static)})
    # the busiest moving link (arm>tool0, 20 Hz) gives the stamps; base_link>arm is interpolated
    # at them, and its span ends at 0.5 s, so stamps after it are dropped (no extrapolation)
    stack = read_bag_poses(path, "/tf:base_link,camera")
    seconds = np.array([50 + 0.05 * k for k in range(2 * n)])
    inside = seconds <= 50.5 + 1e-12
    np.testing.assert_allclose(stack.stamps, seconds[inside], atol=1e-12)
    even = np.flatnonzero(inside)[::2]  # 10 Hz stamps: base_link>arm needs no interpolation there
    expected = base_arm[: len(even)] @ arm_tool[even] @ tool_cam
    np.testing.assert_allclose(stack.poses[::2], expected, atol=1e-12)
    single = read_bag_poses(path, "/tf:arm,tool0")
    np.testing.assert_allclose(single.poses, arm_tool, atol=1e-15)
    with pytest.raises(InputError, match=r"frame 'flange' is not in the tf tree of /tf; its frames are arm, "
                                         r"base_link, camera, map, odom, tool0"):
        read_bag_poses(path, "/tf:base_link,flange")
    with pytest.raises(InputError, match="no tf chain from 'odom' down to 'camera'"):
        read_bag_poses(path, "/tf:odom,camera")
    with pytest.raises(InputError, match=r"topic '/tf' is a tf2_msgs/msg/TFMessage.*write /tf:PARENT,CHILD"):
        read_bag_poses(path, "/tf")


def test_bad_topics_and_files_name_what_the_bag_has(tmp_path):
    m = store("ros1")
    path = write_bag(tmp_path / "a.bag", "ros1", {
        "/pose": (POSE, [(STAMPS[0], m.message(POSE, STAMPS[0], np.eye(4)))]),
        "/status": ("std_msgs/msg/String", [(STAMPS[0], ROS1.types["std_msgs/msg/String"](data="ok"))])})
    listing = r"it has /pose \(geometry_msgs/msg/PoseStamped\), /status \(std_msgs/msg/String\)"
    with pytest.raises(InputError, match=r"has no topic '/cam'; " + listing):
        read_bag_poses(path, "/cam")
    with pytest.raises(InputError, match=r"topic '/status' is a std_msgs/msg/String, not one of .*PoseStamped"):
        read_bag_poses(path, "/status")
    with pytest.raises(InputError, match="is a geometry_msgs/msg/PoseStamped, not a tf2_msgs/msg/TFMessage"):
        read_bag_poses(path, "/pose:base,tool")
    with pytest.raises(InputError, match=r"/tf:PARENT,CHILD \(two frame ids\)"):
        parse_topic("/tf:base")
    (tmp_path / "broken.bag").write_bytes(b"not a bag at all")
    with pytest.raises(InputError, match="could not be read as a ROS bag") as info:
        read_bag_poses(tmp_path / "broken.bag", "/pose")
    assert "\n" not in str(info.value)
    with pytest.raises(InputError, match="bag not found"):
        read_bag_poses(tmp_path / "missing.bag", "/pose")


def test_calibrate_reads_a_bag_and_a_csv_stream(tmp_path, capsys):
    """A robot bag (ROS 2, PoseStamped at 100 Hz) and a camera CSV stream, 25 ms apart."""
    from test_streams import NOISE, cell

    robot, camera = cell(0.025, NOISE, seconds=12.0, seed=7)
    robot, camera = robot.in_unit("m"), camera.in_unit("m")
    m = store("sqlite3")
    stamps = [(int(s), round((s - int(s)) * 1e9)) for s in robot.stamps]
    path = write_bag(tmp_path / "robot", "sqlite3",
                     {"/flange": (POSE, [(s, m.message(POSE, s, T)) for s, T in zip(stamps, robot.poses)])})
    write_poses(tmp_path / "camera.csv", PoseStack(inverse(camera.poses), "m", "matrix", stamps=camera.stamps),
                "xyz-quat-xyzw")
    argv = ["calibrate", "--robot", path, "--robot-topic", "/flange", "--camera", tmp_path / "camera.csv",
            "--camera-format", "xyz-quat-xyzw", "--camera-unit", "m", "--camera-poses", "camera-in-board",
            "--setup", "eye-in-hand", "--match", "interpolate", "--json"]
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert code == 0, err
    offset = json.loads(out)["matching"]["time_offset"]
    assert abs(offset - 0.025) < 2e-3
    code = main([str(a) for a in argv if a != "/flange" and a != "--robot-topic"])
    assert code == 2 and "is a ROS bag: name its pose topic with --robot-topic" in capsys.readouterr().err
