#!/usr/bin/env python3
"""Reads a run's rosbag2 as a ROS 2 tool would, with nothing of tcpf's: rosbags opens it as a
bag, and each topic's type, hash (rosbags' own), message definition, serialization and QoS
must be what ROS 2 says they are; then every message is decoded (tests/ros2/decoded.py) and
written as JSON for tests/ros2.rs to compare with what the fleet published and its telemetry.

    bag.py BAG_DIR OUT.json
"""

import json
import sys
from pathlib import Path

from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from decoded import Decoded


def main():
    bag, out = Path(sys.argv[1]), sys.argv[2]
    store = get_typestore(Stores.ROS2_JAZZY)
    problems, decoded, topics = [], Decoded(), {}
    with Reader(bag) as reader:
        for c in reader.connections:
            topics[c.topic] = {"type": c.msgtype, "count": c.msgcount,
                               "durability": c.ext.offered_qos_profiles[0].durability.name.lower()}
            if c.digest != store.hash_rihs01(c.msgtype):
                problems.append(f"{c.topic}: hash {c.digest}, rosbags says {store.hash_rihs01(c.msgtype)}")
            if c.msgdef.data != store.generate_msgdef(c.msgtype, ros_version=2)[0]:
                problems.append(f"{c.topic}: its message definition is not {c.msgtype}'s")
            if c.ext.serialization_format != "cdr":
                problems.append(f"{c.topic}: serialized as {c.ext.serialization_format}")
        counted = {}
        for c, _, raw in reader.messages():
            counted[c.topic] = counted.get(c.topic, 0) + 1
            decoded.add(c.topic.split("/")[2:], c.msgtype, store.deserialize_cdr(raw, c.msgtype))
        for topic, meta in topics.items():
            if counted.get(topic, 0) != meta["count"]:
                problems.append(f"{topic}: metadata.yaml counts {meta['count']}, the file holds {counted.get(topic, 0)}")
        json.dump({"problems": problems, "topics": topics, "duration_ns": reader.duration,
                   "messages": reader.message_count, **decoded.json()}, open(out, "w"))


if __name__ == "__main__":
    main()
