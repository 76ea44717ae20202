#!/usr/bin/env python3
"""A real ground station (pymavlink) against `firmware-sim sitl`, or with
--hil against the firmware under QEMU (`firmware-sim hil --mavlink`).

Starts the SITL (or the HIL run) on the embedded `route` scenario's robot
at --speedup N, with the floor's origin (--origin), talks to it over UDP on loopback and checks
(docs/mavlink.md, "The SITL" and "The firmware under QEMU"):

* a route mission (MISSION_ITEM_INT, MAV_FRAME_LOCAL_NED) uploaded, read
  back and compared; armed, started; paused mid-leg (the robot stops and
  holds there) and continued; bad missions sent while it drives (more items
  than capacity, a NaN coordinate, an unknown command, an unsupported
  frame), each answered with its MAV_MISSION_RESULT, the running mission
  kept (read back) and finished; every MISSION_ITEM_REACHED in order; the
  final LOCAL_POSITION_NED within 2 cm of the last waypoint;
* a parameter set and read back; an invalid one refused (the old value
  answered, a STATUSTEXT saying so); the same for a gain of the tracking
  law (TRK_K1), restored after;
* the tracker's and RFID reader's counters arrive as NAMED_VALUE_INT, every
  one of them, the fixes and reader frames counted;
* a mission in MAV_FRAME_GLOBAL_INT through the floor's origin (--origin),
  uploaded, read back, run to its end, within 2 cm;
* heartbeats stopped mid-leg: the robot reports the link lost and stops
  within the link timeout.

The SITL is started with --power-on wait: it checks that the robot waits
disarmed and idle with the scenario's route as its mission. Against the
firmware under QEMU (--hil) the robot starts as the robot file says by
default, armed and driving the scenario's own route, so it is paused
first; two more checks are made: the scenario's route runs from
power-on, and Ctrl-C ends the run cleanly with the host's copy of the
firmware's session agreeing on every MAVLink answer and no byte dropped
(the run's summary.json). The origin reaches the firmware with the route
(the HIL link's route announcement), so the global-frame mission runs
there too.

Every wait is in simulated time (the robot's time_boot_ms), so the script
does not depend on how fast the machine is; a wall-clock cap only catches a
robot that hangs. Prints one line per check and "N passed, N failed, N
skipped"; exits non-zero on any failure.
"""

import argparse
import json
import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402

mavutil.set_dialect("common")
M = mavutil.mavlink

GCS_SYS, GCS_COMP = 255, 190
ROBOT_SYS, ROBOT_COMP = 1, 1
CAPACITY = 64
# The floor's origin for the global-frame mission (any point works).
ORIGIN = (47.397742, 8.545594)
# The last waypoint within this of LOCAL_POSITION_NED at the end (m).
FINAL_TOLERANCE_M = 0.02
# A wall-clock cap on any one wait: only a hung SITL reaches it.
WALL_CAP_S = 60.0

# The route scenario's loop (firmware-sim show route), floor frame (x east,
# y north): (x, y, hold s, heading deg counter-clockwise from +x or None).
ROUTE = [
    (0.0, 0.0, 0.0, None),
    (1.0, 0.0, 2.0, None),
    (2.0, 0.0, 0.0, None),
    (2.0, 1.0, 2.0, 180.0),
    (0.0, 1.0, 0.0, None),
    (0.0, 0.0, 1.0, None),
]
# The global mission: a shorter leg and a corner from where the loop ends.
GLOBAL_ROUTE = [
    (0.0, 0.0, 0.0, None),
    (0.6, 0.0, 0.0, None),
    (0.6, 0.5, 0.0, None),
]

# The robot's counters, sent as NAMED_VALUE_INT (docs/mavlink.md, Messages).
COUNTER_NAMES = [
    "TRK_FIXES", "TRK_INVAL", "TRK_STALE", "TRK_GATED", "TRK_RELOC", "TRK_HDGRST",
    "TRK_FSAFE", "TRK_DEADRK", "RF_FRAMES", "RF_CRC", "RF_MALFORM", "RF_UNKNOWN",
    "RF_BACKLOG", "RF_RDERR", "RF_SUPERSD",
]
# The route scenario's k1 (its [controller]).
ROUTE_K1 = 2.0

# The checks skipped against the firmware under QEMU for want of a
# feature, each with its reason: none (the origin reaches it with the
# route).
HIL_SKIPS = {}


class Failed(Exception):
    pass


class Gcs:
    """The ground station: one pymavlink connection, a heartbeat thread,
    the robot's simulated time from its telemetry."""

    def __init__(self, port):
        self.conn = mavutil.mavlink_connection(
            f"udpin:127.0.0.1:{port}",
            source_system=GCS_SYS,
            source_component=GCS_COMP,
            dialect="common",
        )
        self.lock = threading.Lock()
        self.sim_ms = 0
        self.heartbeats = threading.Event()
        self.stop_thread = threading.Event()
        self.thread = None
        self.statustexts = []
        self.reached = []
        # The last value of each NAMED_VALUE_INT counter.
        self.counters = {}
        self.mode = None
        self.system_status = None
        self.position = None

    def send(self, msg):
        with self.lock:
            self.conn.mav.send(msg)

    def heartbeat_loop(self, period_wall_s):
        while not self.stop_thread.is_set():
            if self.heartbeats.is_set():
                self.send(
                    M.MAVLink_heartbeat_message(
                        M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, M.MAV_STATE_ACTIVE, 3
                    )
                )
            time.sleep(period_wall_s)

    def start_heartbeats(self, period_wall_s):
        self.heartbeats.set()
        if self.thread is None:
            self.thread = threading.Thread(
                target=self.heartbeat_loop, args=(period_wall_s,), daemon=True
            )
            self.thread.start()

    def recv(self, wall_timeout=0.5):
        msg = self.conn.recv_match(blocking=True, timeout=wall_timeout)
        if msg is None:
            return None
        if msg.get_srcSystem() != ROBOT_SYS:
            return msg
        kind = msg.get_type()
        if kind in ("LOCAL_POSITION_NED", "ATTITUDE", "GLOBAL_POSITION_INT"):
            self.sim_ms = max(self.sim_ms, msg.time_boot_ms)
        if kind == "LOCAL_POSITION_NED":
            self.position = msg
        elif kind == "STATUSTEXT":
            self.statustexts.append((self.sim_ms, msg.text))
        elif kind == "MISSION_ITEM_REACHED":
            self.reached.append(msg.seq)
        elif kind == "NAMED_VALUE_INT":
            self.counters[msg.name] = msg.value
        elif kind == "HEARTBEAT":
            self.mode = msg.custom_mode
            self.system_status = msg.system_status
        return msg

    def wait(self, what, predicate, sim_timeout_s):
        """The first message for which predicate(msg) holds, within
        sim_timeout_s of simulated time (the robot's clock)."""
        start_sim = self.sim_ms
        wall_end = time.monotonic() + WALL_CAP_S
        while True:
            msg = self.recv()
            if msg is not None and predicate(msg):
                return msg
            if self.sim_ms - start_sim > sim_timeout_s * 1000:
                raise Failed(f"{what}: not within {sim_timeout_s} s simulated")
            if time.monotonic() > wall_end:
                raise Failed(f"{what}: nothing within {WALL_CAP_S} s of wall time (SITL hung?)")

    def wait_type(self, kind, sim_timeout_s, predicate=lambda m: True):
        return self.wait(kind, lambda m: m.get_type() == kind and predicate(m), sim_timeout_s)

    def drain(self):
        while self.recv(wall_timeout=0.0) is not None:
            pass

    # -- commands and parameters --------------------------------------

    def command(self, command, p1=0.0, p2=0.0):
        self.send(
            M.MAVLink_command_long_message(
                ROBOT_SYS, ROBOT_COMP, command, 0, p1, p2, 0, 0, 0, 0, 0
            )
        )
        ack = self.wait_type("COMMAND_ACK", 5, lambda m: m.command == command)
        return ack.result

    def param_set(self, name, value):
        self.send(
            M.MAVLink_param_set_message(
                ROBOT_SYS, ROBOT_COMP, name.encode(), value, M.MAV_PARAM_TYPE_REAL32
            )
        )
        return self.wait_type("PARAM_VALUE", 5, lambda m: m.param_id == name).param_value

    def param_read(self, name):
        self.send(
            M.MAVLink_param_request_read_message(ROBOT_SYS, ROBOT_COMP, name.encode(), -1)
        )
        return self.wait_type("PARAM_VALUE", 5, lambda m: m.param_id == name).param_value

    # -- missions ------------------------------------------------------

    def upload(self, items):
        """The mission protocol's upload: the final MISSION_ACK's type."""
        self.send(
            M.MAVLink_mission_count_message(
                ROBOT_SYS, ROBOT_COMP, len(items), M.MAV_MISSION_TYPE_MISSION
            )
        )
        while True:
            msg = self.wait(
                "upload",
                lambda m: m.get_type()
                in ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"),
                10,
            )
            if msg.get_type() == "MISSION_ACK":
                return msg.type
            self.send(items[msg.seq])

    def download(self):
        """The mission read back: (frame, command, x, y, param1, param4) each."""
        self.send(
            M.MAVLink_mission_request_list_message(
                ROBOT_SYS, ROBOT_COMP, M.MAV_MISSION_TYPE_MISSION
            )
        )
        count = self.wait_type("MISSION_COUNT", 5).count
        items = []
        for seq in range(count):
            self.send(
                M.MAVLink_mission_request_int_message(
                    ROBOT_SYS, ROBOT_COMP, seq, M.MAV_MISSION_TYPE_MISSION
                )
            )
            item = self.wait_type("MISSION_ITEM_INT", 5, lambda m, s=seq: m.seq == s)
            items.append(
                (item.frame, item.command, item.x, item.y, item.param1, _nan_none(item.param4))
            )
        self.send(
            M.MAVLink_mission_ack_message(
                ROBOT_SYS, ROBOT_COMP, M.MAV_MISSION_ACCEPTED, M.MAV_MISSION_TYPE_MISSION
            )
        )
        return items


def _nan_none(v):
    return None if math.isnan(v) else round(v, 3)


def yaw_deg(heading_deg):
    """A floor heading (counter-clockwise from +x = east) as MAVLink's yaw
    (clockwise from north), in [0, 360)."""
    return None if heading_deg is None else (90.0 - heading_deg) % 360.0


def local_items(route):
    """MISSION_ITEM_INT, MAV_FRAME_LOCAL_NED: x north = floor y, y east =
    floor x, in 1e-4 m."""
    return [
        M.MAVLink_mission_item_int_message(
            ROBOT_SYS, ROBOT_COMP, seq, M.MAV_FRAME_LOCAL_NED, M.MAV_CMD_NAV_WAYPOINT,
            0, 1, hold, 0, 0,
            float("nan") if yaw_deg(h) is None else yaw_deg(h),
            round(y * 1e4), round(x * 1e4), 0.0, M.MAV_MISSION_TYPE_MISSION,
        )
        for seq, (x, y, hold, h) in enumerate(route)
    ]


def to_global(x_east, y_north, origin=ORIGIN):
    """Floor metres to latitude, longitude (1e-7 deg) through the origin: the
    local tangent plane of docs/mavlink.md (WGS-84 meridional and
    prime-vertical radii at the origin), in float64."""
    a, e2 = 6378137.0, 6.69437999014e-3
    lat0 = math.radians(origin[0])
    w = 1.0 - e2 * math.sin(lat0) ** 2
    m_radius = a * (1.0 - e2) / w ** 1.5
    n_radius = a / math.sqrt(w)
    lat = origin[0] + math.degrees(y_north / m_radius)
    mid = math.radians((origin[0] + lat) / 2.0)
    lon = origin[1] + math.degrees(x_east / (n_radius * math.cos(mid)))
    return round(lat * 1e7), round(lon * 1e7)


def global_items(route):
    items = []
    for seq, (x, y, hold, h) in enumerate(route):
        lat, lon = to_global(x, y)
        items.append(
            M.MAVLink_mission_item_int_message(
                ROBOT_SYS, ROBOT_COMP, seq, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                M.MAV_CMD_NAV_WAYPOINT, 0, 1, hold, 0, 0,
                float("nan") if yaw_deg(h) is None else yaw_deg(h),
                lat, lon, 0.0, M.MAV_MISSION_TYPE_MISSION,
            )
        )
    return items


def expected(items):
    return [
        (i.frame, i.command, i.x, i.y, i.param1, _nan_none(i.param4)) for i in items
    ]


class Checks:
    def __init__(self):
        self.passed, self.failed, self.skipped = 0, 0, 0

    def skip(self, name, reason):
        self.skipped += 1
        print(f"skip  {name}: {reason}")
        sys.stdout.flush()

    def check(self, name, ok, detail=""):
        if ok:
            self.passed += 1
            print(f"ok    {name}")
        else:
            self.failed += 1
            print(f"FAIL  {name} {detail}")
        sys.stdout.flush()
        return ok


# How long after its command becomes zero a robot may still roll, in the
# robot's ms: the route scenario's drive ramps a wheel down from its
# 18 rad/s limit at 50 rad/s^2 (0.36 s), and its motors lag by 0.05 s. A
# pause that lands while the robot is catching up on its reference (the
# command a few cm/s above the reference's) rolls a few mm in that time.
COAST_MS = 600


def speed(p):
    return math.hypot(p.vx, p.vy)


def run_mission(gcs, c, route, name, pause_leg=None, bad_missions=None):
    """Arms, starts, (pauses mid-leg and continues), (sends bad missions while
    driving), waits for every MISSION_ITEM_REACHED and the end."""
    gcs.reached.clear()
    c.check(f"{name}: start accepted", gcs.command(M.MAV_CMD_MISSION_START, 0, 0) == 0)
    gcs.wait("running", lambda m: m.get_type() == "HEARTBEAT" and gcs.mode == 1, 5)
    if pause_leg is not None:
        (x0, y0), (x1, y1) = pause_leg
        # Early on the leg and moving (10 cm from its start): where the
        # pause lands depends on how soon it arrives, in wall time; this
        # leaves most of the leg (over 2 s of the robot's time) for it.
        def mid_leg(m):
            if m.get_type() != "LOCAL_POSITION_NED" or speed(m) < 0.05:
                return False
            x, y = m.y, m.x
            return math.hypot(x - x0, y - y0) > 0.1 and math.hypot(x - x1, y - y1) > 0.5
        gcs.wait("mid-leg", mid_leg, 60)
        c.check(f"{name}: pause accepted", gcs.command(M.MAV_CMD_DO_PAUSE_CONTINUE, 0) == 0)
        gcs.wait("paused", lambda m: m.get_type() == "HEARTBEAT" and gcs.mode == 2, 5)
        # Held: the command exactly zero within 2 s (LOCAL_POSITION_NED's
        # velocity is the commanded one), then, once the wheels have had
        # COAST_MS to stop, not moving.
        stopping = gcs.wait_type("LOCAL_POSITION_NED", 3, lambda m: speed(m) == 0.0)
        coasting = [stopping]
        while coasting[-1].time_boot_ms < stopping.time_boot_ms + COAST_MS:
            coasting.append(gcs.wait_type("LOCAL_POSITION_NED", 3))
        held = coasting[-1]
        later = [gcs.wait_type("LOCAL_POSITION_NED", 3) for _ in range(5)]
        coasted = math.hypot(held.x - stopping.x, held.y - stopping.y)
        moved = max(math.hypot(p.x - held.x, p.y - held.y) for p in later)
        x, y = held.y, held.x
        on_leg = math.hypot(x - x0, y - y0) > 0.05 and math.hypot(x - x1, y - y1) > 0.05
        c.check(
            f"{name}: paused mid-leg, held still",
            on_leg and moved < 0.001 and all(speed(p) == 0.0 for p in coasting + later),
            f"at ({x:.3f}, {y:.3f}), coasted {coasted:.4f} m, then moved {moved:.4f} m",
        )
        c.check(f"{name}: continue accepted", gcs.command(M.MAV_CMD_DO_PAUSE_CONTINUE, 1) == 0)
        gcs.wait("running again", lambda m: m.get_type() == "HEARTBEAT" and gcs.mode == 1, 5)
    if bad_missions is not None:
        bad_missions()
    gcs.wait("done", lambda m: m.get_type() == "HEARTBEAT" and gcs.mode == 3, 180)
    # The last MISSION_ITEM_REACHED follows the heartbeat of the mode
    # change in the same tick's frames: read on to the next position.
    final = gcs.wait_type("LOCAL_POSITION_NED", 2)
    c.check(
        f"{name}: every MISSION_ITEM_REACHED, in order",
        gcs.reached == list(range(len(route))),
        f"got {gcs.reached}",
    )
    x_end, y_end = route[-1][0], route[-1][1]
    error = math.hypot(final.y - x_end, final.x - y_end)
    c.check(
        f"{name}: final LOCAL_POSITION_NED within {FINAL_TOLERANCE_M * 100:.0f} cm of the last waypoint",
        error <= FINAL_TOLERANCE_M,
        f"{error * 100:.2f} cm",
    )


def free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--firmware-sim", required=True, help="the firmware-sim binary")
    parser.add_argument("--speedup", type=float, default=50.0)
    parser.add_argument("--hil", action="store_true",
                        help="against the firmware under QEMU (firmware-sim hil --mavlink)")
    parser.add_argument("--firmware", help="with --hil: the QEMU-board firmware ELF "
                        "(default: firmware-sim builds it)")
    parser.add_argument("--particle-filter", action="store_true",
                        help="with --hil: the route scenario with the fusion estimator's "
                        "particle filter (--firmware: one built with fusion-particle-filter)")
    args = parser.parse_args()
    if args.particle_filter and not args.hil:
        parser.error("--particle-filter needs --hil")

    port = free_port()
    gcs = Gcs(port)
    out_dir = tempfile.mkdtemp(prefix="wmr-gcs-hil-") if args.hil else None
    scenario = "route"
    if args.particle_filter:
        scenario = particle_filter_route(args.firmware_sim, out_dir)
    if args.hil:
        command = [
            args.firmware_sim, "hil", scenario,
            "--mavlink", f"udp:127.0.0.1:{port}",
            "--speedup", str(args.speedup),
            # Far longer than the checks take; they end the run by Ctrl-C.
            "--duration-s", "600",
            "--out", out_dir, "--no-plot", "--telemetry-every", "0",
            "--origin", f"{ORIGIN[0]},{ORIGIN[1]}",
        ] + (["--firmware", args.firmware] if args.firmware else [])
    else:
        command = [
            args.firmware_sim, "sitl", "route",
            "--mavlink", f"udp:127.0.0.1:{port}",
            "--speedup", str(args.speedup),
            "--duration-s", "3600",
            "--origin", f"{ORIGIN[0]},{ORIGIN[1]}",
            # Disarmed and idle at power-on, the route as the mission.
            "--power-on", "wait",
        ]
    sitl = subprocess.Popen(command, stdin=subprocess.DEVNULL)
    c = Checks()
    wall = time.monotonic()

    def check(name, ok, detail=""):
        """A check of the SITL's list: skipped by name against the
        firmware under QEMU if it lacks the feature (HIL_SKIPS)."""
        if args.hil and name in HIL_SKIPS:
            c.skip(name, HIL_SKIPS[name])
            return True
        return c.check(name, ok, detail)

    try:
        gcs.wait("the robot's heartbeat", lambda m: m.get_type() == "HEARTBEAT", 10)
        if args.hil:
            # The firmware runs the scenario's route from power-on, armed.
            hb = gcs.wait("running", lambda m: m.get_type() == "HEARTBEAT" and gcs.mode == 1, 5)
            c.check("the scenario's route runs from power-on, armed (no ground station needed)",
                    hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED != 0)
        else:
            hb = gcs.wait("a heartbeat", lambda m: m.get_type() == "HEARTBEAT", 5)
            c.check("power_on = wait: disarmed and idle at power-on",
                    hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED == 0 and gcs.mode == 0)
            c.check("power_on = wait: the scenario's route is the mission (read back)",
                    len(gcs.download()) >= 2)
        # Before any GCS heartbeat (the link watch starts with the first):
        # a link timeout long enough for a loaded machine (60 s simulated),
        # 3 s again for the link-loss check at the end.
        c.check("LINK_TIMEOUT_MS set to 60000", gcs.param_set("LINK_TIMEOUT_MS", 60000) == 60000)
        # A heartbeat every 20 ms of wall time: 1 s simulated at 50x.
        gcs.start_heartbeats(0.02 * 50.0 / args.speedup)

        # Parameters.
        c.check("RT_MAX_SPEED set to 0.25 and read back",
                abs(gcs.param_set("RT_MAX_SPEED", 0.25) - 0.25) < 1e-6
                and abs(gcs.param_read("RT_MAX_SPEED") - 0.25) < 1e-6)
        refused = gcs.param_set("RT_MAX_SPEED", -1.0)
        gcs.wait("refusal text", lambda m: m.get_type() == "STATUSTEXT" and "RT_MAX_SPEED" in m.text, 5)
        c.check("RT_MAX_SPEED = -1 refused (old value kept)",
                abs(refused - 0.25) < 1e-6 and abs(gcs.param_read("RT_MAX_SPEED") - 0.25) < 1e-6)
        c.check("RT_MAX_SPEED back to 0.3", abs(gcs.param_set("RT_MAX_SPEED", 0.3) - 0.3) < 1e-6)
        # A gain of the tracking law: checked by the core as a robot
        # file's, taken by the robot from its next tick; restored.
        c.check(f"TRK_K1 read as the robot's ({ROUTE_K1})",
                abs(gcs.param_read("TRK_K1") - ROUTE_K1) < 1e-6)
        c.check("TRK_K1 set to 1.5 and read back",
                abs(gcs.param_set("TRK_K1", 1.5) - 1.5) < 1e-6
                and abs(gcs.param_read("TRK_K1") - 1.5) < 1e-6)
        refused = gcs.param_set("TRK_K1", -1.0)
        gcs.wait("refusal text", lambda m: m.get_type() == "STATUSTEXT" and "TRK_K1" in m.text, 5)
        c.check("TRK_K1 = -1 refused (old value kept)",
                abs(refused - 1.5) < 1e-6 and abs(gcs.param_read("TRK_K1") - 1.5) < 1e-6)
        c.check(f"TRK_K1 back to {ROUTE_K1}",
                abs(gcs.param_set("TRK_K1", ROUTE_K1) - ROUTE_K1) < 1e-6)

        if args.hil:
            # Held where it is, so that the missions below start as on
            # the SITL (from idle): an upload while driving would replace
            # the scenario's route at its next rest instead.
            c.check("pause of the scenario's route accepted",
                    gcs.command(M.MAV_CMD_DO_PAUSE_CONTINUE, 0) == 0)
            gcs.wait("paused", lambda m: m.get_type() == "HEARTBEAT" and gcs.mode == 2, 5)

        # The local mission: upload, read back.
        items = local_items(ROUTE)
        c.check("LOCAL_NED mission accepted", gcs.upload(items) == M.MAV_MISSION_ACCEPTED)
        c.check("LOCAL_NED mission read back equal", gcs.download() == expected(items))
        c.check("arm accepted", gcs.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == 0)

        def bad_missions():
            def nan_item(seq):
                return M.MAVLink_mission_item_message(
                    ROBOT_SYS, ROBOT_COMP, seq, M.MAV_FRAME_LOCAL_NED, M.MAV_CMD_NAV_WAYPOINT,
                    0, 1, 0, 0, 0, float("nan"), float("nan") if seq == 1 else 0.5, 0.5, 0.0,
                    M.MAV_MISSION_TYPE_MISSION)
            unknown = local_items(ROUTE[:3])
            unknown[1].command = 31999
            frame = local_items(ROUTE[:3])
            frame[2].frame = M.MAV_FRAME_BODY_NED
            cases = [
                ("more items than capacity", local_items(ROUTE) * 11, M.MAV_MISSION_NO_SPACE),
                ("a NaN coordinate", [nan_item(s) for s in range(3)], M.MAV_MISSION_INVALID_PARAM5_X),
                ("an unknown command", unknown, M.MAV_MISSION_UNSUPPORTED),
                ("an unsupported frame", frame, M.MAV_MISSION_UNSUPPORTED_FRAME),
            ]
            for label, bad, result in cases:
                for seq, item in enumerate(bad):
                    item.seq = seq
                got = gcs.upload(bad)
                c.check(f"bad mission ({label}): {result}", got == result, f"got {got}")
            c.check("running mission kept (read back, still running)",
                    gcs.download() == expected(items) and gcs.mode == 1)

        run_mission(gcs, c, ROUTE, "LOCAL_NED mission",
                    pause_leg=((0.0, 0.0), (1.0, 0.0)), bad_missions=bad_missions)

        # The counters (one every 333 ms at the default 5 s period): after
        # the loop's ~40 s, each has come, the fixes and frames counted.
        missing = [n for n in COUNTER_NAMES if n not in gcs.counters]
        c.check("every tracker and RFID counter arrived as NAMED_VALUE_INT",
                not missing, f"missing {missing}")
        c.check("fixes used and RFID frames counted (TRK_FIXES, RF_FRAMES > 0)",
                gcs.counters.get("TRK_FIXES", 0) > 0 and gcs.counters.get("RF_FRAMES", 0) > 0,
                str(gcs.counters))

        # The global mission, from where the loop ended.
        gitems = global_items(GLOBAL_ROUTE)
        check("GLOBAL_RELATIVE_ALT_INT mission accepted",
              gcs.upload(gitems) == M.MAV_MISSION_ACCEPTED)
        check("global mission read back equal", gcs.download() == expected(gitems))
        run_mission(gcs, c, GLOBAL_ROUTE, "global mission")
        # Link loss mid-leg: back along the global mission's first leg.
        back = [(0.6, 0.5, 0.0, None), (0.6, 0.0, 0.0, None), (0.0, 0.0, 0.0, None)]
        c.check("return mission accepted", gcs.upload(local_items(back)) == M.MAV_MISSION_ACCEPTED)
        c.check("return: start accepted", gcs.command(M.MAV_CMD_MISSION_START, 0) == 0)
        gcs.wait_type("LOCAL_POSITION_NED", 60, lambda m: speed(m) > 0.1)
        # Heartbeats stopped first, then the 3 s timeout set: no window in
        # which a late heartbeat thread could lose the link by itself.
        gcs.heartbeats.clear()
        with gcs.lock:  # a heartbeat being sent is out before the drain
            pass
        gcs.drain()
        last_hb_ms = gcs.wait_type("LOCAL_POSITION_NED", 2).time_boot_ms
        c.check("LINK_TIMEOUT_MS set to 3000", gcs.param_set("LINK_TIMEOUT_MS", 3000) == 3000)
        gcs.wait("link lost", lambda m: m.get_type() == "STATUSTEXT" and "link lost" in m.text, 10)
        lost_ms = gcs.wait_type("LOCAL_POSITION_NED", 2).time_boot_ms
        gcs.wait("stopped", lambda m: m.get_type() == "HEARTBEAT" and gcs.mode == 4, 5)
        # At rest within the ramp at the failsafe deceleration (under 2 s
        # from 0.3 m/s), then still.
        rest = gcs.wait_type("LOCAL_POSITION_NED", 3, lambda m: speed(m) == 0.0)
        later = [gcs.wait_type("LOCAL_POSITION_NED", 3) for _ in range(5)]
        moved = max(math.hypot(p.x - rest.x, p.y - rest.y) for p in later)
        # Within the 3 s timeout of the last heartbeat the robot handled,
        # plus one telemetry period each side (the heartbeats in flight).
        c.check("link lost within the timeout, stopped (MAV_STATE_EMERGENCY)",
                lost_ms - last_hb_ms <= 3000 + 400 and gcs.system_status == M.MAV_STATE_EMERGENCY,
                f"{lost_ms - last_hb_ms} ms")
        c.check("robot stopped and held after the link loss",
                moved < 0.001 and all(speed(p) == 0.0 for p in later), f"moved {moved:.4f} m")
        gcs.start_heartbeats(0.02 * 50.0 / args.speedup)
        gcs.wait("link regained", lambda m: m.get_type() == "STATUSTEXT" and "regained" in m.text, 10)
        c.check("disarm after the loss accepted", gcs.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 0) == 0)
    except Failed as e:
        c.check("(wait)", False, str(e))
    finally:
        gcs.stop_thread.set()
        if args.hil:
            # Ctrl-C: the run ends at its next tick, the firmware is
            # finished, the outputs are written.
            sitl.send_signal(signal.SIGINT)
        else:
            sitl.terminate()
        try:
            status = sitl.wait(timeout=60)
        except subprocess.TimeoutExpired:
            sitl.kill()
            status = sitl.wait()
    if args.hil:
        hil_end(c, status, out_dir, args.particle_filter)
        # The run's files are kept for a look when a check failed.
        if c.failed == 0:
            shutil.rmtree(out_dir, ignore_errors=True)
        else:
            print(f"the HIL run's files: {out_dir}")
    print(f"robot time {gcs.sim_ms / 1000:.1f} s simulated in {time.monotonic() - wall:.1f} s")
    print(f"{c.passed} passed, {c.failed} failed, {c.skipped} skipped")
    return 0 if c.failed == 0 else 1


def particle_filter_route(firmware_sim, out_dir):
    """The route scenario (`firmware-sim show route`) with the fusion
    estimator's particle filter (wheel noise 2e-7 m^2/m, as the HIL tests
    tune it), written into out_dir; its path."""
    text = subprocess.run([firmware_sim, "show", "route"], check=True,
                          capture_output=True, text=True).stdout
    ekf = 'filter = "ekf"\n'
    if text.count(ekf) != 1:
        raise SystemExit("the route scenario's fusion filter line not found: "
                         "update particle_filter_route()")
    text = text.replace(ekf, 'filter = "particle_filter"\nwheel_variance_per_m = 2e-7\n')
    path = os.path.join(out_dir, "route_particle_filter.toml")
    with open(path, "w") as f:
        f.write(text)
    return path


def hil_end(c, status, out_dir, particle_filter):
    """The HIL run's end, from its summary.json: ended by Ctrl-C, cleanly;
    the host's copy of the firmware's session answered every MAVLink
    message as the firmware did; no byte dropped on the way; with
    particle_filter, the filter used the tags' fixes."""
    try:
        with open(os.path.join(out_dir, "summary.json")) as f:
            summary = json.load(f)
        mavlink = summary["hil"]["mavlink"]
    except (OSError, KeyError, ValueError) as e:
        c.check("Ctrl-C ends the HIL run cleanly (summary written)", False, f"exit {status}: {e}")
        return
    if particle_filter:
        tracker = summary.get("tracker") or {}
        c.check("the particle filter used the tags' fixes",
                tracker.get("fixes_used", 0) > 0, f"{tracker}")
    c.check("Ctrl-C ends the HIL run cleanly (summary written)",
            status == 0 and mavlink["interrupted"], f"exit {status}")
    c.check("host copy of the session gave every MAVLink answer the firmware gave",
            mavlink["copy_mismatches"] == 0 and mavlink["copy_compared"] > 0,
            f"{mavlink['copy_mismatches']} of {mavlink['copy_compared']} differ")
    firmware = mavlink["firmware"]
    # None: the operating system's count could not be read (not Linux).
    kernel = mavlink["udp"]["kernel_dropped_datagrams"]
    c.check("no MAVLink byte dropped (socket, host backlog, firmware queues)",
            kernel in (0, None) and mavlink["dropped_bytes"] == 0
            and firmware["rx_dropped_bytes"] == 0 and firmware["tx_dropped_frames"] == 0,
            f"kernel {kernel} datagrams, backlog {mavlink['dropped_bytes']} B, {firmware}")
    print(f"hil: {mavlink['speedup_achieved']:.1f}x real time (asked {mavlink['speedup']}x), "
          f"{mavlink['messages']} channel messages")


if __name__ == "__main__":
    sys.exit(main())
