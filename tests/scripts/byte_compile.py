#!/usr/bin/env python3
"""Byte-compiles every Python script of bench/, clients/ and sweep/ (recursively).

The test command builds every C++ program under bench/; the Python scripts
there (and the clients') are only run by hand or by some tests, so a syntax
error in one would go unnoticed. This compiles each with py_compile into a
temporary folder (nothing is written into the source tree) and fails on the
first error it reports, or when no script is found at all.

    byte_compile.py REPO_ROOT
"""
import glob
import os
import py_compile
import sys
import tempfile

FOLDERS = ("bench", "clients", "sweep")


def main() -> int:
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    root = sys.argv[1]
    scripts = sorted(
        path
        for folder in FOLDERS
        for path in glob.glob(os.path.join(root, folder, "**", "*.py"), recursive=True)
        if "node_modules" not in path.split(os.sep)
    )
    if not scripts:
        print(f"byte_compile: no *.py under {', '.join(FOLDERS)} of {root}", file=sys.stderr)
        return 1
    failed = 0
    with tempfile.TemporaryDirectory(prefix="locaid-pycompile-") as out:
        for i, path in enumerate(scripts):
            try:
                py_compile.compile(path, cfile=os.path.join(out, f"{i}.pyc"), doraise=True)
                print(f"ok      {os.path.relpath(path, root)}")
            except py_compile.PyCompileError as e:
                failed += 1
                print(f"FAILED  {os.path.relpath(path, root)}\n{e.msg}", file=sys.stderr)
    print(f"byte_compile: {len(scripts) - failed} of {len(scripts)} scripts compile")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
