#!/usr/bin/env python3
"""Conformance of `sweepline emulate create2` with the iRobot Create 2 Open
Interface (OI) specification, driven by a client nobody here wrote:
pycreate2 0.8.0 (see requirements.txt).

Usage: create2_pycreate2.py PATH/TO/sweepline

Starts the emulator (it prints its pty path on stdout's first line), calls
every public method of pycreate2's Create2 at least once and checks what the
specification says a real robot answers. Where pycreate2 itself is wrong or
lacks a call, the check says so and talks to the robot through the library's
own serial object (robot.SCI) instead: pycreate2 0.8.0 has no seek_dock,
spot, clean, max, turn_angle, drive_distance or query_list (they are
commented out in its source), and its getMode() raises. The emulator's
closing line counts what it rejected: the script's own probes of the Off and
Passive modes, and pycreate2's clearSongMemory(), which plays songs in
Passive mode (stop(), reset()) where the specification takes no Play.
Prints one line per check and ends
with `create2 conformance: N passed, M failed`; exits non-zero on failure.
"""

import contextlib
import io
import os
import signal
import struct
import subprocess
import sys
import time

from pycreate2 import Create2
from pycreate2.OI import OPCODES, RESPONSE_SIZES
from pycreate2.packets import SensorPacketDecoder

from checks import Checks

# Packet sizes from the OI specification. pycreate2's RESPONSE_SIZES has 3 for
# the unused packets 32 and 33; the specification gives 1 and 2 bytes.
SINGLE_SIZES = {i: 1 for i in range(7, 59)}
SINGLE_SIZES.update({i: 2 for i in (19, 20, 22, 23, *range(25, 32), 33,
                                    *range(39, 45), *range(46, 52), *range(54, 58))})
GROUPS = {0: (7, 26), 1: (7, 16), 2: (17, 20), 3: (21, 26), 4: (27, 34),
          5: (35, 42), 6: (7, 42), 100: (7, 58), 101: (43, 58), 106: (46, 51),
          107: (54, 58)}
MODES = {0: "Off", 1: "Passive", 2: "Safe", 3: "Full"}


def size(pid):
    if pid in GROUPS:
        a, b = GROUPS[pid]
        return sum(SINGLE_SIZES[i] for i in range(a, b + 1))
    return SINGLE_SIZES[pid]


def quiet(f, *a):
    """Calls pycreate2 `f`, swallowing its banner prints."""
    with contextlib.redirect_stdout(io.StringIO()):
        return f(*a)


class Raw:
    """The robot through pycreate2's own serial object, for what the library
    cannot ask."""

    def __init__(self, robot):
        self.ser = robot.SCI.ser
        self.sci = robot.SCI

    def query(self, ids, timeout=2.0):
        """Query List: the packets' data, concatenated (a loaded machine may
        answer late: a lost distance or angle reply would be lost travel)."""
        n = sum(size(i) for i in ids)
        self.ser.reset_input_buffer()
        self.sci.write(OPCODES.QUERY_LIST, (len(ids),) + tuple(ids))
        old = self.ser.timeout
        self.ser.timeout = timeout
        data = self.ser.read(n)
        self.ser.timeout = old
        return data

    def mode(self):
        d = self.query([35], timeout=1.0)
        return d[0] if len(d) == 1 else None

    def silent(self):
        """Whether a query of the mode goes unanswered (OI off)."""
        return self.query([35], timeout=0.3) == b""

    def collect(self, secs):
        """Everything the robot sends in the next `secs` seconds."""
        data = b""
        t_end = time.monotonic() + secs
        while time.monotonic() < t_end:
            self.ser.timeout = max(0.0, t_end - time.monotonic())
            data += self.ser.read(max(1, self.ser.in_waiting))
        self.ser.timeout = 1
        return data

    def s16(self, pid):
        d = self.query([pid])
        return struct.unpack(">h", d)[0] if len(d) == 2 else None

    def u16(self, pid):
        d = self.query([pid])
        return struct.unpack(">H", d)[0] if len(d) == 2 else None

    def distance_angle(self):
        """Packets 19 and 20 (mm, degrees) since they were last read."""
        d = self.query([19, 20])
        return struct.unpack(">hh", d) if len(d) == 4 else (0, 0)

    def encoders(self):
        d = self.query([43, 44])
        return struct.unpack(">HH", d) if len(d) == 4 else (None, None)


def delta(a, b):
    """Signed difference of two wrapping 16-bit encoder counts."""
    d = (b - a) & 0xFFFF
    return d - 0x10000 if d >= 0x8000 else d


def frames(buf):
    """Stream frames (19, n, payload, checksum) found in `buf`: valid ones."""
    out, i = [], 0
    while i + 2 < len(buf):
        if buf[i] == 19:
            n = buf[i + 1]
            f = buf[i:i + n + 3]
            if len(f) == n + 3 and sum(f) & 0xFF == 0:
                out.append(f[2:-1])
                i += n + 3
                continue
        i += 1
    return out


def drive_for(robot, raw, r, l, secs):
    """Drives (pycreate2 drive_direct) for `secs`; encoder deltas (l, r) and
    the distance and angle read every 0.2 s and summed, as the
    specification's read-and-reset packets 19 and 20 are meant to be used."""
    raw.distance_angle()  # both restart from zero
    e0 = raw.encoders()
    robot.drive_direct(r, l)
    dist = ang = 0
    t_end = time.monotonic() + secs
    while time.monotonic() < t_end:
        time.sleep(0.2)
        a, b = raw.distance_angle()
        dist, ang = dist + a, ang + b
    robot.drive_direct(0, 0)
    time.sleep(0.3)
    a, b = raw.distance_angle()
    dist, ang = dist + a, ang + b
    e1 = raw.encoders()
    return delta(e0[0], e1[0]), delta(e0[1], e1[1]), dist, ang


def run(binary, c):
    emu = subprocess.Popen([binary, "emulate", "create2"], stdout=subprocess.PIPE,
                           stderr=subprocess.DEVNULL, text=True)
    try:
        first = emu.stdout.readline().strip()
        port = first.split()[-1] if first else ""
        if not c.check("emulator prints its pty path", port.startswith("/dev/"), first):
            return
        conformance(port, c)
    finally:
        emu.send_signal(signal.SIGINT)
        try:
            rest = emu.communicate(timeout=5)[0]
        except subprocess.TimeoutExpired:
            emu.kill()
            rest = ""
        for line in rest.splitlines():
            print(f"info emulator: {line}")


def conformance(port, c):
    robot = quiet(Create2, port, 115200)
    raw = Raw(robot)
    c.check("Create2(port, baud=115200) opens the pty", robot.SCI.ser.is_open)

    c.check("before start(): the OI is off and answers nothing", raw.silent())
    robot.start()
    c.check("start(): mode Passive", raw.mode() == 1, f"mode {raw.mode()}")
    try:
        quiet(robot.getMode)
        c.check("getMode()", False, "expected pycreate2's AttributeError")
    except AttributeError as e:
        # pycreate2 bug: getMode() writes OPCODES.MODE, which OI.py does not
        # define; the mode is read as packet 35 instead (above and below).
        c.check("getMode(): pycreate2 bug (no OPCODES.MODE), mode read as packet 35",
                raw.mode() == 1, str(e))
    robot.drive_direct(100, 100)
    time.sleep(0.3)
    e0 = raw.encoders()
    time.sleep(0.3)
    e1 = raw.encoders()
    c.check("Passive mode ignores drive_direct (no wheel motion)",
            e0 == e1 and raw.s16(41) == 0, f"encoders {e0} -> {e1}")

    robot.safe()
    c.check("safe(): mode Safe", raw.mode() == 2, f"mode {raw.mode()}")

    s = robot.get_sensors()
    s = robot.get_sensors()
    c.check("get_sensors(): packet 100 answered, 80 bytes decoded",
            s.open_interface_mode == 2, f"mode {s.open_interface_mode}")
    c.check("get_sensors(): battery plausible",
            13000 <= s.voltage <= 17000 and s.current < 0 and 0 < s.battery_charge
            <= s.battery_capacity and 0 <= s.temperature <= 60,
            f"{s.voltage} mV {s.current} mA {s.temperature} C "
            f"{s.battery_charge}/{s.battery_capacity} mAh")
    c.check("get_sensors(): at rest distance 0, angle 0, requested velocities 0",
            (s.distance, s.angle, s.velocity_left, s.velocity_right) == (0, 0, 0, 0),
            f"{s.distance} mm {s.angle} deg {s.velocity_left}/{s.velocity_right} mm/s")
    c.check("get_sensors(): nothing sensed on open floor (no bump, drop, cliff, wall)",
            not any(s.bumps_wheeldrops) and not (s.cliff_left or s.cliff_front_left or
                                                 s.cliff_front_right or s.cliff_right)
            and not s.wall and s.light_bumper_left == 0)
    charge0 = s.battery_charge

    e0 = raw.encoders()
    time.sleep(0.5)
    e1 = raw.encoders()
    c.check("encoders do not move while stopped", e0 == e1, f"{e0} -> {e1}")

    robot.drive_direct(100, 100)
    time.sleep(0.3)
    s = robot.get_sensors()
    c.check("requested velocities 39-42 follow drive_direct(100, 100)",
            (s.velocity, s.velocity_right, s.velocity_left) == (100, 100, 100),
            f"{s.velocity} {s.velocity_right} {s.velocity_left}")
    robot.drive_stop()
    dl, dr, dist, ang = drive_for(robot, raw, 100, 100, 1.0)
    c.check("drive_direct(100, 100) for 1 s: both encoders count ~225 forward",
            150 < dl < 330 and 150 < dr < 330 and abs(dl - dr) <= 0.05 * max(dl, dr),
            f"left {dl} right {dr}")
    c.check("distance (19) sums to ~100 mm, angle (20) ~0",
            70 <= dist <= 145 and abs(ang) <= 2, f"{dist} mm {ang} deg")
    c.check("distance reads back 0 right after a read (reset on read)",
            raw.s16(19) == 0 and raw.s16(20) == 0)
    e0 = raw.encoders()
    time.sleep(0.3)
    c.check("drive_stop(): encoders stand still", raw.encoders() == e0)

    dl, dr, dist, ang = drive_for(robot, raw, 100, -100, 1.5)
    # Right forward, left back: counter-clockwise, positive in the OI.
    # 0.2 m/s apart on a 235 mm base: ~49 deg/s.
    c.check("turn in place counter-clockwise: angle (20) positive, ~70 deg",
            45 <= ang <= 90 and abs(dist) <= 3 and dl < 0 < dr,
            f"{ang} deg {dist} mm, encoders {dl} / {dr}")

    # The issue: the note duration 145 was taken for Drive Direct's opcode.
    robot.createSong(0, [60, 145])
    dl, dr, dist, ang = drive_for(robot, raw, 100, 100, 1.0)
    c.check("createSong(0, [60, 145]) then drive_direct(100, 100) drives straight",
            dl > 150 and dr > 150 and abs(dl - dr) <= 0.05 * max(dl, dr) and abs(ang) <= 2,
            f"encoders {dl} / {dr}, {ang} deg")
    robot.playSong(0)
    d = raw.query([36, 37])
    c.check("playSong(0): song 0 playing (packets 36, 37)", d == bytes([0, 1]), d.hex())
    robot.clearSongMemory()
    c.check("clearSongMemory(): mode unchanged", raw.mode() == 2)

    # led(0, 128, 255): 0x80 is Start's opcode, here a data byte.
    robot.led(0, 128, 255)
    c.check("led(0, 128, 255) does not change the mode", raw.mode() == 2, f"mode {raw.mode()}")
    robot.led(0x0F, 255, 128)
    robot.digit_led_ascii("ABCD")
    c.check("digit_led_ascii('ABCD') does not change the mode", raw.mode() == 2)

    robot.full()
    c.check("full(): mode Full", raw.mode() == 3, f"mode {raw.mode()}")
    e0 = raw.encoders()
    robot.drive_pwm(100, 100)
    time.sleep(0.5)
    robot.drive_direct(0, 0)
    time.sleep(0.2)
    e1 = raw.encoders()
    c.check("drive_pwm(100, 100) drives forward", delta(e0[0], e1[0]) > 20 and
            delta(e0[1], e1[1]) > 20, f"{e0} -> {e1}")
    c.check("limit(600, -500, 500) clamps", robot.limit(600, -500, 500) == 500)

    # Opcodes pycreate2 does not send, through its serial object, with data
    # bytes that are themselves opcodes (128 Start, 129 Baud, 131 Safe, 173
    # Stop): a robot that consumed too few or too many data bytes would change
    # mode or swallow the query that follows.
    tricky = [
        ("Baud 115200 (129)", 129, (11,)),
        ("Drive straight (137)", 137, (0, 0, 128, 0)),
        ("Motors (138)", 138, (7,)),
        ("PWM Motors (144)", 144, (129, 127, 127)),
        ("Scheduling LEDs (162)", 162, (127, 31)),
        ("Digit LEDs raw (163)", 163, (127, 6, 91, 79)),
        ("Buttons (165)", 165, (128,)),
        ("Schedule (167)", 167, (127, 9, 30, 10, 0, 11, 15, 12, 45, 13, 59, 14, 1, 23, 59)),
        ("Set Day/Time (168)", 168, (6, 23, 59)),
        ("Drive Direct (145)", 145, (0, 131, 0, 131)),
    ]
    bad = []
    for name, opc, data in tricky:
        robot.SCI.write(opc, data)
        if raw.mode() != 3:
            bad.append(name)
    d = raw.query([41, 42])
    c.check("every other opcode consumes exactly its data bytes (mode stays Full)",
            not bad and d == bytes([0, 131, 0, 131]), f"misread after {bad}" if bad else "")
    robot.SCI.write(130)
    c.check("Control (130): mode Safe, as the specification says", raw.mode() == 2)
    robot.drive_direct(0, 0)
    robot.full()

    # Group packets and single packets: every one answered with its size.
    ok = [pid for pid in list(GROUPS) + list(range(7, 59))
          if len(raw.query([pid])) == size(pid)]
    c.check("every packet 7-58 and group 0-6, 100, 101, 106, 107 answered",
            len(ok) == len(GROUPS) + 52, f"{len(ok)} of {len(GROUPS) + 52}")
    c.check("group sizes agree with pycreate2's RESPONSE_SIZES",
            all(RESPONSE_SIZES[g] == size(g) for g in GROUPS))
    d = raw.query([7, 100, 35])
    c.check("Query List [7, 100, 35]: 82 bytes, mode last",
            len(d) == 82 and d[-1] == 3, f"{len(d)} bytes")

    # pycreate2 bug: its BumpsAndWheelDrop fields are (bump_left, bump_right,
    # ...) but it fills them from bit 0 (bump RIGHT in the specification) and
    # bit 1; so bumps are checked on the raw packet 7 byte instead.
    swapped = SensorPacketDecoder(bytes([0x01]) + bytes(79)).bumps_wheeldrops
    c.check("pycreate2 names the spec's bump-right bit 0 bump_left (library bug)",
            swapped.bump_left and not swapped.bump_right)
    c.check("packet 7 raw byte: no bump, no wheel drop on open floor",
            raw.query([7]) == b"\x00")

    # Stream: 19, n, ids and data, checksum, every 15 ms; then pause.
    raw.ser.reset_input_buffer()
    robot.SCI.write(148, (3, 7, 43, 44))
    got = frames(raw.collect(0.3))
    c.check("Stream [7, 43, 44]: a valid frame every 15 ms",
            14 <= len(got) <= 24 and all(f[0] == 7 and f[2] == 43 and f[5] == 44 for f in got),
            f"{len(got)} frames in 0.3 s")
    robot.SCI.write(148, (1, 100))
    time.sleep(0.05)
    raw.ser.reset_input_buffer()
    got = frames(raw.collect(0.15))
    c.check("Stream [100]: frames of 81 payload bytes",
            len(got) >= 5 and all(len(f) == 81 and f[0] == 100 for f in got),
            f"{len(got)} frames in 0.15 s")
    robot.SCI.write(150, (0,))
    time.sleep(0.05)
    raw.ser.reset_input_buffer()
    c.check("Pause (150, 0) stops the stream", raw.collect(0.1) == b"")
    robot.SCI.write(150, (1,))
    got = frames(raw.collect(0.1))
    c.check("Resume (150, 1) restarts it", len(got) >= 3, f"{len(got)} frames in 0.1 s")
    robot.SCI.write(150, (0,))
    time.sleep(0.05)
    raw.ser.reset_input_buffer()

    # Cleaning commands: pycreate2 0.8.0 has no seek_dock/clean/max/spot
    # methods (commented out); sent through its serial object. Each puts the
    # robot in Passive mode.
    for name, opc in (("seek dock", 143), ("spot", 134), ("clean", 135), ("max", 136)):
        robot.full()
        robot.SCI.write(opc)
        time.sleep(0.05)
        c.check(f"{name} ({opc}): mode Passive", raw.mode() == 1, f"mode {raw.mode()}")

    robot.safe()
    robot.power()
    c.check("power(): mode Passive", raw.mode() == 1, f"mode {raw.mode()}")

    robot.stop()
    c.check("stop(): OI off, no answers", raw.silent())
    robot.start()
    c.check("start() after stop(): Passive again", raw.mode() == 1)

    msg = robot.reset()
    c.check("reset(): the robot prints its boot message", msg.startswith(b"bl-start"),
            repr(msg[:24]))
    time.sleep(0.2)
    raw.ser.reset_input_buffer()
    c.check("reset(): OI off afterwards", raw.silent())
    robot.start()

    try:
        robot.wake()
        c.check("wake(): toggles RTS/DTR", True)
    except OSError as e:
        # A pty has no modem lines: the BRC wake pulse cannot be emulated
        # (the emulated robot never sleeps).
        c.check("wake(): a pty has no RTS/DTR (the emulator never sleeps)", True, str(e))
    robot.safe()
    s = robot.get_sensors()
    c.check("battery charge drained with use", s.battery_charge < charge0,
            f"{charge0} -> {s.battery_charge} mAh")
    # The destructor (drive_stop, led, digit_led_ascii, stop, close) runs as
    # the last reference goes.
    sci = robot.SCI
    with contextlib.redirect_stdout(io.StringIO()):
        del robot
    c.check("__del__ and close(): port closed", not sci.ser.is_open)

    import serial
    ser = serial.Serial(port, 115200, timeout=0.3)
    ser.write(bytes([142, 35]))
    c.check("after stop() in the destructor the OI stays off", ser.read(1) == b"")
    ser.write(bytes([128, 142, 35]))
    c.check("Start then Sensors 35 answers Passive", ser.read(1) == b"\x01")
    ser.close()


def world_bump(binary, c):
    """In a room (`--world`), driving straight ahead closes a bumper: the
    80-byte get_sensors() packet's first byte (packet 7) shows it, on the
    bits the specification gives bumps (0 right, 1 left)."""
    world = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..",
                         "hw", "worlds", "paper.world")
    emu = subprocess.Popen([binary, "emulate", "create2", "--world", world, "--rate", "4"],
                           stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        port = emu.stdout.readline().split(" at ")[-1].split()[0]
        robot = quiet(Create2, port, 115200)
        raw = Raw(robot)
        robot.start()
        robot.safe()
        robot.drive_direct(200, 200)
        bumps = 0
        t_end = time.monotonic() + 20
        while time.monotonic() < t_end and not bumps:
            robot.SCI.ser.reset_input_buffer()
            robot.SCI.write(142, (100,))
            data = robot.SCI.read(80)
            bumps = data[0] & 0b11 if len(data) == 80 else 0
            time.sleep(0.05)
        robot.drive_direct(0, 0)
        c.check("--world: driving into a wall closes a bumper (get_sensors packet 100, byte 0)",
                bumps != 0, f"bits {bumps:02b}")
        # pycreate2's destructor stops the motors through the port: it is
        # left open for it, as the library expects.
    finally:
        emu.send_signal(signal.SIGINT)
        try:
            emu.communicate(timeout=5)
        except subprocess.TimeoutExpired:
            emu.kill()


def main():
    if len(sys.argv) != 2:
        print("usage: create2_pycreate2.py PATH/TO/sweepline", file=sys.stderr)
        return 2
    c = Checks()
    t0 = time.monotonic()
    try:
        run(sys.argv[1], c)
        world_bump(sys.argv[1], c)
    except Exception as e:  # a crash is a failed check, not a traceback
        c.check("script ran to the end", False, f"{type(e).__name__}: {e}")
    print(f"info took {time.monotonic() - t0:.1f} s")
    return c.close("create2 conformance")


if __name__ == "__main__":
    sys.exit(main())
