#!/usr/bin/env python3
"""Seed inputs for fuzz_push_requests: PushSensorData streams (most begin after
'start'; "live_start" begins with one) as length-delimited locaid.v1.PushRequest messages, written from text format
with `protoc --encode`, so they follow proto/locaid/v1/localization.proto as
it is today.

    fuzz/make_push_seeds.py OUT_DIR [REPO]
"""
import pathlib
import subprocess
import sys

OXTS = ("49.015 8.43 116.4 0.03 0.01 1.2 -2.1 9.5 9.7 0.1 -0.05 0.2 0.1 9.8 0.2 0.1 9.8 0.001 0.002 "
        "0.01 0.001 0.002 0.01 0.5 0.1 4 10 5 5 5")
SIDE = 16  # the fuzz target's camera: 16x16 px


def gray8(seed):
    return bytes((x * 7 + y * 3 + seed) % 256 for y in range(SIDE) for x in range(SIDE))


def text_bytes(data):
    return '"' + "".join("\\%03o" % b for b in data) + '"'


def imu(t_ns, az=9.81, wz=0.01, extra=""):
    return f"imu {{ t_ns: {t_ns} accel_mps2 {{ x: 0.2 y: -0.1 z: {az} }} gyro_radps {{ z: {wz} }} {extra} }}"


def gps(t_ns, extra="fix_type: GPS_FIX_3D sigma_horizontal_m: 2.5 sigma_vertical_m: 4", lat=49.015):
    return f"gps {{ t_ns: {t_ns} latitude_deg: {lat} longitude_deg: 8.43 altitude_m: 116.4 {extra} }}"


def frame(t_ns, seed=0):
    return (f"frame {{ t_ns: {t_ns} encoding: IMAGE_ENCODING_GRAY8 left: {text_bytes(gray8(seed))} "
            f"right: {text_bytes(gray8(seed + 1))} }}")


def oxts(t_ns):
    return f'oxts {{ t_ns: {t_ns} line: "{OXTS}" }}'


MS = 1_000_000
SEEDS = {
    # A car pushing everything: 100 Hz IMU, 10 Hz frames, GPS, OXTS.
    "drive": [imu(i * 10 * MS) for i in range(5)] + [gps(40 * MS), frame(50 * MS), oxts(50 * MS)]
             + [imu(i * 10 * MS) for i in range(6, 11)] + [frame(100 * MS, 2), gps(100 * MS)],
    "imu_only": [imu(i * 5 * MS, extra="accel_noise_mps2_sqrt_hz: 0.02 gyro_noise_radps_sqrt_hz: 0.0005")
                 for i in range(4)],
    "gps_kinds": [
        gps(1 * MS, "fix_type: GPS_FIX_2D sigma_horizontal_m: 3"),
        gps(2 * MS, "fix_type: GPS_FIX_NONE"),
        gps(3 * MS, "fix_type: GPS_FIX_RTK_FIXED covariance_enu_m2: [0.04, 0.01, 0, 0.01, 0.04, 0, 0, 0, 0.09]"),
        gps(4 * MS, "has_velocity: true velocity_enu_mps { x: 10 y: 1 } sigma_velocity_mps: 0.2"),
        gps(5 * MS, "covariance_enu_m2: [nan, 0, 0, 0, nan, 0, 0, 0, nan]"),
    ],
    # Items the server refuses (the stream goes on) or drops as out of order.
    "refused": [
        imu(10 * MS, az="nan"), imu(20 * MS, az=3000), imu(30 * MS, wz=200),
        imu(40 * MS, extra="accel_noise_mps2_sqrt_hz: -1"),
        gps(10 * MS, "", lat=91), gps(11 * MS, "fix_type: 99"),
        gps(12 * MS, "covariance_enu_m2: [1, 2, 3]"),
        gps(13 * MS, "covariance_enu_m2: [1, 5, 0, -5, 1, 0, 0, 0, 1]"),
        gps(14 * MS, "sigma_horizontal_m: inf"),
        imu(5 * MS), gps(9 * MS), "start { }", "",
    ],
    # A stream that starts its own live session with every LiveSource field.
    "live_start": [
        "start { live { fx: 20 fy: 20 cx: 7.5 cy: 7.5 baseline_m: 0.5 width: 16 height: 16 "
        "T_cam0_imu: [0, -1, 0, 0.1, 0, 0, -1, -0.2, 1, 0, 0, -1.1] max_gps_delay_s: 2 "
        "gps_antenna_body_m: [0.5, 0, 1.2] speed_sensor { rate_hz: 50 sigma_mps: 0.1 scale_factor_sigma: 0.02 } "
        'gps_source { gpsd { host: "127.0.0.1" port: 2947 } } } }',
        imu(1 * MS), gps(2 * MS), frame(3 * MS), imu(4 * MS), gps(5 * MS)],
    "frames": [frame(0), frame(0, 1), frame(-5 * MS, 2), frame(20 * MS, 3),
               f'frame {{ t_ns: {30 * MS} encoding: IMAGE_ENCODING_PNG left: "\\211PNG" right: "x" }}'],
}


def encode(repo, text):
    proto_dir = repo / "proto"
    return subprocess.run(
        ["protoc", "--encode=locaid.v1.PushRequest", f"-I{proto_dir}",
         str(proto_dir / "locaid/v1/localization.proto")],
        input=text.encode(), stdout=subprocess.PIPE, check=True).stdout


def varint(n):
    out = bytearray()
    while True:
        b = n & 0x7F
        n >>= 7
        out.append(b | (0x80 if n else 0))
        if not n:
            return bytes(out)


def main():
    out_dir = pathlib.Path(sys.argv[1])
    repo = pathlib.Path(sys.argv[2] if len(sys.argv) > 2 else pathlib.Path(__file__).resolve().parent.parent)
    out_dir.mkdir(parents=True, exist_ok=True)
    for name, messages in SEEDS.items():
        stream = b""
        for text in messages:
            body = encode(repo, text)
            stream += varint(len(body)) + body
        (out_dir / name).write_bytes(stream)


if __name__ == "__main__":
    main()
