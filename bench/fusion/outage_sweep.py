#!/usr/bin/python3
"""Seed sweep of locaid-replay: one filter figure over many GPS-noise seeds.

One seed is one draw of the GPS noise; on a short drive the end-of-outage
error depends on that draw as much as on the filter (the heading at the start
of the outage comes from a few seconds of noisy fixes). This runs
locaid-replay for seeds 1..N on each (scenario, IMU / no IMU) case, reusing one
VO run per drive through --vo-cache, and prints the median, 90th percentile
and maximum of rmse_gps_m and of every outage's end_error_pct.

  bench/fusion/outage_sweep.py --drive DIR --scenario tunnel-30s \
      [--scenario urban-canyon ...] [--seeds 10] [--no-imu-too] [--json]

Progress goes to stderr; with --json one object goes to stdout.
"""
import argparse
import hashlib
import json
import os
import statistics
import subprocess
import sys
import tempfile


def percentile(values, q):
    s = sorted(values)
    if not s:
        return float("nan")
    k = (len(s) - 1) * q
    lo, hi = int(k), min(int(k) + 1, len(s) - 1)
    return s[lo] + (s[hi] - s[lo]) * (k - lo)


def summary(values):
    return {"median": statistics.median(values), "p90": percentile(values, 0.9),
            "max": max(values), "values": values} if values else None


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--drive", required=True, help="drive folder (raw sync/extract or synthetic)")
    ap.add_argument("--scenario", action="append", required=True, help="built-in name or YAML (repeatable)")
    ap.add_argument("--seeds", type=int, default=10, help="seeds 1..N (default 10)")
    ap.add_argument("--no-imu-too", action="store_true", help="also run every case without IMU")
    ap.add_argument("--replay", default=os.path.join(here, "..", "..", "build", "bin", "locaid-replay"),
                    help="locaid-replay binary (default build/bin/locaid-replay)")
    ap.add_argument("--cache-dir", default=tempfile.gettempdir(), help="where the VO cache is kept")
    ap.add_argument("--ekf", action="append", default=[], help="NAME=VALUE passed to locaid-replay --ekf")
    ap.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    args = ap.parse_args()
    if args.seeds < 1:
        ap.error("--seeds must be >= 1")
    if not os.access(args.replay, os.X_OK):
        ap.error(f"{args.replay}: not an executable (build first, or pass --replay)")

    drive = os.path.realpath(args.drive)
    key = hashlib.sha1(drive.encode()).hexdigest()[:12]
    cache = os.path.join(args.cache_dir, f"locaid-vo-{key}.cache")
    extra = [a for e in args.ekf for a in ("--ekf", e)]
    cases = [(s, imu) for s in args.scenario for imu in ([True, False] if args.no_imu_too else [True])]
    result = {"drive": drive, "seeds": args.seeds, "ekf": args.ekf, "cases": []}
    for scenario, imu in cases:
        rmse, end_pct, reconv = [], [], []
        for seed in range(1, args.seeds + 1):
            cmd = [args.replay, "--drive", drive, "--scenario", scenario, "--json", "--seed", str(seed),
                   "--vo-cache", cache] + ([] if imu else ["--no-imu"]) + extra
            print(f"\r{scenario} {'IMU' if imu else 'no IMU'} seed {seed}/{args.seeds}   ",
                  end="", file=sys.stderr, flush=True)
            run = subprocess.run(cmd, capture_output=True, text=True)
            if run.returncode != 0:
                sys.exit(f"\n{' '.join(cmd)}\nfailed: {run.stderr.strip().splitlines()[-1:]}")
            j = json.loads(run.stdout)
            rmse.append(j["rmse_gps_m"])
            for o in j["outages"]:
                end_pct.append(o["end_error_pct"])
                reconv.append(o["reconverge_s"])
        result["cases"].append({"scenario": scenario, "use_imu": imu, "rmse_gps_m": summary(rmse),
                                "end_error_pct": summary(end_pct), "reconverge_s": summary(reconv)})
    print("", file=sys.stderr)
    if args.json:
        print(json.dumps(result, indent=2))
        return
    print(f"{drive}, seeds 1..{args.seeds}" + (f", --ekf {' '.join(args.ekf)}" if args.ekf else ""))
    print(f"{'scenario':<28} {'IMU':<4} {'rmse_gps_m med/p90/max':<26} {'end_error_pct med/p90/max':<28}")
    for c in result["cases"]:
        def fmt(s, f):
            return "-" if s is None else "/".join(f % s[k] for k in ("median", "p90", "max"))
        print(f"{c['scenario']:<28} {'yes' if c['use_imu'] else 'no':<4} "
              f"{fmt(c['rmse_gps_m'], '%.3f'):<26} {fmt(c['end_error_pct'], '%.2f'):<28}")


if __name__ == "__main__":
    main()
