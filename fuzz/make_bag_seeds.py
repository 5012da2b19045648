#!/usr/bin/env python3
"""Seed inputs for fuzz_bag_reader: small MCAP files as rosbag2 writes them
(profile "ros2", CDR messages with a std_msgs/Header), with top-level
messages, an uncompressed chunk, a chunk with a bad CRC, and one cut short.
Only uncompressed chunks: the fuzzer reaches zstd and lz4 from the opcodes
and the "zstd" / "lz4" strings of the dictionary (fuzz/dicts/bag_reader.dict).

    fuzz/make_bag_seeds.py OUT_DIR
"""
import pathlib
import struct
import sys
import zlib

MAGIC = b"\x89MCAP0\r\n"


def record(op, content):
    return struct.pack("<BQ", op, len(content)) + content


def string(text):
    data = text.encode() if isinstance(text, str) else text
    return struct.pack("<I", len(data)) + data


def header(profile="ros2"):
    return record(0x01, string(profile) + string("make_bag_seeds"))


def schema(sid, name, text):
    return record(0x03, struct.pack("<H", sid) + string(name) + string("ros2msg") + string(text))


def channel(cid, sid, topic):
    entries = string("offered_qos_profiles") + string("- history: 3")
    return record(0x04, struct.pack("<HH", cid, sid) + string(topic) + string("cdr") + string(entries))


def message(cid, seq, t_ns, data):
    return record(0x05, struct.pack("<HIQQ", cid, seq, t_ns, t_ns) + data)


def chunk(records, crc=None):
    crc = zlib.crc32(records) if crc is None else crc
    return record(0x06, struct.pack("<QQQI", 0, 0, len(records), crc) + string("") +
                  struct.pack("<Q", len(records)) + records)


def data_end_and_footer():
    return record(0x0F, struct.pack("<I", 0)) + record(0x02, struct.pack("<QQI", 0, 0, 0)) + MAGIC


def cdr_imu(i):
    """Little-endian CDR: Header (stamp, frame_id), then float64 fields."""
    frame = b"imu_link\x00"
    body = struct.pack("<iI", 1700000000 + i, 1000 * i) + struct.pack("<I", len(frame)) + frame
    body += b"\x00" * ((8 - len(body) % 8) % 8)
    body += struct.pack("<4d", 0, 0, 0, 1) + struct.pack("<3d", 0.01 * i, 0, 9.81)
    return b"\x00\x01\x00\x00" + body


def cdr_odometry_be(i):
    """Big-endian CDR with a float64 sequence (count, then the values)."""
    frame = b"odom\x00"
    body = struct.pack(">iI", i, 0) + struct.pack(">I", len(frame)) + frame
    body += b"\x00" * ((4 - len(body) % 4) % 4) + struct.pack(">I", 3)
    body += b"\x00" * ((8 - len(body) % 8) % 8) + struct.pack(">3d", 1.0, 2.0, 3.0)
    return b"\x00\x00\x00\x00" + body


def main():
    out = pathlib.Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    declarations = (schema(1, "sensor_msgs/msg/Imu", "std_msgs/Header header\n") + channel(1, 1, "/imu") +
                    schema(2, "nav_msgs/msg/Odometry", "std_msgs/Header header\n") + channel(2, 2, "/odom"))
    messages = b"".join(message(1 + i % 2, i, 10**9 * i, cdr_imu(i) if i % 2 == 0 else cdr_odometry_be(i))
                        for i in range(4))

    top_level = MAGIC + header() + declarations + messages + data_end_and_footer()
    chunked = MAGIC + header() + chunk(declarations + messages) + data_end_and_footer()
    bad_crc = (MAGIC + header() + chunk(declarations + messages[:len(messages) // 2], crc=1) +
               chunk(declarations + messages) + data_end_and_footer())
    no_summary = MAGIC + header() + chunk(declarations + messages)
    cut = no_summary + chunk(messages)[:-7]
    for name, data in [("top_level", top_level), ("chunked", chunked), ("bad_crc", bad_crc),
                       ("no_summary", no_summary), ("cut", cut)]:
        (out / f"bag_{name}.mcap").write_bytes(data)


if __name__ == "__main__":
    main()
