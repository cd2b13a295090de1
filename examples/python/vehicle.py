#!/usr/bin/env python3
"""One vehicle of a tcpf mission, played in Python over Zenoh (docs/PROTOCOL.md, "Play a vehicle").

It follows the realtime clock the world serves on tcpf/<m>/clock, publishes its State at every
tick, moves with the freshest Command of its agent, and stops at End or at max_duration. The
postcard encoding is written out by hand, so that this file is also a reading of the protocol.

    python3 vehicle.py MISSION.toml --id N [-e ENDPOINT ...] [-c ZENOH_JSON5]
    python3 vehicle.py --self-test

Needs Python >= 3.11 (tomllib) and `pip install eclipse-zenoh==1.10.2`.
"""

import argparse
import base64
import json
import math
import os
import re
import signal
import struct
import sys
import threading
import time
import tomllib

VERSION = 12
# How far ahead of this vehicle's clock a command's tick may be, in wall seconds (as every role).
AHEAD_LIMIT_WALL_S = 1.0
# The longest a vehicle holds its agent's last command, in simulated seconds (the world's
# HOLD_LIMIT_S, core/src/roles/realtime.rs): then its watchdog stops the thrusters.
HOLD_LIMIT_S = 1.0
F64 = struct.Struct("<d")

# Message layouts: the fields in order, as postcard writes them (PROTOCOL.md, "Encoding"). A type is
# ("u", bits), ("f64",), ("bool",), ("array", T, n), ("vec", T), ("option", T), ("enum", names)
# (variants without fields) or ("record", ((name, T), ...)).
U16, U32, U64, F, BOOL = ("u", 16), ("u", 32), ("u", 64), ("f64",), ("bool",)
XY = ("array", F, 2)


def record(*fields):
    return ("record", fields)


DYNAMICS = record(("surge", F), ("sway", F), ("yaw_rate", F), ("command", XY), ("motor", XY), ("thrust", XY))
STATE = record(("version", U16), ("tick", U64), ("id", U32), ("t", F), ("position", XY), ("heading", F),
               ("sideslip", F), ("sideslip_rate", F), ("current", XY), ("dynamics", ("option", DYNAMICS)))
# What became of a neighbour's γ frame: `cause` is "delivered" or why not (PROTOCOL.md, `Reception`).
CAUSE = ("enum", ("delivered", "busy", "half_duplex", "collision", "noise", "loss", "burst", "outage", "range"))
RECEPTION = record(("from", U32), ("delivered", BOOL), ("sent", F), ("distance", ("option", F)),
                   ("sinr_db", ("option", F)), ("cause", CAUSE))
COMMAND = record(("version", U16), ("tick", U64), ("id", U32), ("v", F), ("r", F), ("accel", F), ("hold", BOOL),
                 ("gamma", F), ("gamma_dot", F), ("v_d", F), ("x_e", F), ("y_e", F), ("psi_e", F),
                 ("receptions", ("vec", RECEPTION)))
LOST = record(("id", U32), ("tick", U64), ("reason", ("enum", ("gone", "silent"))))
ARRIVAL = record(("id", U32), ("tick", U64))
END = record(("version", U16), ("ticks", U64), ("lost", ("vec", LOST)), ("arrived", ("vec", ARRIVAL)))
CLOCK = record(("version", U16), ("realtime", BOOL), ("time_scale", F), ("epoch", F), ("tick", U64), ("mission", U64))
# For the self-test (PROTOCOL.md's worked example) and tests/testbed/intruder.py: this vehicle sends no γ.
GAMMA = record(("version", U16), ("tick", U64), ("from", U32),
               ("sample", ("option", record(("t", F), ("gamma", F), ("gamma_dot", F), ("position", XY)))),
               ("busy", BOOL))


def varint(n):
    out = bytearray()
    while n >= 0x80:
        out.append(n & 0x7F | 0x80)
        n >>= 7
    out.append(n)
    return bytes(out)


def encode(t, value, out=None):
    out = bytearray() if out is None else out
    kind = t[0]
    if kind == "u":
        if not 0 <= value < 1 << t[1]:
            raise ValueError(f"{value} does not fit u{t[1]}")
        out += varint(value)
    elif kind == "f64":
        out += F64.pack(value)
    elif kind == "bool":
        out.append(1 if value else 0)
    elif kind in ("array", "vec"):
        if kind == "vec":
            out += varint(len(value))
        elif len(value) != t[2]:
            raise ValueError(f"expected {t[2]} values, got {len(value)}")
        for x in value:
            encode(t[1], x, out)
    elif kind == "option":
        out.append(0 if value is None else 1)
        if value is not None:
            encode(t[1], value, out)
    elif kind == "enum":
        out += varint(t[1].index(value))
    else:
        for name, ft in t[1]:
            encode(ft, value[name], out)
    return out


class Refused(Exception):
    """A payload a receiver drops and counts; `kind` is its Rejections field."""

    def __init__(self, kind, detail=""):
        super().__init__(f"{kind} {detail}".strip())
        self.kind = kind


class Reader:
    def __init__(self, data):
        self.data, self.pos, self.finite = data, 0, True

    def take(self, n):
        if self.pos + n > len(self.data):
            raise Refused("undecodable", "(too short)")
        self.pos += n
        return self.data[self.pos - n:self.pos]

    def uint(self, bits):
        n = 0
        for i in range((bits + 6) // 7):
            b = self.take(1)[0]
            n |= (b & 0x7F) << (7 * i)
            if b < 0x80:
                # Postcard refuses a varint whose last byte carries bits beyond the type.
                if n >> bits:
                    raise Refused("undecodable", f"(varint overflows u{bits})")
                return n
        raise Refused("undecodable", f"(varint longer than u{bits} allows)")

    def value(self, t):
        kind = t[0]
        if kind == "u":
            return self.uint(t[1])
        if kind == "f64":
            x = F64.unpack(self.take(8))[0]
            self.finite = self.finite and math.isfinite(x)
            return x
        if kind == "bool":
            b = self.take(1)[0]
            if b > 1:
                raise Refused("undecodable", "(bool not 0 or 1)")
            return b == 1
        if kind == "array":
            return [self.value(t[1]) for _ in range(t[2])]
        if kind == "vec":
            return [self.value(t[1]) for _ in range(self.uint(64))]
        if kind == "option":
            tag = self.take(1)[0]
            if tag > 1:
                raise Refused("undecodable", "(option tag not 0 or 1)")
            return self.value(t[1]) if tag else None
        if kind == "enum":
            i = self.uint(32)
            if i >= len(t[1]):
                raise Refused("undecodable", "(no such enum variant)")
            return t[1][i]
        return {name: self.value(ft) for name, ft in t[1]}


def decode(t, data):
    """The message, if `data` is exactly one of ours; else raises Refused, checked in the order
    the Rust decoder checks: shape (trailing bytes included), version, finite numbers."""
    r = Reader(data)
    message = r.value(t)
    if r.pos != len(data):
        raise Refused("undecodable", f"({len(data) - r.pos} trailing bytes)")
    if message["version"] != VERSION:
        raise Refused("wrong_version", f"({message['version']})")
    if not r.finite:
        raise Refused("non_finite")
    return message


def wrap(angle):
    """Into (-pi, pi], as core's follow::wrap."""
    a = math.remainder(angle, math.tau)
    return math.pi if a == -math.pi else a


class Vehicle:
    """The kinematics of core/src/roles/world.rs without side-slip, and what the Zenoh callbacks share
    with the main thread (they run on Zenoh's threads, hence the lock)."""

    def __init__(self, vid, position, heading, current, max_ticks):
        self.id, self.position, self.heading, self.current = vid, position, heading, current
        self.t, self.max_ticks = 0.0, max_ticks
        self.clock = None  # (epoch, time scale, dt) once the world has answered
        self.lock = threading.Lock()
        self.command = None  # the freshest usable Command
        self.older = 0  # commands ignored: not newer than the one held
        self.refused = {}
        self.used = self.published = self.skipped = 0  # the main thread's alone
        self.used_tick = None
        self.done = threading.Event()
        self.outcome = None  # (exit code, why), the first stop wins

    def stop(self, code, why):
        with self.lock:
            self.outcome = self.outcome or (code, why)
        self.done.set()

    def refuse(self, kind):
        with self.lock:
            self.refused[kind] = self.refused.get(kind, 0) + 1

    def on_command(self, sample):
        try:
            c = decode(COMMAND, sample.payload.to_bytes())
        except Refused as e:
            return self.refuse(e.kind)
        if c["id"] != self.id:
            return self.refuse("wrong_sender")
        if c["tick"] > self.horizon():
            # As the roles do: a command from a wrong clock, held, would shut out every later one.
            return self.refuse("future")
        with self.lock:
            if self.command is not None and c["tick"] <= self.command["tick"]:
                # Freshest wins, as in the world: an older command must not undo a newer one.
                self.older += 1
            else:
                self.command = c

    def horizon(self):
        """The latest tick a command may carry now: this clock's, and AHEAD_LIMIT_WALL_S more."""
        if self.clock is None:
            return self.max_ticks
        epoch, scale, dt = self.clock
        ahead = math.ceil(max(0.0, time.time() - epoch + AHEAD_LIMIT_WALL_S) * scale / dt)
        return min(self.max_ticks, ahead)

    def on_end(self, sample):
        try:
            end = decode(END, sample.payload.to_bytes())
        except Refused as e:
            return self.refuse(e.kind)
        self.stop(0, f"End after {end['ticks']} ticks")

    def advance(self, t, dt):
        """Integrates from self.t to t, exactly: v and r are held, so ψ is linear in time and
        ∫cos ψ, ∫sin ψ have a closed form, whatever the interval (skipped periods included).
        A command older than HOLD_LIMIT_S is not held: the vehicle's watchdog stops its
        thrusters, as the world does for the vehicles it simulates."""
        with self.lock:
            c = self.command
        if c is not None:
            # Held for the steps from ticks up to c.tick + hold, as the world holds it: a span of
            # skipped periods that runs past that is cut there.
            expires = (c["tick"] + math.ceil(HOLD_LIMIT_S / dt) + 1) * dt
            if self.t < expires - 0.5 * dt < t - 0.5 * dt:
                self.advance(expires, dt)
            if round(self.t / dt) * dt >= expires - 0.5 * dt:
                c = None
        if c is not None and c["tick"] != self.used_tick:
            self.used, self.used_tick = self.used + 1, c["tick"]
        h, self.t = t - self.t, t
        if c is not None and c["hold"]:
            return
        v, r = (c["v"], c["r"]) if c is not None else (0.0, 0.0)  # no command yet: thrusters off
        half = 0.5 * r * h
        sinc = math.sin(half) / half if half else 1.0
        mid = self.heading + half
        self.position = [self.position[0] + h * (v * sinc * math.cos(mid) + self.current[0]),
                         self.position[1] + h * (v * sinc * math.sin(mid) + self.current[1])]
        self.heading = wrap(self.heading + r * h)


class Interrupted(Exception):
    pass


def on_signal(signum, _frame):
    # Unwinding by exception is what lets `finally` close the session; setting an Event here
    # instead could deadlock on the lock the main thread holds inside Event.wait. A second signal
    # must not interrupt the closing, so both are ignored from now on.
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.SIG_IGN)
    raise Interrupted(signal.Signals(signum).name)


def fail(code, message):
    print(f"vehicle.py: {message}", file=sys.stderr)
    sys.exit(code)


def load_mission(path, vid):
    try:
        with open(path, "rb") as f:
            m = tomllib.load(f)
        name = m["mission"]["name"]
        dt = float(m["mission"].get("control_period", 0.01))
        max_duration = float(m["mission"].get("max_duration", 120.0))
        speed = float(m.get("current", {}).get("speed", 0.0))
        direction = float(m.get("current", {}).get("direction", 0.0))
        amplitude = float(m.get("sideslip", {}).get("amplitude", 0.0))
        vehicle = next((v for v in m.get("vehicle", []) if v["id"] == vid), None)
        if amplitude != 0.0:
            fail(2, f"{path}: [sideslip] amplitude is {amplitude}: this vehicle does not model side-slip")
        if vehicle is None:
            fail(2, f"{path}: the mission has no vehicle {vid}")
        # This vehicle is the kinematic one of MODEL.md §2: a mission that makes it dynamic (D22)
        # expects thrusters and inner loops that this script does not have.
        model = vehicle.get("vehicle_model", m.get("vehicle_model", {}))
        if model.get("kind", "kinematic") != "kinematic":
            fail(2, f"{path}: vehicle {vid} is a {model['kind']} vehicle ([vehicle_model] kind): "
                    "this script plays a kinematic vehicle only")
        if not (dt > 0 and math.isfinite(dt)):
            fail(2, f"{path}: control_period must be a positive number")
        (x, y), (vx, vy) = vehicle["start"], vehicle["start_velocity"]
        x_e, y_e, psi_e = vehicle.get("initial_offset", [0.0, 0.0, 0.0])
    except KeyError as e:
        fail(2, f"{path}: missing key {e}")
    except (OSError, tomllib.TOMLDecodeError, AttributeError, TypeError, ValueError) as e:
        fail(2, f"{path}: cannot read the mission: {e}")
    # As world.rs: the offset is in the path frame at the start, whose heading is v0's.
    h0 = math.atan2(vy, vx)
    position = [x + math.cos(h0) * x_e - math.sin(h0) * y_e, y + math.sin(h0) * x_e + math.cos(h0) * y_e]
    current = [speed * math.cos(direction), speed * math.sin(direction)]
    max_ticks = math.floor(max_duration / dt + 0.5)  # Mission::max_ticks; the world runs 0..=max_ticks
    return name, dt, max_duration, Vehicle(vid, position, wrap(h0 + psi_e), current, max_ticks)


def credential(path):
    """Where and what of a `tcpf credential` file goes into a Zenoh configuration: a role's
    certificate, its key and the fleet's authority (mutual TLS), or a user and password. Refused,
    as tcpf refuses it, when others may read it."""
    try:
        if os.stat(path).st_mode & 0o077:
            fail(2, f"--credential {path}: others may read it; `chmod 600 {path}` and keep it so")
        with open(path) as f:
            text = f.read()
    except OSError as e:
        fail(2, f"--credential {path}: {e.strerror}")
    if "-----BEGIN " in text:
        pems = [(m.group(1), m.group(0)) for m in re.finditer(r"-----BEGIN ([A-Z ]+)-----.*?-----END \1-----\n?", text, re.S)]
        certificates = [pem for label, pem in pems if label == "CERTIFICATE"]
        keys = [pem for label, pem in pems if label.endswith("PRIVATE KEY")]
        if len(certificates) != 2 or len(keys) != 1:
            fail(2, f"--credential {path}: a role's certificate file holds its certificate, its private key "
                    "and the fleet's authority (`tcpf credential DIR MISSION` makes them)")
        inline = lambda pem: base64.b64encode(pem.encode()).decode()
        return "transport/link/tls", {
            "root_ca_certificate_base64": inline(certificates[1]),
            "connect_certificate_base64": inline(certificates[0]),
            "connect_private_key_base64": inline(keys[0]),
            "enable_mtls": True,
        }
    line = next((l.strip() for l in text.splitlines() if l.strip()), "")
    user, _, password = line.partition(":")
    if not user or not password:
        fail(2, f"--credential {path}: not a credential: neither a certificate (PEM) nor a line USER:PASSWORD")
    return "transport/auth/usrpwd", {"user": user, "password": password}


def open_session(zenoh, args):
    if not (args.config or args.credential or args.open):
        fail(2, "this vehicle would run open: give it its certificate, --credential DIR/vehicle-<id>.pem (`tcpf credential`), "
                "-c a Zenoh configuration that holds one, or --open on a network only you use")
    try:
        config = zenoh.Config.from_file(args.config) if args.config else zenoh.Config()
        if not args.config:
            # A client of the process that listens, as a tcpf role given --credential is: peers
            # with a user and password refuse each other's second link (eclipse-zenoh/zenoh#2577).
            config.insert_json5("mode", '"client"' if args.credential else '"peer"')
            # Zenoh's default listens on every interface; like tcpf, stay on loopback.
            config.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
        # Never find (or be found by) another run on the network by accident.
        config.insert_json5("scouting/multicast/enabled", "false")
        if args.connect:
            config.insert_json5("connect/endpoints", json.dumps(args.connect))
        if args.credential:
            key, value = credential(args.credential)
            config.insert_json5(key, json.dumps(value))
            if not args.config:
                # Wait for the router, as a tcpf client does, up to the startup timeout.
                config.insert_json5("connect/timeout_ms", str(int(args.startup_timeout * 1000)))
                config.insert_json5("connect/retry", '{ "period_init_ms": 50, "period_max_ms": 1000 }')
    except zenoh.ZError as e:
        fail(2, f"bad Zenoh configuration: {e}")
    try:
        return zenoh.open(config)
    except zenoh.ZError as e:
        fail(1, f"cannot open the Zenoh session: {e}")


def get_clock(session, key, timeout, ship):
    """The world's Clock, or None if the run ended first. The world answers only once the run
    has started, so ask until it does."""
    give_up = time.monotonic() + timeout
    while not ship.done.is_set():
        for reply in session.get(key, timeout=max(0.1, min(1.0, give_up - time.monotonic()))):
            if reply.ok is not None:
                try:
                    clock = decode(CLOCK, reply.ok.payload.to_bytes())
                except Refused as e:
                    fail(1, f"the world's clock on {key} is unusable: {e}; this script speaks {VERSION}")
                if not clock["realtime"]:
                    fail(2, "the world runs the lockstep clock; this script plays vehicles only in "
                            "realtime (tcpf world --clock realtime --vehicles <the ids it simulates>)")
                if not clock["time_scale"] > 0:
                    fail(1, f"the world's clock has time_scale {clock['time_scale']}")
                return clock
        if time.monotonic() >= give_up:
            fail(1, f"no clock on {key} after {timeout:g} s: is the world running this mission, and started?")
        ship.done.wait(0.1)
    return None


def drive(ship, publisher, clock, dt, log):
    """Publishes State k at the wall time of tick k, k up to max_ticks or until stopped."""
    scale, epoch = clock["time_scale"], clock["epoch"]
    ship.clock = (epoch, scale, dt)

    def deadline(k):
        return epoch + k * dt / scale

    def tick_at(wall):
        return math.floor((wall - epoch) * scale / dt)

    # Joining late, the vehicle has drifted with the current since t = 0, like any vehicle the
    # world holds no command for.
    k = max(0, tick_at(time.time()) + 1)
    log(f"clock realtime x{scale:g}, epoch {epoch:.3f}, first tick {k} (t = {k * dt:.3f} s); at t = 0 "
        f"({ship.position[0]:.3f}, {ship.position[1]:.3f}) heading {ship.heading:.4f} rad")
    while k <= ship.max_ticks:
        while not ship.done.is_set() and time.time() < deadline(k):
            ship.done.wait(deadline(k) - time.time())
        if ship.done.is_set():
            break
        # Late (a stall, a suspended process): go to the tick under way, never catch up in a burst.
        now = tick_at(time.time())
        if now > k:
            ship.skipped, k = ship.skipped + now - k, now
            if k > ship.max_ticks:
                break
        ship.advance(k * dt, dt)
        publisher.put(encode(STATE, {
            "version": VERSION, "tick": k, "id": ship.id, "t": k * dt, "position": ship.position,
            "heading": ship.heading, "sideslip": 0.0, "sideslip_rate": 0.0, "current": ship.current,
            "dynamics": None}))
        ship.published += 1
        k += 1


def run(args):
    import zenoh

    name, dt, max_duration, ship = load_mission(args.mission, args.id)
    root = f"tcpf/{name}"

    def log(line):
        print(f"vehicle {args.id}: {line}", file=sys.stderr)

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, on_signal)
    session = None
    try:
        session = open_session(zenoh, args)
        session.declare_subscriber(f"{root}/cmd/{args.id}", ship.on_command)
        session.declare_subscriber(f"{root}/end", ship.on_end)
        # As the world publishes a realtime state: the freshest wins, one that cannot leave in
        # time is dropped rather than queued (PROTOCOL.md).
        publisher = session.declare_publisher(f"{root}/state/{args.id}",
                                              congestion_control=zenoh.CongestionControl.DROP,
                                              express=True)
        clock = get_clock(session, f"{root}/clock", args.startup_timeout, ship)
        if clock is not None:
            drive(ship, publisher, clock, dt, log)
            ship.stop(0, f"max_duration {max_duration:g} s")
    except Interrupted as e:
        ship.stop(130, e.args[0])
    finally:
        if session is not None:
            session.close()
    with ship.lock:
        code, why = ship.outcome
        refused = ", ".join(f"{n} {kind}" for kind, n in sorted(ship.refused.items())) or "none"
    log(f"stopped ({why}): {ship.published} ticks published, {ship.used} commands used "
        f"({ship.older} older or repeated ones ignored), refused: {refused}, {ship.skipped} periods skipped")
    return code


def self_test():
    """PROTOCOL.md's Gamma, Clock and Reception examples, round trips, varints and refusals."""
    def refused_as(t, data):
        try:
            decode(t, data)
        except Refused as e:
            return e.kind

    gamma = {"version": VERSION, "tick": 300, "from": 2,
             "sample": {"t": 3.0, "gamma": 1.5, "gamma_dot": 1.0, "position": [2.0, -0.5]}, "busy": False}
    state = {"version": VERSION, "tick": 42, "id": 2, "t": 0.42, "position": [1.0, -2.5], "heading": 0.1,
             "sideslip": 0.0, "sideslip_rate": 0.0, "current": [-0.1, 0.0], "dynamics": None}
    command = {"version": VERSION, "tick": 7, "id": 2, "v": 0.5, "r": -0.1, "accel": 0.0, "hold": False, "gamma": 1.0,
               "gamma_dot": 1.1, "v_d": 0.5, "x_e": 0.01, "y_e": -0.2, "psi_e": 0.03,
               "receptions": [
                   {"from": 1, "delivered": True, "sent": 0.07, "distance": 212.5, "sinr_db": 18.25,
                    "cause": "delivered"},
                   {"from": 3, "delivered": False, "sent": 0.05, "distance": 830.0, "sinr_db": None,
                    "cause": "loss"}]}
    # PROTOCOL.md's receptions, as a Command ends.
    receptions = [{"from": 1, "delivered": False, "sent": 3.0, "distance": 1500.0, "sinr_db": -2.5,
                   "cause": "collision"},
                  {"from": 3, "delivered": False, "sent": 3.0, "distance": None, "sinr_db": None, "cause": "busy"}]
    end = {"version": VERSION, "ticks": 12001, "lost": [{"id": 3, "tick": 500, "reason": "silent"}],
           "arrived": [{"id": 1, "tick": 12000}]}
    clock = {"version": VERSION, "realtime": True, "time_scale": 2.0, "epoch": 1.7e9, "tick": 12,
             "mission": 0x72b3548f8bc2f98c}
    gamma_bytes = ("0cac020201" "0000000000000840" "000000000000f83f" "000000000000f03f"
                   "0000000000000040" "000000000000e0bf" "00")
    receptions_bytes = ("02"
                        "0100" "0000000000000840" "01" "0000000000709740" "01" "00000000000004c0" "03"
                        "0300" "0000000000000840" "00" "00" "01")
    version_id = record(("version", U16), ("id", U32))
    checks = {
        "Gamma example": encode(GAMMA, gamma) == bytes.fromhex(gamma_bytes),
        "Gamma without a sample": encode(GAMMA, dict(gamma, sample=None)) == bytes.fromhex("0cac02020000"),
        "Gamma busy": encode(GAMMA, dict(gamma, sample=None, busy=True)) == bytes.fromhex("0cac02020001"),
        "Clock example": encode(CLOCK, dict(clock, time_scale=10.0, epoch=1.5, tick=300, mission=5))
        == bytes.fromhex("0c01" "0000000000002440" "000000000000f83f" "ac02" "05"),
        "Reception example": encode(("vec", RECEPTION), receptions) == bytes.fromhex(receptions_bytes),
        "the Command ends with its receptions": encode(COMMAND, dict(command, receptions=receptions))
        .endswith(bytes.fromhex(receptions_bytes)),
        "no such cause refused": refused_as(COMMAND, encode(COMMAND, command)[:-1] + b"\x09") == "undecodable",
        "NaN in a reception refused":
        refused_as(COMMAND, encode(COMMAND, dict(command, receptions=[dict(receptions[0], sinr_db=math.nan)])))
        == "non_finite",
        "u32 overflow refused": refused_as(version_id, varint(VERSION) + varint(2**32)) == "undecodable",
        "trailing byte refused": refused_as(COMMAND, encode(COMMAND, command) + b"\0") == "undecodable",
        "version 3 refused": refused_as(STATE, encode(STATE, dict(state, version=3))) == "wrong_version",
        "NaN refused": refused_as(STATE, encode(STATE, dict(state, t=math.nan))) == "non_finite",
    }
    ship = Vehicle(2, [0.0, 0.0], 0.0, [0.0, 0.0], 12000)
    checks["no clock yet: commands up to max_ticks"] = ship.horizon() == 12000
    ship.clock = (time.time(), 10.0, 0.01)
    checks["at t = 0, x10: commands up to a wall second ahead"] = 1000 <= ship.horizon() <= 1002
    ship.command = dict(command, tick=0, v=1.0, r=0.0)
    ship.advance(1.0, 0.01)
    ship.advance(1.01, 0.01)
    held = ship.position[0]
    # The world holds command k for the steps from ticks k … k + 100 (a second at 0.01 s).
    checks["a command held for a simulated second"] = abs(held - 1.01) < 1e-12
    ship.advance(1.02, 0.01)
    checks["then the watchdog stops the thrusters"] = ship.position[0] == held
    ship = Vehicle(2, [0.0, 0.0], 0.0, [0.0, 0.0], 12000)
    ship.command = dict(command, tick=0, v=1.0, r=0.0)
    ship.advance(1.5, 0.01)
    checks["skipped periods stop where the world's hold does"] = abs(ship.position[0] - 1.01) < 1e-12
    for n, hex_ in [(0, "00"), (127, "7f"), (128, "8001"), (300, "ac02"), (2**32, "8080808010")]:
        checks[f"varint {n}"] = encode(U64, n) == bytes.fromhex(hex_) and Reader(varint(n)).uint(64) == n
    for t, m in [(STATE, state), (COMMAND, command), (END, end), (CLOCK, clock), (GAMMA, gamma),
                 (GAMMA, dict(gamma, sample=None, busy=True)), (COMMAND, dict(command, receptions=receptions))]:
        checks[f"round trip {m}"] = decode(t, encode(t, m)) == m
    failed = [what for what, ok in checks.items() if not ok]
    print(f"self-test: {len(checks) - len(failed)} passed, {len(failed)} failed {failed or ''}".rstrip())
    return 1 if failed else 0


def main():
    p = argparse.ArgumentParser(description="Play one vehicle of a tcpf mission in the realtime clock.")
    p.add_argument("mission", nargs="?", help="the mission file (TOML)")
    p.add_argument("--id", type=int, help="the vehicle to play")
    p.add_argument("-e", "--connect", action="append", default=[], metavar="ENDPOINT",
                   help="Zenoh endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable)")
    p.add_argument("-c", "--config", metavar="ZENOH_JSON5", help="Zenoh configuration file")
    p.add_argument("--credential", metavar="FILE",
                   help="its key (vehicle-<id>.key of `tcpf credential DIR MISSION --played <id>`), or the fleet's shared credential: present it to the fleet's router")
    p.add_argument("--open", action="store_true",
                   help="run with no credential, on a network only you use")
    p.add_argument("--startup-timeout", type=float, default=60.0, metavar="S",
                   help="seconds to wait for the world's clock (default 60)")
    p.add_argument("--self-test", action="store_true", help="check the encoder and decoder, then exit")
    args = p.parse_args()
    if args.self_test:
        return self_test()
    if args.mission is None or args.id is None:
        p.error("MISSION and --id are required")
    return run(args)


if __name__ == "__main__":
    sys.exit(main())
