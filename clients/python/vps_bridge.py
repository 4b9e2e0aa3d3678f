"""A standard-library Python 3 client for the vps UDP device bridge (socket and struct only).

Protocol version 1, as documented in crates/vps-input/src/bridge/protocol.rs. Every integer and
float is little-endian (floats as IEEE 754 binary64), whatever the host's byte order:

    offset size field
         0    4 magic b"VPSB"
         4    1 version = 1
         5    1 kind: 1 PoseIn, 3 PoseInFlags (client -> vps), 2 WrenchOut (vps -> client)
         6   16 token (shared secret; all zero when vps has none)
        22    8 sequence u64 (strictly increasing per sender)
        30      payload
    PoseInFlags (138 bytes): position xyz (m), orientation quaternion xyzw (unit), linear velocity
                 xyz (m/s), angular velocity xyz (rad/s): 13 doubles, then flags u32
                 (bit 0 FLAG_CLUTCH; other bits must be zero)
    WrenchOut   (86 bytes): force xyz (N), torque xyz (N.m): 6 doubles, then frame u64

Poses are in the device's own frame; vps maps them into the scene and maps the wrench back
(docs/devices.md).

    bridge = Bridge("127.0.0.1:7700")
    bridge.send_pose(position, orientation, linear_velocity, angular_velocity, clutch=False)
    wrench = bridge.recv_latest()   # None when nothing is pending; never blocks
    bridge.close()
"""

import socket
import struct

VERSION = 1
KIND_POSE_IN = 1
KIND_WRENCH_OUT = 2
KIND_POSE_IN_FLAGS = 3
FLAG_CLUTCH = 1
HEADER = struct.Struct("<4sBB16sQ")
POSE_IN_FLAGS = struct.Struct("<4sBB16sQ13dI")
WRENCH_OUT = struct.Struct("<4sBB16sQ6dQ")
assert HEADER.size == 30 and POSE_IN_FLAGS.size == 138 and WRENCH_OUT.size == 86


class Wrench:
    """A wrench received from vps: force (N) and torque (N.m), device frame, already scaled and
    within the device's limits; frame is vps's write counter; raw is the datagram's payload
    doubles as their 8-byte little-endian encodings (for exact comparisons)."""

    __slots__ = ("force", "torque", "frame", "raw")

    def __init__(self, force, torque, frame, raw):
        self.force = force
        self.torque = torque
        self.frame = frame
        self.raw = raw

    def bits_hex(self):
        """The six doubles as 16-hex-digit IEEE 754 bit patterns (force xyz, torque xyz)."""
        return ["%016x" % struct.unpack("<Q", b)[0] for b in self.raw]


def encode_pose(token, sequence, position, orientation, linear_velocity, angular_velocity, flags):
    """A PoseInFlags datagram (138 bytes). Units: m, unit quaternion xyzw, m/s, rad/s."""
    values = list(position) + list(orientation) + list(linear_velocity) + list(angular_velocity)
    if len(values) != 13:
        raise ValueError("position, velocities: 3 numbers each; orientation: 4 (x, y, z, w)")
    return POSE_IN_FLAGS.pack(
        b"VPSB", VERSION, KIND_POSE_IN_FLAGS, token, sequence, *values, flags
    )


def decode_wrench(data, token):
    """The Wrench in a WrenchOut datagram, or None when it is not a valid one for this token."""
    if len(data) != WRENCH_OUT.size:
        return None
    magic, version, kind, tok, _seq, fx, fy, fz, tx, ty, tz, frame = WRENCH_OUT.unpack(data)
    if magic != b"VPSB" or version != VERSION or kind != KIND_WRENCH_OUT or tok != token:
        return None
    values = (fx, fy, fz, tx, ty, tz)
    if any(v != v or v in (float("inf"), float("-inf")) for v in values):
        return None
    raw = [data[30 + 8 * i : 38 + 8 * i] for i in range(6)]
    return Wrench((fx, fy, fz), (tx, ty, tz), frame, raw)


class Bridge:
    """A non-blocking UDP client connected to one vps bridge device."""

    def __init__(self, host_port, token=None):
        """host_port: "HOST:PORT" (or "[v6addr]:PORT"); token: 16 bytes, or None for none."""
        host, sep, port = host_port.rpartition(":")
        if not sep or not host or not port.isdigit():
            raise ValueError("expected HOST:PORT, got %r" % host_port)
        host = host.strip("[]")
        if token is not None and len(token) != 16:
            raise ValueError("the token is 16 bytes")
        self.token = bytes(token) if token is not None else bytes(16)
        family, kind, proto, _, addr = socket.getaddrinfo(host, int(port), 0, socket.SOCK_DGRAM)[0]
        self.sock = socket.socket(family, kind, proto)
        self.sock.connect(addr)
        self.sock.setblocking(False)
        self.sequence = 0

    def send_pose(self, position, orientation, linear_velocity, angular_velocity, clutch=False):
        """Sends the next pose (sequence numbers start at 1). Returns False when the datagram
        could not be sent now (socket buffer full, or vps refused it); never blocks."""
        self.sequence += 1
        data = encode_pose(
            self.token,
            self.sequence,
            position,
            orientation,
            linear_velocity,
            angular_velocity,
            FLAG_CLUTCH if clutch else 0,
        )
        try:
            return self.sock.send(data) == len(data)
        except (BlockingIOError, ConnectionRefusedError):
            return False

    def recv_wrench(self):
        """The next pending valid wrench, or None when none is pending. Never blocks."""
        while True:
            try:
                data = self.sock.recv(WRENCH_OUT.size + 1)
            except (BlockingIOError, ConnectionRefusedError):
                return None
            w = decode_wrench(data, self.token)
            if w is not None:
                return w

    def recv_latest(self):
        """Drains every pending wrench and returns the newest, or None. Never blocks."""
        latest = None
        while True:
            w = self.recv_wrench()
            if w is None:
                return latest
            latest = w

    def close(self):
        self.sock.close()
