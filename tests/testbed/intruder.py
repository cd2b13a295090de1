#!/usr/bin/env python3
"""A process with a genuine certificate that publishes where its identity may not: on other
vehicles' keys. Random bytes and well-formed commands and γ (encoded with the example vehicle's
codec), or ROS 2 samples, for a bounded time and count. Used by tests/testbed.rs to check access control.

    intruder.py ZENOH_JSON5 CREDENTIAL ENDPOINT SECONDS KEY...

CREDENTIAL is its genuine certificate (`tcpf credential`'s agent-1.pem, say).
"""

import importlib.util
import json
import os
import random
import sys
import time

import zenoh

here = os.path.dirname(os.path.abspath(__file__))
spec = importlib.util.spec_from_file_location(
    "vehicle", os.path.join(here, "..", "..", "examples", "python", "vehicle.py"))
vehicle = importlib.util.module_from_spec(spec)
spec.loader.exec_module(vehicle)

MAX_MESSAGES = 200_000


def forged(key, rng):
    """A message a genuine sender on `key` could have sent, with made-up values; on a ROS 2 key
    (`<domain>/tcpf/vehicle_<id>/<topic>/<type>/<hash>`), CDR's header and a mark an observer
    can tell."""
    if "::" in key:
        return b"\x00\x01\x00\x00intruder" + bytes(rng.randrange(256) for _ in range(rng.randrange(0, 64)))
    kind, ident = key.split("/")[-2:]
    tick = rng.randrange(0, 6000)
    if kind == "cmd":
        return vehicle.encode(vehicle.COMMAND, {
            "version": vehicle.VERSION, "tick": tick, "id": int(ident), "v": 1.0, "r": 0.5,
            "accel": 0.0, "hold": False, "gamma": 50.0, "gamma_dot": 1.0, "v_d": 1.0, "x_e": 0.0, "y_e": 0.0,
            "psi_e": 0.0, "receptions": []})
    return vehicle.encode(vehicle.GAMMA, {
        "version": vehicle.VERSION, "tick": tick, "from": int(ident),
        "sample": {"t": tick * 0.01, "gamma": 50.0, "gamma_dot": 1.0, "position": [0.0, 0.0]}, "busy": False})


def main():
    config_file, credential, endpoint = sys.argv[1:4]
    seconds, keys = float(sys.argv[4]), sys.argv[5:]
    config = zenoh.Config.from_file(config_file)
    config.insert_json5("connect/endpoints", f'["{endpoint}"]')
    key, value = vehicle.credential(credential)
    config.insert_json5(key, json.dumps(value))
    config.insert_json5("scouting/multicast/enabled", "false")
    rng = random.Random(1)
    sent = 0
    with zenoh.open(config) as session:
        publishers = [session.declare_publisher(k) for k in keys]
        # What the test waits for before it starts the vehicle the fleet waits for: every forged
        # message from here on meets a running fleet.
        print(f"intruder: connected, publishing on {keys}", file=sys.stderr, flush=True)
        end = time.monotonic() + seconds
        while time.monotonic() < end and sent < MAX_MESSAGES:
            for key, publisher in zip(keys, publishers):
                junk = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 64)))
                publisher.put(forged(key, rng) if "::" in key else junk)
                publisher.put(forged(key, rng))
                session.put(key, forged(key, rng))
                sent += 3
            time.sleep(0.001)
    print(f"intruder: {sent} messages sent on {keys}", file=sys.stderr)


if __name__ == "__main__":
    main()
