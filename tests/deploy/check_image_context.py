#!/usr/bin/env python3
"""Fails when the container image could not build from its build context.

deploy/Containerfile copies the source tree less what .containerignore drops.
This check makes that context as podman or docker would send it (the ignore
file's patterns with their rules: `*`, `?`, `**`, `!` exceptions, the last
matching pattern wins, a dropped folder drops everything under it), then:

  1. every file a `COPY` of the Containerfile names from the context is in it;
  2. the build stage's source folder is put together from the context by the
     Containerfile's own `COPY ... /src...` lines, and CMake configures it
     with the stage's exact -D options: a module folder the top-level
     CMakeLists.txt adds that the ignore file or the COPY lines leave out
     stops here, as it would in the image build;
  3. .dockerignore is the same file as .containerignore (docker reads one,
     podman the other).

    check_image_context.py SOURCE_DIR     exit 0: the image's build stage configures
    check_image_context.py --self-test    drops a module from a scratch copy's context: must fail
"""
import os
import pathlib
import re
import shlex
import shutil
import subprocess
import sys
import tempfile


def ignore_rules(text: str) -> list[tuple[bool, re.Pattern]]:
    """(is_exception, regex) per pattern line, in file order."""
    rules = []
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        exception = line.startswith("!")
        pattern = os.path.normpath(line.lstrip("!").strip()).lstrip("/")
        regex, i = "", 0
        while i < len(pattern):
            if pattern.startswith("**/", i):
                regex += "(?:.*/)?"
                i += 3
            elif pattern.startswith("**", i):
                regex += ".*"
                i += 2
            elif pattern[i] == "*":
                regex += "[^/]*"
                i += 1
            elif pattern[i] == "?":
                regex += "[^/]"
                i += 1
            else:
                regex += re.escape(pattern[i])
                i += 1
        rules.append((exception, re.compile(regex + r"\Z")))
    return rules


def ignored(rel: str, rules) -> bool:
    """Whether a context path is left out: the last rule matching it or one of its folders wins."""
    parts = rel.split("/")
    prefixes = ["/".join(parts[: n + 1]) for n in range(len(parts))]
    verdict = False
    for exception, regex in rules:
        if any(regex.match(p) for p in prefixes):
            verdict = not exception
    return verdict


def make_context(src: pathlib.Path, dst: pathlib.Path) -> int:
    rules = ignore_rules((src / ".containerignore").read_text())
    count = 0
    for root, dirs, files in os.walk(src):
        rel_root = pathlib.Path(root).relative_to(src).as_posix()
        rel_of = (lambda n: n) if rel_root == "." else (lambda n: f"{rel_root}/{n}")
        dirs[:] = [d for d in dirs if not ignored(rel_of(d), rules)]
        for f in files:
            rel = rel_of(f)
            if ignored(rel, rules):
                continue
            out = dst / rel
            out.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(pathlib.Path(root) / f, out, follow_symlinks=True)
            count += 1
    return count


def containerfile_facts(text: str) -> tuple[list[tuple[list[str], str]], list[str]]:
    """(COPY lines from the context as (sources, destination), -D options of the build stage's cmake)."""
    joined = re.sub(r"\\\n", " ", text)
    copies, options = [], []
    for line in joined.splitlines():
        words = shlex.split(line, comments=False) if line.strip() and not line.lstrip().startswith("#") else []
        if words and words[0] == "COPY" and not any(w.startswith("--from") for w in words):
            copies.append(([w for w in words[1:-1] if not w.startswith("--")], words[-1]))
        if "cmake -S /src" in line:
            options = [w for w in shlex.split(line) if w.startswith("-D") and "COMPILER_LAUNCHER" not in w]
    return copies, options


def copy_into(ctx: pathlib.Path, sources: list[str], dest: str, root: pathlib.Path) -> None:
    """One COPY's effect under root (the image's /): a folder's contents, or files, as docker copies them."""
    target = root / dest.lstrip("/")
    for s in sources:
        item = ctx / s
        if item.is_dir():
            shutil.copytree(item, target, dirs_exist_ok=True)
        else:
            into = target / item.name if dest.endswith("/") or len(sources) > 1 else target
            into.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(item, into)


def check(src: pathlib.Path) -> list[str]:
    problems = []
    if (src / ".dockerignore").read_text() != (src / ".containerignore").read_text():
        problems.append(".dockerignore differs from .containerignore: docker and podman would send different contexts")
    copies, options = containerfile_facts((src / "deploy/Containerfile").read_text())
    if not options:
        problems.append("deploy/Containerfile: no `cmake -S /src` line found to configure like")
    with tempfile.TemporaryDirectory(prefix="locaid-image-context-") as tmp:
        ctx, image, build = (pathlib.Path(tmp) / d for d in ("context", "image", "build"))
        n = make_context(src, ctx)
        print(f"context: {n} files from {src}")
        for sources, dest in copies:
            missing = [s for s in sources if not (ctx / s).exists()]
            for s in missing:
                problems.append(f"deploy/Containerfile copies '{s}', which is not in the build context")
            if dest.startswith("/src") and not missing:
                copy_into(ctx, sources, dest, image)
        cmd = ["cmake", "-S", str(image / "src"), "-B", str(build), "-G", "Ninja" if shutil.which("ninja") else "Unix Makefiles",
               *options]
        print("configure:", " ".join(cmd[:1] + cmd[5:]))
        run = subprocess.run(cmd, capture_output=True, text=True)
        if run.returncode != 0:
            errors = [l for l in (run.stderr + run.stdout).splitlines() if "rror" in l or "not an existing" in l]
            problems.append("CMake cannot configure the image's build context:\n    " +
                            "\n    ".join(errors[:12] or (run.stderr.splitlines()[-12:])))
    return problems


def self_test() -> int:
    src = pathlib.Path(__file__).resolve().parents[2]
    with tempfile.TemporaryDirectory(prefix="locaid-image-context-self-") as tmp:
        scratch = pathlib.Path(tmp) / "src"
        keep = {"CMakeLists.txt", ".containerignore", ".dockerignore"}
        shutil.copytree(src, scratch, ignore=lambda d, names: [
            n for n in names if pathlib.Path(d) == src and n not in keep and
            (n.startswith(".") or n.startswith("build") or n in ("docs", "tests", "bench", "fuzz"))])
        for name in (".containerignore", ".dockerignore"):  # the image forgets the bag module
            with open(scratch / name, "a") as f:
                f.write("bag\n")
        found = check(scratch)
        if not any("not an existing directory" in p or "bag" in p for p in found):
            print("self-test: a context without bag/ was not refused:", found)
            return 1
        (scratch / ".dockerignore").write_text("")
        if not any(".dockerignore differs" in p for p in check(scratch)):
            print("self-test: differing ignore files were not found")
            return 1
    # pattern rules as podman applies them
    rules = ignore_rules("build\n**/__pycache__\ndocs\n!docs/keep.md\nbuild-*\n")
    cases = {"build/x.o": True, "builder/x": False, "a/b/__pycache__/m.pyc": True, "docs/api.md": True,
             "docs/keep.md": False, "build-asan/y": True, "pipeline/build.cpp": False}
    bad = {p: v for p, v in cases.items() if ignored(p, rules) != v}
    if bad:
        print("self-test: ignore rules wrong for", bad)
        return 1
    print("self-test: a missing module and differing ignore files are refused; pattern rules hold")
    return 0


def main() -> int:
    if sys.argv[1:] == ["--self-test"]:
        return self_test()
    src = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else ".").resolve()
    problems = check(src)
    for p in problems:
        print("FAIL:", p)
    if not problems:
        print("the image's build stage configures from its context")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
