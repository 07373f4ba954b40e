"""Reads a ratf recording with the `mcap` and `mcap-ros2-support` packages (independent of
ratf: they decode each ROS 2 message by the `ros2msg` schema embedded in the file) and
checks the decoded values against the run recorded beside them in the same file (the JSON
channels: every input the core consumed, its status at every host tick, the simulator's
truth). Then prints the figures: topics, message counts, rates, bytes per second.

Usage: python check_ros2_recording.py RECORDING.mcap
Ends with "N passed, M failed" and exits 1 when a check failed.
"""

import collections
import json
import math
import os
import struct
import sys
import tomllib

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

ROS_TOPICS = {
    "/tf_static": "tf2_msgs/msg/TFMessage",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/scan": "sensor_msgs/msg/LaserScan",
    "/odom": "nav_msgs/msg/Odometry",
    "/imu": "sensor_msgs/msg/Imu",
    "/localiser/pose": "geometry_msgs/msg/PoseWithCovarianceStamped",
    "/sim/true_pose": "geometry_msgs/msg/PoseStamped",
    "/markers/field": "visualization_msgs/msg/MarkerArray",
    "/markers/beacons": "visualization_msgs/msg/MarkerArray",
    "/markers/parts": "visualization_msgs/msg/MarkerArray",
    "/markers/path": "visualization_msgs/msg/MarkerArray",
    "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
}

passed = 0
failed = 0


def check(name, ok, detail=""):
    global passed, failed
    if ok:
        passed += 1
        print(f"ok    {name}")
    else:
        failed += 1
        print(f"FAIL  {name}: {detail}")


def f32(x):
    return struct.unpack("<f", struct.pack("<f", x))[0]


def yaw(q):
    return 2.0 * math.atan2(q.z, q.w)


def wrap(a):
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def compose(a, b):
    """Planar poses (x, y, yaw): b expressed in a's frame, returned in a's parent."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2])


def planar(transform):
    t = transform.translation
    return (t.x, t.y, yaw(transform.rotation))


def main(path):
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        channels = {c.topic: c for c in summary.channels.values()}
        for topic, type_name in ROS_TOPICS.items():
            channel = channels.get(topic)
            schema = summary.schemas.get(channel.schema_id) if channel else None
            check(
                f"{topic} is a cdr channel of {type_name} with a ros2msg schema",
                channel is not None
                and channel.message_encoding == "cdr"
                and schema.name == type_name
                and schema.encoding == "ros2msg",
                f"{channel} {schema}",
            )
        json_msgs = collections.defaultdict(list)
        ros = collections.defaultdict(list)
        sizes = collections.Counter()
        for schema, channel, message in reader.iter_messages():
            sizes[channel.topic] += len(message.data)
            if channel.message_encoding == "json":
                json_msgs[channel.topic].append(json.loads(message.data))
        f.seek(0)
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages(
            topics=list(ROS_TOPICS)
        ):
            ros[channel.topic].append((message.log_time, decoded))

    session = json_msgs["/ratf/session"][0]
    config = tomllib.loads(session["config_toml"])
    lidar = config["lidar"]
    inputs = json_msgs["/ratf/input"]
    scans = [i["input"] for i in inputs if i["input"]["type"] == "scan"]
    imus = [i["input"] for i in inputs if i["input"]["type"] == "imu"]
    ticks = [i for i in inputs if i["input"]["type"] == "host_tick"]
    status = json_msgs["/ratf/status"]
    truth = json_msgs["/sim/truth"]

    # The scans: one message per scan input, each range at its sample index, corrected.
    check("one /scan per scan input", len(ros["/scan"]) == len(scans), f"{len(ros['/scan'])} vs {len(scans)}")
    mismatches = 0
    placed = 0
    points = 0
    worst_angle = 0.0
    for (_, message), scan in zip(ros["/scan"], scans):
        stamp_ns = message.header.stamp.sec * 10**9 + message.header.stamp.nanosec
        if abs(stamp_ns - scan["stamp_us"] * 1000.0) > 1.0:
            mismatches += 1
        rays = len(message.ranges)
        step = abs(message.angle_increment)
        direction = 1.0 if message.angle_increment > 0 else -1.0
        taken = set()
        for p in scan["points"]:
            points += 1
            turned = (direction * (p["angle_rad"] - message.angle_min)) % (2.0 * math.pi)
            want = f32((p["range_m"] - lidar["range_offset_m"]) / lidar["range_scale"])
            x = turned / step
            # The writer places a point by its f64 angles; a reader has the message's f32
            # angle_min and increment, which move `x` by up to ~1e-4 ray: a point that far
            # from halfway between two rays may stand in either.
            if abs(x - math.floor(x) - 0.5) < 1e-3:
                near = [math.floor(x) % rays, math.ceil(x) % rays]
                near.sort(key=lambda r: (r in taken, message.ranges[r] != want))
                k = near[0]
            else:
                k = round(x) % rays
            if k in taken:
                continue
            taken.add(k)
            if message.ranges[k] != want:
                mismatches += 1
            placed += 1
            ray = message.angle_min + k * message.angle_increment
            worst_angle = max(worst_angle, abs(wrap(ray - p["angle_rad"])))
        finite = sum(1 for r in message.ranges if math.isfinite(r))
        if finite != len(taken):
            mismatches += 1
    check(
        "every scan point's corrected range is in the ray of its own angle, stamps are acquisition times",
        mismatches == 0 and points > 0,
        f"{mismatches} mismatches over {points} points",
    )
    check(
        "the rays are within half a ray of the X4's angles, and at least 99 % of the points have a ray",
        worst_angle <= 0.5 * step + 1e-5 and placed >= 0.99 * points,
        f"worst {math.degrees(worst_angle):.3f}°, {placed} of {points} placed",
    )
    print(
        f"      scan points placed {placed} of {points} ({100.0 * placed / max(points, 1):.2f} %);"
        f" worst angle residual {math.degrees(worst_angle):.3f}°"
    )

    # The pose track: the localiser's pose at every host tick.
    poses = ros["/localiser/pose"]
    check("one /localiser/pose per status", len(poses) == len(status), f"{len(poses)} vs {len(status)}")
    worst = 0.0
    asymmetric = 0
    for (_, message), s in zip(poses, status):
        p = message.pose.pose
        worst = max(
            worst,
            abs(p.position.x - s["pose"]["x"]),
            abs(p.position.y - s["pose"]["y"]),
            abs(wrap(yaw(p.orientation) - s["pose"]["yaw_rad"])),
        )
        c = message.pose.covariance
        if any(abs(c[i * 6 + j] - c[j * 6 + i]) > 1e-15 for i in range(6) for j in range(6)):
            asymmetric += 1
        if c[0] <= 0 or c[7] <= 0 or c[35] <= 0:
            asymmetric += 1
        sx = math.sqrt(max(c[0], c[7]))
        if sx > 0 and s["pose_std"][0] + 1e-9 < sx * 0.999:
            asymmetric += 1
    check("the pose track is the localiser's, to 1e-9", worst < 1e-9, f"worst {worst}")
    check("the covariance is symmetric with positive variances", asymmetric == 0, f"{asymmetric} bad")

    # The tf chain: map → odom → base_footprint is the localiser's pose.
    tf = ros["/tf"]
    check("one /tf per host tick", len(tf) == len(ticks), f"{len(tf)} vs {len(ticks)}")
    worst = 0.0
    chain_ok = True
    for (_, message), s in zip(tf, status):
        frames = [(t.header.frame_id, t.child_frame_id) for t in message.transforms]
        chain_ok &= frames == [("map", "odom"), ("odom", "base_footprint")]
        pose = compose(planar(message.transforms[0].transform), planar(message.transforms[1].transform))
        worst = max(
            worst,
            abs(pose[0] - s["pose"]["x"]),
            abs(pose[1] - s["pose"]["y"]),
            abs(wrap(pose[2] - s["pose"]["yaw_rad"])),
        )
    check("/tf is map → odom → base_footprint", chain_ok)
    check("map → odom → base_footprint composes to the localiser's pose (1e-9)", worst < 1e-9, f"worst {worst}")
    static = ros["/tf_static"]
    robot = config["robot"]
    ok = len(static) == 1
    if ok:
        t = {tr.child_frame_id: tr for tr in static[0][1].transforms}
        laser = t.get("laser")
        ok = (
            set(t) == {"laser", "imu_link"}
            and all(tr.header.frame_id == "base_footprint" for tr in t.values())
            and abs(laser.transform.translation.x - robot["lidar_x_m"]) < 1e-12
            and abs(laser.transform.translation.y - robot["lidar_y_m"]) < 1e-12
            and abs(wrap(yaw(laser.transform.rotation) - math.radians(robot["lidar_yaw_deg"]))) < 1e-9
        )
    check("/tf_static: base_footprint → laser (as configured) and → imu_link, once", ok)

    # The truth, the odometry, the IMU.
    worst = max(
        (
            max(abs(m.pose.position.x - t["pose"]["x"]), abs(m.pose.position.y - t["pose"]["y"]))
            for (_, m), t in zip(ros["/sim/true_pose"], truth)
        ),
        default=1.0,
    )
    check(
        "/sim/true_pose is the simulator's truth",
        len(ros["/sim/true_pose"]) == len(truth) > 0 and worst < 1e-12,
        f"{len(ros['/sim/true_pose'])} vs {len(truth)}, worst {worst}",
    )
    wheels = sum(1 for i in inputs if i["input"]["type"] == "wheels")
    check("one /odom per telemetry batch but the first", len(ros["/odom"]) == wheels - 1, f"{len(ros['/odom'])} vs {wheels}")
    odom_frames = all(m.header.frame_id == "odom" and m.child_frame_id == "base_footprint" for _, m in ros["/odom"])
    grows = ros["/odom"][-1][1].pose.covariance[0] > 0 if ros["/odom"] else False
    check("/odom is odom → base_footprint with a growing covariance", odom_frames and grows)
    imu_ok = len(ros["/imu"]) == len(imus) and all(
        m.angular_velocity.z == s["gyro_rad_s"][2] and m.orientation_covariance[0] == -1.0
        for (_, m), s in zip(ros["/imu"], imus)
    )
    check("one /imu per sample, the gyro's rates exact, no orientation", imu_ok)

    # The markers.
    field = ros["/markers/field"]
    namespaces = collections.Counter(m.ns for m in field[0][1].markers) if field else {}
    check(
        "the field: the floor, warehouse and machine walls and dividers",
        len(field) == 1
        and namespaces["field/floor"] == 1
        and namespaces["field/WarehouseWall"] == 2
        and namespaces["field/MachineWall"] == 2
        and namespaces["field/WarehouseDivider"] > 0
        and namespaces["field/MachineDivider"] > 0,
        str(namespaces),
    )
    beacons = ros["/markers/beacons"]
    used = sum(1 for _, m in beacons for b in m.markers if b.color.g > 0.5)
    check(
        "four beacons per scan, most of them used",
        len(beacons) == len(scans) and all(len(m.markers) == 4 for _, m in beacons) and used > 2 * len(beacons),
        f"{used} used over {len(beacons)} scans",
    )
    part_lists = [
        e for o in json_msgs["/ratf/output"] for e in o["outputs"].get("events", []) if e["event"] == "part_list"
    ]
    parts = ros["/markers/parts"]
    last = [m for m in parts[-1][1].markers if m.action == 0] if parts else []
    listed = sum(1 for p in part_lists[0]["parts"] if p) if part_lists else -1
    check(
        "the parts: one marker per listed part, in red, green or blue",
        len(last) == listed
        and all(max(m.color.r, m.color.g, m.color.b) > 0.7 for m in last)
        and parts[-1][1].markers[0].action == 3,
        f"{len(last)} markers, {listed} listed",
    )
    legs = [m for _, m in ros["/markers/path"] if len(m.markers) == 3]
    actions = sum(
        1 for o in json_msgs["/ratf/output"] for e in o["outputs"].get("events", []) if e["event"] == "action_started"
    )
    check(
        "the planned path: per leg a line ending at its target (one leg to the pick, one to the drop)",
        actions <= len(legs) <= 2 * actions
        and all(
            m.markers[1].type == 4
            and len(m.markers[1].points) >= 2
            and m.markers[2].type == 2
            and math.hypot(
                m.markers[1].points[-1].x - m.markers[2].pose.position.x,
                m.markers[1].points[-1].y - m.markers[2].pose.position.y,
            )
            < 1e-3
            for m in legs
        ),
        f"{len(legs)} legs, {actions} actions",
    )
    diagnostics = ros["/diagnostics"]
    names = {s.name for s in diagnostics[-1][1].status} if diagnostics else set()
    check(
        "diagnostics: Mega link, lidar, IMU, server, localiser, mission",
        names
        == {"ratf: Mega link", "ratf: lidar", "ratf: IMU", "ratf: server", "ratf: localiser", "ratf: mission"}
        and all(s.level == 0 for s in diagnostics[-1][1].status),
        str(names),
    )

    # Figures.
    duration_s = (ticks[-1]["time"] - ticks[0]["time"]) * 1e-6 if len(ticks) > 1 else 0.0
    file_bytes = os.path.getsize(path)
    print(f"\nfigures for {os.path.basename(path)}: {duration_s:.1f} s of robot time")
    print(f"{'topic':<20} {'type':<45} {'messages':>9} {'Hz':>7} {'bytes/s (raw)':>14}")
    for topic in ROS_TOPICS:
        n = len(ros[topic])
        print(
            f"{topic:<20} {ROS_TOPICS[topic]:<45} {n:>9} {n / duration_s if duration_s else 0:>7.1f}"
            f" {sizes[topic] / duration_s if duration_s else 0:>14.0f}"
        )
    ros_raw = sum(sizes[t] for t in ROS_TOPICS)
    json_raw = sum(v for t, v in sizes.items() if t not in ROS_TOPICS)
    print(
        f"ROS 2 topics {ros_raw / duration_s:.0f} B/s raw, the JSON run record {json_raw / duration_s:.0f} B/s raw;"
        f" the file (zstd) {file_bytes} bytes = {file_bytes / duration_s:.0f} B/s"
    )
    print(f"\nros2-recording: {passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: check_ros2_recording.py RECORDING.mcap")
    sys.exit(main(sys.argv[1]))
