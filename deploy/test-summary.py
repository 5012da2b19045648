#!/usr/bin/python3
"""Summary of a CTest run from its JUnit file (ctest --output-junit).

    deploy/test-summary.py build/ctest-junit.xml

Prints the counts (passed, failed, skipped) and every skipped test by name
with the reason it gave (GoogleTest's GTEST_SKIP message, else CTest's), and
every test that failed or did not run. deploy/test.sh calls it after CTest.
Exit status 0 whatever the results (CTest's own status is what fails a run).
"""
import sys
import xml.etree.ElementTree as ET


def skip_reason(case, skipped):
    """The GTEST_SKIP message (the lines after 'file:line: Skipped'), else CTest's."""
    out = case.findtext("system-out") or ""
    lines = out.splitlines()
    for i, line in enumerate(lines):
        if line.rstrip().endswith(": Skipped"):
            reason = []
            for follow in lines[i + 1:]:
                if follow.startswith("[  SKIPPED ]"):
                    break
                if follow.strip():
                    reason.append(follow.strip())
            if reason:
                return " ".join(reason)
    for line in lines:  # a script that printed its own reason
        if "skip" in line.lower():
            return line.strip()
    return skipped.get("message", "") or "(no reason given)"


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    try:
        root = ET.parse(sys.argv[1]).getroot()
    except (OSError, ET.ParseError) as e:
        print(f"test-summary: cannot read {sys.argv[1]}: {e}")
        return
    passed, failed, skipped = [], [], []
    for case in root.iter("testcase"):
        name = case.get("name", "?")
        skip = case.find("skipped")
        if case.find("failure") is not None or case.get("status") == "fail":
            failed.append((name, "failed"))
        elif skip is not None and skip.get("message") == "Fixture dependency failed":
            failed.append((name, "not run: " + (case.findtext("system-out") or "fixture failed").strip()))
        elif skip is not None or case.get("status") == "notrun":
            skipped.append((name, skip_reason(case, skip if skip is not None else {})))
        else:
            passed.append(name)
    total = len(passed) + len(failed) + len(skipped)
    print(f"test-summary: {total} tests: {len(passed)} passed, {len(failed)} failed or not run, "
          f"{len(skipped)} skipped")
    if skipped:
        print(f"test-summary: {len(skipped)} skipped, and why:")
        for name, reason in skipped:
            print(f"  {name}: {reason}")
    if failed:
        print(f"test-summary: {len(failed)} failed or not run:")
        for name, what in failed:
            print(f"  {name}: {what}")


if __name__ == "__main__":
    main()
