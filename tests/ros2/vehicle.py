#!/usr/bin/env python3
"""A ROS 2 node that plays a tcpf vehicle, with nothing of tcpf's: eclipse-zenoh for the bus and
rosbags for ROS 2's types, hashes and CDR, speaking rmw_zenoh's wire format. As a vehicle's
driver or simulator would, it takes its start from the vehicle's planned path (transient local:
it comes after the path was published), follows the commands on `vehicle_<id>/cmd`
(geometry_msgs/Twist: linear.x the speed through the water, angular.z the yaw rate), integrates
the kinematic vehicle of docs/MODEL.md in the water current, and publishes
`vehicle_<id>/odom` (nav_msgs/Odometry) every control period, stamped with the wall clock. It
stops when the fleet's world leaves the ROS 2 graph, and writes what it did as JSON.

    vehicle.py ENDPOINT CREDENTIAL DOMAIN NAMESPACE ID TIME_SCALE CONTROL_PERIOD CURRENT_X CURRENT_Y OUT.json
               [every=N] [jitter=J] [frame=NAME]

As drivers do: `every=3` publishes every third control period, `jitter=0.3` draws each wait
between 70 % and 130 % of its length (seeded: the same waits every run), `frame=odom` stamps the
pose in another frame than the fleet's `map`.
"""

import hashlib
import json
import math
import os
import random
import sys
import threading
import time

import numpy
import zenoh
from rosbags.typesys import Stores, get_typestore

STORE = get_typestore(Stores.ROS2_JAZZY)
QOS = "1:2:1,10:,:,:,,"


def dds(name):
    package, _, message = name.split("/")
    return f"{package}::msg::dds_::{message}_"


class Ros2:
    """One node of rmw_zenoh's graph on a Zenoh session: its keys, tokens and attachments."""

    def __init__(self, session, domain, namespace, node):
        self.session, self.domain, self.namespace, self.node = session, domain, namespace, node
        self.zid, self.next, self.tokens = str(session.info.zid()), 0, []

    def topic(self, rest):
        return f"{self.namespace.rstrip('/')}/{rest}"

    def key(self, topic, name):
        return f"{self.domain}/{topic.strip('/')}/{dds(name)}/{STORE.hash_rihs01(name)}"

    def token(self, kind, topic, name):
        self.next += 1
        mangle = lambda s: s.replace("/", "%")
        token = (f"@ros2_lv/{self.domain}/{self.zid}/0/{self.next}/{kind}/%/{mangle(self.namespace)}/{self.node}/"
                 f"{mangle(topic)}/{dds(name)}/{STORE.hash_rihs01(name)}/{QOS}")
        self.tokens.append(self.session.liveliness().declare_token(token))
        return token

    def declared(self):
        self.tokens.append(self.session.liveliness().declare_token(
            f"@ros2_lv/{self.domain}/{self.zid}/0/0/NN/%/{self.namespace.replace('/', '%')}/{self.node}"))


def main():
    (endpoint, credential, domain, namespace, vid, time_scale, period,
     cx, cy, out) = sys.argv[1:11]
    vid, time_scale, period, current = int(vid), float(time_scale), float(period), (float(cx), float(cy))
    options = dict(option.split("=", 1) for option in sys.argv[11:])
    every, jitter = int(options.get("every", 1)), float(options.get("jitter", 0))
    frame, draws = options.get("frame", "map"), random.Random(1)
    user, _, password = open(credential).read().strip().partition(":")
    config = zenoh.Config()
    config.insert_json5("mode", '"client"')
    config.insert_json5("connect/endpoints", json.dumps([endpoint]))
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("transport/auth/usrpwd", json.dumps({"user": user, "password": password}))
    Odometry = STORE.types["nav_msgs/msg/Odometry"]
    Header, Time = STORE.types["std_msgs/msg/Header"], STORE.types["builtin_interfaces/msg/Time"]
    g = STORE.types

    with zenoh.open(config) as session:
        node = Ros2(session, domain, namespace, f"vehicle_{vid}")
        # The start: the first pose of the planned path, which a late subscriber asks for.
        path_key = node.key(node.topic(f"vehicle_{vid}/path"), "nav_msgs/msg/Path")
        deadline, path = time.monotonic() + 60, None
        while path is None:
            if time.monotonic() > deadline:
                sys.exit(f"vehicle.py: no path on {path_key} within 60 s")
            for r in session.get(f"{path_key}/@adv/**?_max=1", accept_replies=zenoh.ReplyKeyExpr.ANY):
                if r.ok:
                    path = STORE.deserialize_cdr(r.ok.payload.to_bytes(), "nav_msgs/msg/Path")
            time.sleep(0.05)
        first = path.poses[0].pose
        state = {"x": first.position.x, "y": first.position.y,
                 "yaw": 2.0 * math.atan2(first.orientation.z, first.orientation.w)}
        command, lock, commands = [0.0, 0.0], threading.Lock(), [0]

        def on_command(sample):
            twist = STORE.deserialize_cdr(sample.payload.to_bytes(), "geometry_msgs/msg/Twist")
            with lock:
                command[:] = [twist.linear.x, twist.angular.z]
                commands[0] += 1

        cmd_topic = node.topic(f"vehicle_{vid}/cmd")
        subscriber = session.declare_subscriber(node.key(cmd_topic, "geometry_msgs/msg/Twist"), on_command)
        node.token("MS", cmd_topic, "geometry_msgs/msg/Twist")
        odom_topic = node.topic(f"vehicle_{vid}/odom")
        publisher = session.declare_publisher(node.key(odom_topic, "nav_msgs/msg/Odometry"))
        # Any 16 bytes unique to the publisher make a GID (rmw_zenoh hashes its token with XXH3).
        gid = hashlib.sha256(node.token("MP", odom_topic, "nav_msgs/msg/Odometry").encode()).digest()[:16]
        node.declared()

        world_here, world_gone = threading.Event(), threading.Event()

        def on_graph(sample):
            if str(sample.key_expr).endswith(f"/NN/%/{namespace.replace('/', '%')}/world"):
                (world_gone if sample.kind == zenoh.SampleKind.DELETE else world_here).set()

        graph = session.liveliness().declare_subscriber(f"@ros2_lv/{domain}/**", on_graph, history=True)
        sequence, published, wall = 0, 0, time.time()
        end = time.monotonic() + 120
        while not world_gone.is_set() and time.monotonic() < end:
            now = time.time()
            h, wall = (now - wall) * time_scale, now
            with lock:
                v, r = command
            # Exact for v and r held over the step: ψ is linear in time (docs/MODEL.md §2).
            half = 0.5 * r * h
            sinc = math.sin(half) / half if half else 1.0
            mid = state["yaw"] + half
            state["x"] += h * (v * sinc * math.cos(mid) + current[0])
            state["y"] += h * (v * sinc * math.sin(mid) + current[1])
            state["yaw"] = math.atan2(math.sin(state["yaw"] + r * h), math.cos(state["yaw"] + r * h))
            ns = int(now * 1e9)
            c, s = math.cos(state["yaw"]), math.sin(state["yaw"])
            over_ground = (v + c * current[0] + s * current[1], -s * current[0] + c * current[1])
            message = Odometry(
                header=Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame),
                child_frame_id=f"vehicle_{vid}",
                pose=g["geometry_msgs/msg/PoseWithCovariance"](
                    pose=g["geometry_msgs/msg/Pose"](
                        position=g["geometry_msgs/msg/Point"](x=state["x"], y=state["y"], z=0.0),
                        orientation=g["geometry_msgs/msg/Quaternion"](
                            x=0.0, y=0.0, z=math.sin(state["yaw"] / 2), w=math.cos(state["yaw"] / 2))),
                    covariance=numpy.zeros(36)),
                twist=g["geometry_msgs/msg/TwistWithCovariance"](
                    twist=g["geometry_msgs/msg/Twist"](
                        linear=g["geometry_msgs/msg/Vector3"](x=over_ground[0], y=over_ground[1], z=0.0),
                        angular=g["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=r)),
                    covariance=numpy.zeros(36)))
            sequence += 1
            attachment = (sequence.to_bytes(8, "little", signed=True) + ns.to_bytes(8, "little", signed=True)
                          + bytes([16]) + gid)
            publisher.put(bytes(STORE.serialize_cdr(message, "nav_msgs/msg/Odometry")), attachment=attachment)
            published += 1
            wait = every * period / time_scale * (1 + jitter * draws.uniform(-1, 1))
            time.sleep(max(0.0, wait - (time.time() - now)))
        graph.undeclare()
        subscriber.undeclare()
        json.dump({"start": [first.position.x, first.position.y], "poses": len(path.poses),
                   "commands": commands[0], "published": published, "world_seen": world_here.is_set(),
                   "world_gone": world_gone.is_set(), "pid": os.getpid()}, open(out, "w"))


if __name__ == "__main__":
    main()
