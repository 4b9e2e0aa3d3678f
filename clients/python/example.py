#!/usr/bin/env python3
"""A simulated haptic device driving vps over the UDP bridge at 1 kHz.

    vps run --device bridge:127.0.0.1:7700 --seconds 30 &
    python3 example.py 127.0.0.1:7700 10

The device point holds the clutch for the first 0.1 s (so vps anchors it where the part starts),
then moves 0.15 m along -Z and back every 2 s (with `vps run --map-scale 6` it reaches the floor
of the built-in bay). Every 100th wrench received is printed; the last line is exactly
`wrenches N` (N = wrenches received). With VPS_DUMP=FILE set, every wrench received is written to
FILE as one line `FRAME FX FY FZ TX TY TZ`, each float as the 16 hex digits of its IEEE 754 bits.

The loop sleeps to absolute deadlines, so a late wake-up does not delay the following ticks.
"""

import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from vps_bridge import Bridge  # noqa: E402

AMPLITUDE = 0.15  # m
PERIOD = 2.0  # s
CLUTCH_UNTIL = 0.1  # s


def simulated_pose(t):
    """Position (m) and linear velocity (m/s) of the simulated device at t (s), device frame."""
    if t < CLUTCH_UNTIL:
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    s = t - CLUTCH_UNTIL
    w = 2.0 * math.pi / PERIOD
    z = -AMPLITUDE * 0.5 * (1.0 - math.cos(w * s))
    vz = -AMPLITUDE * 0.5 * w * math.sin(w * s)
    return (0.0, 0.0, z), (0.0, 0.0, vz)


def main(argv):
    if len(argv) != 3:
        print("usage: %s HOST:PORT SECONDS" % argv[0], file=sys.stderr)
        return 2
    try:
        seconds = float(argv[2])
    except ValueError:
        seconds = float("nan")
    if not 0.0 < seconds <= 86400.0:
        print("SECONDS must be a number in (0, 86400], got %r" % argv[2], file=sys.stderr)
        return 2
    bridge = Bridge(argv[1])
    dump_path = os.environ.get("VPS_DUMP")
    dump = open(dump_path, "w") if dump_path else None
    received = 0
    send_errors = 0

    def drain():
        nonlocal received
        while True:
            w = bridge.recv_wrench()
            if w is None:
                return
            received += 1
            if dump:
                dump.write("%d %s\n" % (w.frame, " ".join(w.bits_hex())))
            if received % 100 == 0:
                print(
                    "frame %d force %.4f %.4f %.4f N torque %.5f %.5f %.5f N.m"
                    % ((w.frame,) + w.force + w.torque)
                )

    ticks = int(round(seconds * 1000.0))
    start = time.monotonic()
    for k in range(ticks):
        t = k * 1e-3
        position, velocity = simulated_pose(t)
        if not bridge.send_pose(
            position, (0.0, 0.0, 0.0, 1.0), velocity, (0.0, 0.0, 0.0), clutch=t < CLUTCH_UNTIL
        ):
            send_errors += 1
        drain()
        # Absolute deadline: tick k + 1 is due at start + (k + 1) ms.
        delay = start + (k + 1) * 1e-3 - time.monotonic()
        if delay > 0:
            time.sleep(delay)
    # Collect the replies still in flight (50 ms).
    for k in range(50):
        drain()
        time.sleep(1e-3)
    bridge.close()
    if dump:
        dump.close()
    print("poses sent %d, send errors %d" % (ticks - send_errors, send_errors), file=sys.stderr)
    print("wrenches %d" % received)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
