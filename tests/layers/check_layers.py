#!/usr/bin/env python3
"""Fails when an #include runs from a lower module into a higher one.

The layers are the table of docs/architecture.md ("Module map"), repeated
here as LAYERS: a module's libraries may include their own module and the
modules of lower layers only. Programs (a module's apps/ folder, clients/)
may also use the output and connection libraries, never the server's or the
Foxglove bridge's, nor another folder of programs. tests/, bench/ and fuzz/
may include anything.

    check_layers.py [SOURCE_DIR]     exit 0: no back-include; 1: each one listed
    check_layers.py --self-test      plants back-includes in a scratch tree: must find each
"""
import pathlib
import re
import sys
import tempfile

# Layer of each library module (lower number = lower layer).
LAYERS = {
    "core": 0, "fusion": 0, "record": 0, "locaid": 0,  # "locaid/v1/...": the generated API (proto/)
    "kitti": 1, "ros": 1, "sim": 1, "vo": 1,  # ros/: ROS 2 messages and the camera model, no bags
    "bag": 2, "sensors": 2,
    "synth": 3, "eval": 3,
    "pipeline": 4,
    "output": 5, "connection": 5, "sweep": 5,
    "server": 6, "foxglove": 6, "ros2": 6,  # ros2/: ROS 2 topics over DDS (locaid-ros2)
}
PROGRAMS = 5.5   # apps/ folders and clients/: above output/ and connection/, below server/ and foxglove/
ANYTHING = 100   # tests/, bench/, fuzz/
LAYERS["clients"] = PROGRAMS
SCANNED = ["core", "fusion", "record", "kitti", "ros", "bag", "sim", "sensors", "synth", "eval", "vo", "pipeline",
           "output", "connection", "sweep", "server", "foxglove", "ros2", "clients", "tests", "bench", "fuzz"]
INCLUDE = re.compile(r'^\s*#\s*include\s+"(([a-z_0-9]+)/[^"]*)"')


def layer_of(rel: pathlib.PurePosixPath) -> float:
    if rel.parts[0] in ("tests", "bench", "fuzz"):
        return ANYTHING
    if rel.parts[0] == "clients" or "apps" in rel.parts:
        return max(PROGRAMS, LAYERS[rel.parts[0]])
    return LAYERS[rel.parts[0]]


def self_test() -> int:
    planted = {
        "kitti/reader.cpp": '#include "server/session.hpp"\n',        # library into a higher library
        "ros/camera.cpp": '#include "bag/ros_bag.hpp"\n',              # ROS messages into bag files
        "pipeline/apps/tool.cpp": '#include "foxglove/ws_server.hpp"\n',  # program into the bridge
        "server/x.cpp": '#include "clients/recorder.hpp"\n',         # into a folder of programs
    }
    clean = {"server/y.cpp": '#include "pipeline/frame_loop.hpp"\n#include <vector>\n',
             "tests/t.cpp": '#include "server/session.hpp"\n'}
    with tempfile.TemporaryDirectory(prefix="check_layers_") as tmp:
        for name, text in {**planted, **clean}.items():
            (pathlib.Path(tmp) / name).parent.mkdir(parents=True, exist_ok=True)
            (pathlib.Path(tmp) / name).write_text(text)
        found = check(pathlib.Path(tmp))
    missed = [name for name in planted if not any(p.startswith(name + ":") for p in found)]
    wrong = [p for p in found if not any(p.startswith(name + ":") for name in planted)]
    print(f"check_layers --self-test: {len(found)} found, missed {missed}, wrongly flagged {wrong}")
    return 0 if not missed and not wrong else 1


def main() -> int:
    if sys.argv[1:] == ["--self-test"]:
        return self_test()
    root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else pathlib.Path(__file__).resolve().parents[2])
    if not (root / "pipeline").is_dir():
        print(f"check_layers: {root} is not the source tree", file=sys.stderr)
        return 1
    problems = check(root)
    for p in problems:
        print(p)
    print(f"check_layers: {len(problems)} back-include(s)")
    return 1 if problems else 0


def check(root: pathlib.Path) -> list:
    problems, files = [], 0
    for top in SCANNED:
        for path in sorted((root / top).rglob("*")):
            if path.suffix not in (".cpp", ".hpp", ".h", ".cc") or not path.is_file():
                continue
            rel = pathlib.PurePosixPath(path.relative_to(root).as_posix())
            files += 1
            own = layer_of(rel)
            for n, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
                m = INCLUDE.match(line)
                if not m or m.group(2) not in LAYERS:
                    continue  # a system header, or a test's own helper
                target = m.group(2)
                if target == rel.parts[0] or own == ANYTHING:
                    continue  # own module; tests, benchmarks and fuzzers use any
                if target == "clients" or "/apps/" in m.group(1):
                    problems.append(f"{rel}:{n}: includes another folder's programs: {line.strip()}")
                elif LAYERS[target] >= own:
                    problems.append(f"{rel}:{n}: {rel.parts[0]}/ (layer {own}) includes {target}/ "
                                    f"(layer {LAYERS[target]}): {line.strip()}")
    return problems


if __name__ == "__main__":
    sys.exit(main())
