#!/bin/sh
# Re-runs every deterministic figure of docs/benchmarks.md and compares it with
# the published value (bench/figures.tsv) at its printed digits; prints a table
# (figure, published, today, OK/DIFF) and exits 1 on any difference.
#
#   bench/figures.sh            every figure (renders the synthetic drives; ~1 h on 2 cores)
#   bench/figures.sh --fast     the real excerpt, devkit, simulator and MCAP figures (minutes;
#                               the test command runs it: ctest -L figures)
#   bench/figures.sh --help     all options (bench/figures.py)
#
# Exit status 77 (a CTest skip) when ../shared/data/kitti is absent.
exec /usr/bin/python3 "$(dirname "$0")/figures.py" "$@"
