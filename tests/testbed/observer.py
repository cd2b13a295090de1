#!/usr/bin/env python3
"""A shore observer of the fleet's ROS 2 graph, as rviz2 or rosbag2 would be, through a router
that enforces access control: it subscribes to every ROS 2 topic of the domain, counts what it
hears per topic and whether any of it is an intruder's (a payload with `intruder` in it), tries
to publish a command of its own (which the router must drop), and stops when the fleet's world
leaves the graph. Used by tests/testbed.rs.

    observer.py ZENOH_JSON5 CREDENTIAL ENDPOINT DOMAIN OUT.json

CREDENTIAL is its certificate (`tcpf credential`'s observer.pem).
"""

import importlib.util
import json
import os
import sys
import threading
import time

import zenoh

here = os.path.dirname(os.path.abspath(__file__))
spec = importlib.util.spec_from_file_location(
    "vehicle", os.path.join(here, "..", "..", "examples", "python", "vehicle.py"))
vehicle = importlib.util.module_from_spec(spec)
spec.loader.exec_module(vehicle)


def main():
    config_file, credential, endpoint, domain, out = sys.argv[1:6]
    config = zenoh.Config.from_file(config_file)
    config.insert_json5("connect/endpoints", f'["{endpoint}"]')
    key, value = vehicle.credential(credential)
    config.insert_json5(key, json.dumps(value))
    config.insert_json5("scouting/multicast/enabled", "false")
    heard, forged, lock = {}, [0], threading.Lock()
    world_here, world_gone = threading.Event(), threading.Event()

    def on_sample(sample):
        # The topic: the key without its domain, type and hash.
        topic = "/".join(str(sample.key_expr).split("/")[1:-2])
        with lock:
            heard[topic] = heard.get(topic, 0) + 1
            if b"intruder" in sample.payload.to_bytes():
                forged[0] += 1

    def on_graph(sample):
        if str(sample.key_expr).endswith("/NN/%/%tcpf/world"):
            (world_gone if sample.kind == zenoh.SampleKind.DELETE else world_here).set()

    # Its attempts to publish from a session of their own: a session delivers its own puts to its
    # own subscribers without the router.
    with zenoh.open(config) as session, zenoh.open(config) as speaker:
        subscriber = session.declare_subscriber(f"{domain}/tcpf/**", on_sample)
        graph = session.liveliness().declare_subscriber(f"@ros2_lv/{domain}/**", on_graph, history=True)
        print("observer: connected, listening", file=sys.stderr, flush=True)
        deadline = time.monotonic() + 120
        while not world_gone.is_set() and time.monotonic() < deadline:
            speaker.put(f"{domain}/tcpf/vehicle_1/cmd/geometry_msgs::msg::dds_::Twist_/x", b"intruder observer")
            time.sleep(0.05)
        graph.undeclare()
        subscriber.undeclare()
    with lock:
        json.dump({"heard": heard, "forged": forged[0], "world_seen": world_here.is_set(),
                   "world_gone": world_gone.is_set()}, open(out, "w"))


if __name__ == "__main__":
    main()
