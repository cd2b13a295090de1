#!/usr/bin/env python3
"""Watches a running tcpf fleet as a ROS 2 tool would, with nothing of tcpf's: eclipse-zenoh for
the bus and rosbags (an independent implementation of ROS 2's type hashes and CDR) for the
messages. Joins as a recorder so that the run waits for it, reads every ROS 2 sample of the
domain until the run ends, checks what rmw_zenoh would, and writes what it decoded as JSON for
tests/ros2.rs to compare with the run's telemetry and its rosbag2 (tests/ros2/decoded.py).

    watch.py ZENOH_JSON5 MISSION_NAME DOMAIN OUT.json
"""

import json
import sys
import threading
import time

import zenoh
from rosbags.typesys import Stores, get_typestore

from decoded import Decoded

TYPES = {"nav_msgs::msg::dds_::Odometry_": "nav_msgs/msg/Odometry",
         "nav_msgs::msg::dds_::Path_": "nav_msgs/msg/Path",
         "rosgraph_msgs::msg::dds_::Clock_": "rosgraph_msgs/msg/Clock",
         "geometry_msgs::msg::dds_::Twist_": "geometry_msgs/msg/Twist",
         "geometry_msgs::msg::dds_::Vector3Stamped_": "geometry_msgs/msg/Vector3Stamped",
         "std_msgs::msg::dds_::String_": "std_msgs/msg/String"}


def main():
    config_file, mission, domain, out = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4]
    store = get_typestore(Stores.ROS2_JAZZY)
    hashes = {name: store.hash_rihs01(name) for name in TYPES.values()}
    samples, ended, started, last = [], threading.Event(), threading.Event(), [time.monotonic()]

    def take(sample):
        attachment = sample.attachment.to_bytes() if sample.attachment is not None else None
        key = str(sample.key_expr)
        # A path is published once, maybe before this subscription: it is asked for below.
        if "::Path_/" not in key:
            samples.append((key, sample.payload.to_bytes(), attachment))
        if "::Clock_/" in key:
            started.set()
        last[0] = time.monotonic()

    def drain_until(done, within):
        """Takes what has come until `done()` or `within` seconds have passed; whether done."""
        deadline = time.monotonic() + within
        while not done():
            if time.monotonic() > deadline:
                return False
            sample = subscriber.try_recv()
            if sample is None:
                time.sleep(0.01)
            else:
                take(sample)
        return True

    with zenoh.open(zenoh.Config.from_file(config_file)) as session:
        # Into a channel that zenoh fills without Python: a Python callback per sample, starved
        # beside a CPU hog, kept the session from reading for 5 s, and the world, whose lockstep
        # samples may not be dropped, closed the connection (the end never came here).
        subscriber = session.declare_subscriber(f"{domain}/**", zenoh.handlers.FifoChannel(1 << 20))
        end = session.declare_subscriber(f"tcpf/{mission}/end", lambda _: ended.set())
        # The world declares its node's token after its publishers': once the node is in the
        # graph, so is every topic of it.
        deadline = time.monotonic() + 60
        while True:
            tokens = [str(r.ok.key_expr) for r in session.liveliness().get(f"@ros2_lv/{domain}/**") if r.ok]
            if any("/NN/" in t for t in tokens) or time.monotonic() > deadline:
                break
            time.sleep(0.1)
        # A recorder's token: the world starts once it is here, so nothing is missed.
        recorder = session.liveliness().declare_token(f"tcpf/{mission}/alive/record/77")
        if not drain_until(started.is_set, 60):
            sys.exit("watch.py: the run did not start within 60 s")
        # Under way: every node of the fleet is in the graph, and a subscriber that comes now
        # gets each planned path as rmw_zenoh's transient-local subscriber asks for it.
        tokens = [str(r.ok.key_expr) for r in session.liveliness().get(f"@ros2_lv/{domain}/**") if r.ok]
        adv = sorted(str(r.ok.key_expr) for r in session.liveliness().get(f"{domain}/**/@adv/pub/**") if r.ok)
        latched = {}
        for key in sorted({t.split("/@adv/")[0] for t in adv}):
            for r in session.get(f"{key}/@adv/**?_max=1", accept_replies=zenoh.ReplyKeyExpr.ANY):
                if r.ok:
                    latched.setdefault(str(r.ok.key_expr), []).append(
                        (r.ok.payload.to_bytes(), r.ok.attachment.to_bytes() if r.ok.attachment else None))
        if not drain_until(ended.is_set, 120):
            sys.exit("watch.py: the run did not end within 120 s")
        # The world publishes a tick's ROS 2 samples before it announces the end; wait for the
        # last of them to arrive.
        drain_until(lambda: time.monotonic() - last[0] >= 1.0, 60)
        recorder.undeclare()
        subscriber.undeclare()
        end.undeclare()

    problems, sequences, decoded = [], {}, Decoded()
    for key, replies in latched.items():
        if len(replies) != 1:
            problems.append(f"{key}: {len(replies)} replies to a late subscriber, not its one path")
        payload, attachment = replies[0]
        if attachment is None or len(attachment) != 33:
            problems.append(f"{key}: the cached path has no rmw_zenoh attachment")
        name = TYPES[key.split("/")[-2]]
        decoded.add(key.split("/")[2:-2], name, store.deserialize_cdr(payload, name))
    for key, payload, attachment in samples:
        parts = key.split("/")
        dds, hash_ = parts[-2], parts[-1]
        name = TYPES.get(dds)
        if name is None:
            problems.append(f"{key}: a type rosbags was not asked about")
            continue
        if hash_ != hashes[name]:
            problems.append(f"{key}: hash {hash_}, rosbags says {hashes[name]}")
        if attachment is None or len(attachment) != 33 or attachment[16] != 16:
            problems.append(f"{key}: attachment {attachment!r} is not rmw_zenoh's 33 bytes")
            continue
        sequence = int.from_bytes(attachment[0:8], "little", signed=True)
        sequences.setdefault(key, []).append(sequence)
        decoded.add(parts[2:-2], name, store.deserialize_cdr(payload, name))
    for key, seq in sequences.items():
        if seq != list(range(1, len(seq) + 1)):
            problems.append(f"{key}: sequence numbers {seq[:5]}... are not 1, 2, 3 without a gap")
    json.dump({"problems": problems, "hashes": hashes, "tokens": tokens, "adv": adv, "keys": sorted(sequences),
               **decoded.json()}, open(out, "w"))


if __name__ == "__main__":
    main()
