"""An independent DDS peer for `ratf run --ros2`: Eclipse Cyclone DDS (PyPI `cyclonedds`)
with ROS 2's naming (`rt/<ns>/scan`, `sensor_msgs::msg::dds_::LaserScan_`), not our code.

1. subscribes `scan` and `odom` and checks what arrives (frames, sizes, finite values);
2. joins `tf_static` late (transient-local) and still gets base_footprint → laser, imu_link;
3. publishes `cmd_vel` (a turn on the spot) and sees the robot turn on `odom`;
4. asks the volatile `scan` for transient-local data, a QoS that cannot match: it gets
   nothing, and ratf reports the mismatch (the Rust test reads ratf's stderr).

Usage: python dds_peer.py NAMESPACE (e.g. /robot1, or "" for none); ROS_DOMAIN_ID as the
robot's. Prints one line per check and ends with "N passed, M failed"; exits 1 on a failure.
"""

import math
import os
import sys
import time
from dataclasses import dataclass

import cyclonedds.idl.annotations as annotate
from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, float32, float64, int32, sequence, uint32
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration


@dataclass
@annotate.final
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32
    nanosec: uint32


@dataclass
@annotate.final
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time
    frame_id: str


@dataclass
@annotate.final
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64
    y: float64
    z: float64


@dataclass
@annotate.final
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64
    y: float64
    z: float64


@dataclass
@annotate.final
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64
    y: float64
    z: float64
    w: float64


@dataclass
@annotate.final
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point
    orientation: Quaternion


@dataclass
@annotate.final
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose
    covariance: array[float64, 36]


@dataclass
@annotate.final
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3
    angular: Vector3


@dataclass
@annotate.final
class TwistWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    twist: Twist
    covariance: array[float64, 36]


@dataclass
@annotate.final
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header
    child_frame_id: str
    pose: PoseWithCovariance
    twist: TwistWithCovariance


@dataclass
@annotate.final
class LaserScan(IdlStruct, typename="sensor_msgs::msg::dds_::LaserScan_"):
    header: Header
    angle_min: float32
    angle_max: float32
    angle_increment: float32
    time_increment: float32
    scan_time: float32
    range_min: float32
    range_max: float32
    ranges: sequence[float32]
    intensities: sequence[float32]


@dataclass
@annotate.final
class Transform(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3
    rotation: Quaternion


@dataclass
@annotate.final
class TransformStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
    header: Header
    child_frame_id: str
    transform: Transform


@dataclass
@annotate.final
class TFMessage(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
    transforms: sequence[TransformStamped]


passed = 0
failed = 0


def check(name, ok, detail=""):
    global passed, failed
    if ok:
        passed += 1
        print(f"ok    {name}", flush=True)
    else:
        failed += 1
        print(f"FAIL  {name}: {detail}", flush=True)


def take_until(reader, deadline_s, enough):
    """Samples with data until `enough(samples)` or the deadline (the writer's exit sends
    one invalid sample per topic: skipped)."""
    samples = []
    end = time.monotonic() + deadline_s
    while time.monotonic() < end and not enough(samples):
        for sample in reader.take(N=100):
            if isinstance(sample, IdlStruct):
                samples.append(sample)
        time.sleep(0.01)
    return samples


def main(namespace):
    prefix = "rt" + namespace.rstrip("/")
    # Cyclone's domain is its own setting: a ROS 2 RMW maps ROS_DOMAIN_ID onto it.
    participant = DomainParticipant(int(os.environ.get("ROS_DOMAIN_ID", "0")))
    reliable = Qos(
        Policy.Reliability.Reliable(duration(seconds=1)),
        Policy.Durability.Volatile,
        Policy.History.KeepLast(50),
    )
    scans = DataReader(participant, Topic(participant, f"{prefix}/scan", LaserScan), qos=reliable)
    odom = DataReader(participant, Topic(participant, f"{prefix}/odom", Odometry), qos=reliable)

    got = take_until(scans, 30.0, lambda s: len(s) >= 3)
    check("scans arrive on rt/…/scan as sensor_msgs::msg::dds_::LaserScan_", len(got) >= 3, f"{len(got)} scans")
    if got:
        scan = got[-1]
        finite = [r for r in scan.ranges if math.isfinite(r)]
        check(
            "a scan: frame laser, clockwise rays, finite ranges within its limits",
            scan.header.frame_id == "laser"
            and scan.angle_increment < 0
            and len(scan.ranges) > 100
            and len(finite) > 50
            and all(scan.range_min <= r <= scan.range_max for r in finite),
            f"{scan.header.frame_id} {scan.angle_increment} {len(scan.ranges)} rays, {len(finite)} finite",
        )

    # Late join: tf_static was published once, at the start; a transient-local reader
    # created now still gets it.
    latched = Qos(
        Policy.Reliability.Reliable(duration(seconds=1)),
        Policy.Durability.TransientLocal,
        Policy.History.KeepLast(1),
    )
    static = DataReader(participant, Topic(participant, f"{prefix}/tf_static", TFMessage), qos=latched)
    got = take_until(static, 10.0, lambda s: len(s) >= 1)
    children = {(t.header.frame_id, t.child_frame_id) for m in got for t in m.transforms}
    check(
        "tf_static joined late still arrives: base_footprint → laser, imu_link",
        children == {("base_footprint", "laser"), ("base_footprint", "imu_link")},
        str(children),
    )

    # cmd_vel: turn on the spot at 1 rad/s for 1.5 s, 20 Hz (inside the 0.5 s deadman).
    writer_qos = Qos(
        Policy.Reliability.Reliable(duration(seconds=1)),
        Policy.Durability.Volatile,
        Policy.History.KeepLast(10),
        Policy.DataRepresentation(use_cdrv0_representation=True),
    )
    cmd_vel = DataWriter(participant, Topic(participant, f"{prefix}/cmd_vel", Twist), qos=writer_qos)
    take_until(odom, 0.5, lambda s: False)
    turn = Twist(linear=Vector3(0.0, 0.0, 0.0), angular=Vector3(0.0, 0.0, 1.0))
    end = time.monotonic() + 1.5
    while time.monotonic() < end:
        cmd_vel.write(turn)
        time.sleep(0.05)
    got = take_until(odom, 2.0, lambda s: False)
    rates = [o.twist.twist.angular.z for o in got]
    check(
        "cmd_vel drives the robot: odom shows it turning at about 1 rad/s",
        bool(rates) and max(rates) > 0.5,
        f"largest yaw rate {max(rates) if rates else None} over {len(rates)} odom messages",
    )
    frames = {(o.header.frame_id, o.child_frame_id) for o in got}
    check("odom is odom → base_footprint", frames == {("odom", "base_footprint")}, str(frames))

    # A QoS that cannot match: transient-local asked of the volatile scan writer. ratf
    # must say so on its side (the test reads its stderr); here, nothing arrives.
    mismatched = Qos(
        Policy.Reliability.Reliable(duration(seconds=1)),
        Policy.Durability.TransientLocal,
        Policy.History.KeepLast(1),
    )
    wrong = DataReader(participant, Topic(participant, f"{prefix}/scan", LaserScan), qos=mismatched)
    got = take_until(wrong, 1.5, lambda s: False)
    check("a transient-local reader of the volatile scan gets nothing", not got, f"{len(got)} scans")
    print("qos-mismatch reader created", flush=True)

    print(f"\ndds-peer: {passed} passed, {failed} failed", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: dds_peer.py NAMESPACE")
    sys.exit(main(sys.argv[1]))
