#!/usr/bin/env python3
"""Writes the ROS camera_info YAML files of a KITTI raw recording's gray
cameras (image_00 left, image_01 right) from its calib_cam_to_cam.txt: what
`locaid session start --live --camera-info-left/-right` takes, so a KITTI
drive played through GStreamer (multifilesrc) stands in for a car's cameras.

    kitti_camera_info.py [--rectified] CALIB_CAM_TO_CAM OUT_DIR   -> OUT_DIR/left.yaml, OUT_DIR/right.yaml

Raw images (*_extract drives): K, D (plumb_bob), R_rect and P_rect of
cameras 00 and 01, image size S. --rectified, for drives whose images are
rectified already (*_sync, locaid-synth's): the rectified camera, K from
P_rect, no distortion, R the identity, size S_rect.
"""
import pathlib
import sys


def read_calib(path):
    values = {}
    for n, line in enumerate(pathlib.Path(path).read_text().splitlines(), 1):
        key, sep, rest = line.partition(":")
        if not sep:
            continue
        try:
            values[key.strip()] = [float(x) for x in rest.split()]
        except ValueError:
            if key.strip() != "calib_time":
                sys.exit(f"{path}:{n}: {key.strip()}: not a list of numbers")
    return values


def matrix(rows, cols, data):
    numbers = ", ".join(f"{x:.9g}" for x in data)
    return f"\n  rows: {rows}\n  cols: {cols}\n  data: [{numbers}]"


def camera_info(calib, cam, path, rectified):
    size = f"S_rect_{cam}" if rectified else f"S_{cam}"
    need = {size: 2, f"K_{cam}": 9, f"D_{cam}": 5, f"R_rect_{cam}": 9, f"P_rect_{cam}": 12}
    for key, count in need.items():
        if len(calib.get(key, [])) != count:
            sys.exit(f"{path}: {key}: expected {count} numbers, got {len(calib.get(key, []))}")
    width, height = (int(round(v)) for v in calib[size])
    p = calib[f"P_rect_{cam}"]
    k = p[0:3] + p[4:7] + p[8:11] if rectified else calib[f"K_{cam}"]
    d = [0.0] * 5 if rectified else calib[f"D_{cam}"]
    r = [1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0] if rectified else calib[f"R_rect_{cam}"]
    return (f"image_width: {width}\nimage_height: {height}\ncamera_name: kitti_cam{cam}\n"
            f"camera_matrix:{matrix(3, 3, k)}\n"
            f"distortion_model: plumb_bob\n"
            f"distortion_coefficients:{matrix(1, 5, d)}\n"
            f"rectification_matrix:{matrix(3, 3, r)}\n"
            f"projection_matrix:{matrix(3, 4, p)}\n")


def main():
    args = sys.argv[1:]
    rectified = "--rectified" in args
    args = [a for a in args if a != "--rectified"]
    if len(args) != 2:
        sys.exit(__doc__)
    calib = read_calib(args[0])
    out = pathlib.Path(args[1])
    out.mkdir(parents=True, exist_ok=True)
    for cam, name in (("00", "left.yaml"), ("01", "right.yaml")):
        (out / name).write_text(camera_info(calib, cam, args[0], rectified))
        print(out / name)


if __name__ == "__main__":
    main()
