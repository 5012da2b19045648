#!/usr/bin/env python3
"""Fails when an #include runs from a lower module into a higher one, when
folders include each other in a cycle, or when a folder of code is missing
from the table.

The layers are the table of docs/architecture.md ("Module map"), repeated
here as LAYERS: a module's libraries may include their own module and the
modules of lower layers only. Programs (a module's apps/ folder, and the
folders that hold programs only: clients/, replay/) may also use the output
and connection libraries, never the server's or the Foxglove bridge's, nor
another folder of programs. tests/, bench/ and fuzz/ may include anything.

Folders, programs included, must not use each other: a folder whose
programs include output/ while output/ includes that folder is a cycle,
though each include alone is allowed (the check names the folders and one
include per step).

Every top-level folder that holds C++ sources is in LAYERS (or is tests/,
bench/, fuzz/): a new module enters the table with its first code.

    check_layers.py [SOURCE_DIR]     exit 0: none of these; 1: each one listed
    check_layers.py --self-test      plants each kind in a scratch tree: must find each, and nothing else
"""
import pathlib
import re
import sys
import tempfile

# Layer of each library module (lower number = lower layer).
LAYERS = {
    "core": 0, "fusion": 0, "record": 0, "proto": 0,  # proto/: the generated API, included as "locaid/v1/..."
    "kitti": 1, "ros": 1, "sim": 1, "vo": 1,  # ros/: ROS 2 messages and the camera model, no bags
    "bag": 2, "sensors": 2,
    "synth": 3, "eval": 3,
    "pipeline": 4,
    "output": 5, "connection": 5, "sweep": 5,
    "server": 6, "foxglove": 6, "ros2": 6,  # ros2/: live ROS 2 topics over DDS (uses output/, connection/)
}
PROGRAMS = 5.5   # apps/ folders and the folders of programs: above output/ and connection/, below server/ and foxglove/
PROGRAM_FOLDERS = ("clients", "replay")  # programs only, no library
ANYTHING = 100   # tests/, bench/, fuzz/
ANY_FOLDERS = ("tests", "bench", "fuzz")
for folder in PROGRAM_FOLDERS:
    LAYERS[folder] = PROGRAMS
INCLUDE_ROOTS = {"locaid": "proto"}  # an include's first path part -> its folder, where they differ
SOURCES = (".cpp", ".hpp", ".h", ".cc")
INCLUDE = re.compile(r'^\s*#\s*include\s+"(([a-z_0-9]+)/[^"]*)"')


def layer_of(rel: pathlib.PurePosixPath) -> float:
    if rel.parts[0] in ANY_FOLDERS:
        return ANYTHING
    if rel.parts[0] in PROGRAM_FOLDERS or "apps" in rel.parts:
        return max(PROGRAMS, LAYERS[rel.parts[0]])
    return LAYERS[rel.parts[0]]


def sources(folder: pathlib.Path):
    return (p for p in sorted(folder.rglob("*")) if p.suffix in SOURCES and p.is_file())


def check(root: pathlib.Path) -> list:
    problems = []
    edges = {}  # folder -> {folder it includes: the first such include, "file:line"}
    for top in sorted(p.name for p in root.iterdir() if p.is_dir() and not p.name.startswith(".")):
        if (root / top / "CMakeCache.txt").exists():
            continue  # a build folder
        if top not in LAYERS and top not in ANY_FOLDERS:
            if any(True for _ in sources(root / top)):
                problems.append(f"{top}/: holds C++ sources but is not in the LAYERS table (check_layers.py, "
                                f"docs/architecture.md 'Module map')")
            continue
        for path in sources(root / top):
            rel = pathlib.PurePosixPath(path.relative_to(root).as_posix())
            own = layer_of(rel)
            for n, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
                m = INCLUDE.match(line)
                if not m:
                    continue
                target = INCLUDE_ROOTS.get(m.group(2), m.group(2))
                if target not in LAYERS or target == top or own == ANYTHING:
                    continue  # a system header or a test's own helper; own module; tests, benchmarks, fuzzers
                edges.setdefault(top, {}).setdefault(target, f"{rel}:{n}")
                if target in PROGRAM_FOLDERS or "/apps/" in m.group(1):
                    problems.append(f"{rel}:{n}: includes another folder's programs: {line.strip()}")
                elif LAYERS[target] >= own:
                    problems.append(f"{rel}:{n}: {top}/ (layer {own}) includes {target}/ "
                                    f"(layer {LAYERS[target]}): {line.strip()}")
    return problems + folder_cycles(edges)


def folder_cycles(edges: dict) -> list:
    """One line per cycle of folders: the folders in order and the include of each step."""
    found, seen = [], set()
    for start in sorted(edges):
        # Shortest way back to `start` (breadth first), so each cycle is named by its fewest folders.
        paths, queue = {start: [start]}, [start]
        cycle = None
        while queue and not cycle:
            here = queue.pop(0)
            for nxt in sorted(edges.get(here, {})):
                if nxt == start:
                    cycle = paths[here] + [start]
                    break
                if nxt not in paths:
                    paths[nxt] = paths[here] + [nxt]
                    queue.append(nxt)
        if not cycle or frozenset(cycle) in seen:
            continue
        seen.add(frozenset(cycle))
        steps = "; ".join(f"{edges[a][b]} includes {b}/" for a, b in zip(cycle, cycle[1:]))
        found.append(f"folder cycle: {' -> '.join(f + '/' for f in cycle)} ({steps})")
    return found


def self_test() -> int:
    planted = {
        "kitti/reader.cpp": '#include "server/session.hpp"\n',        # library into a higher library
        "ros/camera.cpp": '#include "bag/ros_bag.hpp"\n',              # ROS messages into bag files
        "pipeline/apps/tool.cpp": '#include "foxglove/ws_server.hpp"\n',  # program into the bridge
        "server/x.cpp": '#include "clients/recorder.hpp"\n',         # into a folder of programs
        "newmodule/thing.cpp": "int x;\n",                           # a folder of code the table lacks
    }
    # Each include alone is allowed (programs use output/, output/ is above
    # sim/); together the two folders use each other.
    cycle = {"sim/apps/tool.cpp": '#include "output/channels.hpp"\n',
             "output/pose.cpp": '#include "sim/scenario.hpp"\n'}
    clean = {"server/y.cpp": '#include "pipeline/frame_loop.hpp"\n#include <vector>\n',
             "server/z.cpp": '#include "locaid/v1/localization.pb.h"\n',
             "tests/t.cpp": '#include "server/session.hpp"\n',
             "docs/notes.md": "no code\n"}
    with tempfile.TemporaryDirectory(prefix="check_layers_") as tmp:
        for name, text in {**planted, **cycle, **clean}.items():
            (pathlib.Path(tmp) / name).parent.mkdir(parents=True, exist_ok=True)
            (pathlib.Path(tmp) / name).write_text(text)
        found = check(pathlib.Path(tmp))
    flagged = lambda name: any(p.startswith(name + ":") or p.startswith(name.split("/")[0] + "/:") for p in found)
    missed = [name for name in planted if not flagged(name)]
    cycles = [p for p in found if p.startswith("folder cycle:")]
    if not any(all(f + ":1 includes" in p for f in cycle) for p in cycles):
        missed.append("the cycle output/ <-> sim/")
    wrong = [p for p in found if p not in cycles and not any(
        p.startswith(name + ":") or p.startswith(name.split("/")[0] + "/:") for name in planted)]
    wrong += [p for p in cycles if not all(f + ":1 includes" in p for f in cycle)]
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
    print(f"check_layers: {len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
