"""ROS conventions shared by the bag reader and writers: the optional ``rosbags`` import, the message types,
time stamps and planar poses.

Bags are read and written with the ``rosbags`` library (pure Python; its own message definitions, no ROS
installation), an optional extra: :func:`rosbags` imports it or raises :class:`RosExtraMissing`, one line
that names the extra. Poses follow REP 103 (x forward, y left, z up, angles counter-clockwise, quaternions
``(x, y, z, w)``); a planar pose is ``(x, y, yaw)``. Time stamps are ``sec`` and ``nanosec``; they become
seconds through their integer count of nanoseconds, so that a time written from seconds of up to nine
decimals reads back as the same float.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

#: The pip command that installs the extra.
EXTRA_COMMAND = "pip install 'emmi-gym[ros]'"

#: Message type names as ``rosbags`` spells them for ROS 1 and ROS 2 bags alike.
LASER_SCAN = "sensor_msgs/msg/LaserScan"
ODOMETRY = "nav_msgs/msg/Odometry"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
POSE_WITH_COVARIANCE_STAMPED = "geometry_msgs/msg/PoseWithCovarianceStamped"
OCCUPANCY_GRID = "nav_msgs/msg/OccupancyGrid"
PATH = "nav_msgs/msg/Path"
#: ROS 1's noetic store of ``rosbags`` lacks tf2_msgs: its definition, as tf2_msgs/TFMessage.msg has it.
_TF_MESSAGE_DEFINITION = "geometry_msgs/TransformStamped[] transforms"


class RosExtraMissing(ValueError):
    """The ``rosbags`` library is not installed (the ``ros`` extra)."""


def rosbags() -> SimpleNamespace:
    """The parts of ``rosbags`` used here (``highlevel``, ``rosbag1``, ``rosbag2``, ``typesys``), or
    :class:`RosExtraMissing`."""
    try:
        from rosbags import highlevel, rosbag1, rosbag2, typesys
    except ImportError:
        raise RosExtraMissing(f"ROS bags need the 'ros' extra (the rosbags library): {EXTRA_COMMAND}") from None
    return SimpleNamespace(highlevel=highlevel, rosbag1=rosbag1, rosbag2=rosbag2, typesys=typesys)


def typestore(ros1: bool):
    """The message definitions of ROS 1 noetic (with tf2_msgs added) or ROS 2 humble."""
    typesys = rosbags().typesys
    store = typesys.get_typestore(typesys.Stores.ROS1_NOETIC if ros1 else typesys.Stores.ROS2_HUMBLE)
    if TF_MESSAGE not in store.types:
        store.register(typesys.get_types_from_msg(_TF_MESSAGE_DEFINITION, TF_MESSAGE))
    return store


# ----------------------------------------------------------------------------- time


def stamp_ns(stamp) -> int:
    """A ``builtin_interfaces/Time`` as an integer count of nanoseconds."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def seconds(ns) -> np.ndarray | float:
    """Nanoseconds to seconds (one division: correctly rounded)."""
    return np.asarray(ns, dtype=np.int64) / 1e9 if np.ndim(ns) else int(ns) / 1e9


def to_ns(t: float) -> int:
    """Seconds to the nearest nanosecond."""
    return int(round(t * 1e9))


def time_message(store, ns: int):
    return store.types["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def header(store, ns: int, frame_id: str):
    """A ``std_msgs/Header`` (ROS 1's has a sequence number, left at 0)."""
    cls = store.types["std_msgs/msg/Header"]
    extra = {"seq": 0} if "seq" in cls.__dataclass_fields__ else {}
    return cls(**extra, stamp=time_message(store, ns), frame_id=frame_id)


# ----------------------------------------------------------------------------- planar poses


def planar(translation, rotation) -> tuple[float, float, float, bool]:
    """``(x, y, yaw, upside_down)`` of a 3D pose (a ``Point`` or ``Vector3`` and a ``Quaternion``): the
    heading of the frame's x axis in the plane, and whether its z axis points down (a laser mounted upside
    down sees the plane mirrored)."""
    qx, qy, qz, qw = rotation.x, rotation.y, rotation.z, rotation.w
    yaw = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    upside_down = 1.0 - 2.0 * (qx * qx + qy * qy) < 0.0
    return float(translation.x), float(translation.y), yaw, upside_down


def pose_message(store, x: float, y: float, yaw: float):
    """A ``geometry_msgs/Pose`` in the plane z = 0, turned by ``yaw`` about z."""
    types = store.types
    return types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=0.0),
        orientation=quaternion(store, yaw))


def quaternion(store, yaw: float):
    return store.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0))


def transform_stamped(store, ns: int, parent: str, child: str, x: float, y: float, yaw: float):
    types = store.types
    return types["geometry_msgs/msg/TransformStamped"](
        header=header(store, ns, parent), child_frame_id=child,
        transform=types["geometry_msgs/msg/Transform"](
            translation=types["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=0.0),
            rotation=quaternion(store, yaw)))


def odometry_message(store, ns: int, parent: str, child: str, pose):
    """A ``nav_msgs/Odometry`` of the planar ``pose`` of ``child`` in ``parent``, at rest, covariances 0."""
    types = store.types
    zeros, vector = np.zeros(36), types["geometry_msgs/msg/Vector3"]
    still = types["geometry_msgs/msg/Twist"](linear=vector(x=0.0, y=0.0, z=0.0), angular=vector(x=0.0, y=0.0, z=0.0))
    return types[ODOMETRY](
        header=header(store, ns, parent), child_frame_id=child,
        pose=types["geometry_msgs/msg/PoseWithCovariance"](pose=pose_message(store, *pose), covariance=zeros),
        twist=types["geometry_msgs/msg/TwistWithCovariance"](twist=still, covariance=zeros))
