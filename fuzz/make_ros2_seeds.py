#!/usr/bin/env python3
"""Seeds of the ros2_sample and ros2_graph fuzz targets (fuzz/run-fuzzers.sh).

    make_ros2_seeds.py sample|graph OUT_DIR

sample: records [role byte][uint16 LE size][CDR], a small car's messages as
fuzz_ros2_sample.cpp reads them (roles: 0 left image, 1 right image, 2 left
camera_info, 3 right camera_info, 4 IMU, 5 NavSatFix, 6 TwistStamped,
7 TFMessage), plain little-endian CDR as ROS 2 writes it.
graph: rmw_dds_common/ParticipantEntitiesInfo messages, 16- and 24-byte gids.
"""
import os
import struct
import sys


class Cdr:
    def __init__(self):
        self.b = bytearray(b"\x00\x01\x00\x00")

    def align(self, n):
        while (len(self.b) - 4) % n:
            self.b.append(0)

    def put(self, fmt, *v):
        self.align(struct.calcsize(fmt))
        self.b += struct.pack("<" + fmt, *v)
        return self

    def string(self, s):
        self.put("I", len(s) + 1)
        self.b += s.encode() + b"\x00"
        return self

    def header(self, t_ns, frame):
        return self.put("i", t_ns // 10**9).put("I", t_ns % 10**9).string(frame)


T0 = 1_700_000_000 * 10**9


def image(t, frame, w=16, h=12):
    c = Cdr().header(t, frame).put("I", h).put("I", w).string("mono8").put("B", 0).put("I", w).put("I", w * h)
    c.b += bytes((x * 13 + t // 10**6) % 256 for x in range(w * h))
    return bytes(c.b)


def imu(t):
    c = Cdr().header(t, "imu")
    for v in (0, 0, 0, 1, -1) + (0,) * 8 + (0.1, 0, 0) + (0,) * 9 + (0.2, 0, 9.81) + (0,) * 9:
        c.put("d", float(v))
    return bytes(c.b)


def fix(t, status=0):
    c = Cdr().header(t, "gps").put("b", status).put("H", 1)
    for v in (49.0, 8.4, 110.0, 4, 0, 0, 0, 4, 0, 0, 0, 9):
        c.put("d", float(v))
    return bytes(c.put("B", 2).b)


def twist(t, v):
    c = Cdr().header(t, "base_link")
    for x in (v, 0, 0, 0, 0, 0):
        c.put("d", float(x))
    return bytes(c.b)


def tf(t):
    c = Cdr().put("I", 1).header(t, "imu").string("cam")
    for v in (0, 0, 0, -0.5, 0.5, -0.5, 0.5):
        c.put("d", float(v))
    return bytes(c.b)


def record(role, cdr):
    return bytes([role]) + struct.pack("<H", len(cdr)) + cdr


def sample_seeds(out):
    car = b""
    for k in range(4):
        t = T0 + k * 100_000_000
        car += record(4, imu(t)) + record(6, twist(t, 3.0)) + record(5, fix(t, -1 if k == 2 else 0))
        car += record(0, image(t, "cam")) + record(1, image(t + 2_000_000, "cam_r"))
    with open(os.path.join(out, "car"), "wb") as f:
        f.write(car)
    with open(os.path.join(out, "backwards_and_cut"), "wb") as f:
        f.write(record(4, imu(T0 + 50)) + record(4, imu(T0)) + record(4, imu(T0 + 99)[:40]) + record(7, tf(T0)))
    with open(os.path.join(out, "wrong_size_image"), "wb") as f:
        f.write(record(0, image(T0, "cam", 12, 12)) + record(1, image(T0, "cam_r")))


def graph_seeds(out):
    for gid_bytes, name in ((16, "jazzy"), (24, "humble")):
        c = Cdr()
        c.b += bytes(range(16)) + bytes(gid_bytes - 16)
        c.put("I", 1).string("/").string("locaid_ros2")
        for n in (1, 2):
            c.put("I", n)
            for k in range(n):
                c.b += bytes([0xA0 + k] * 16) + bytes(gid_bytes - 16)
        with open(os.path.join(out, name), "wb") as f:
            f.write(bytes(c.b))


if __name__ == "__main__":
    os.makedirs(sys.argv[2], exist_ok=True)
    {"sample": sample_seeds, "graph": graph_seeds}[sys.argv[1]](sys.argv[2])
