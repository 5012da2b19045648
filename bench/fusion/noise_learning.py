#!/usr/bin/python3
"""What the learned noise does (EkfConfig::learn_vo_noise / learn_gps_noise):
locaid-replay over seeds 1..N of one drive and scenario, learned against the
fixed model (--fixed-vo-noise --fixed-gps-noise), per case:

  - VO's own 6-dof NEES under the noise the filter used (vo_error
    nees6_mean_model_gps_good / _in_outage; 6 when consistent)
  - rmse_gps_m, the fused 3-dof NEES from 30 s on against its 99 % bound
    (runs above it), end error % of every outage
  - the learned scales at the end (VO per axis, GPS horizontal / vertical)

  bench/fusion/noise_learning.py --drive DIR --scenario NAME_OR_YAML [--seeds 20] [--jobs 1] [--json]

VO runs once per drive (--vo-cache in --cache-dir). Progress goes to stderr;
exit status 0 even when a target is missed: this measures, it does not judge.
"""
import argparse
import concurrent.futures
import json
import os
import statistics
import subprocess
import sys
import tempfile

CASES = {"learned": [], "fixed": ["--fixed-vo-noise", "--fixed-gps-noise"]}


def replay(args, case, seed, cache):
    cmd = [args.replay, "--drive", args.drive, "--scenario", args.scenario, "--seed", str(seed),
           "--vo-cache", cache, "--json"] + CASES[case]
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"noise_learning: {' '.join(cmd)} failed:\n{out.stderr}")
    return json.loads(out.stdout)


def median(values):
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def summarise(runs):
    vo = [r["vo_error"] for r in runs]
    late = [(r["nees_mean_after_30s"], r["nees_bound_99_after_30s"]) for r in runs]
    ends = [o["end_error_pct"] for r in runs for o in r["outages"]]
    scales = [r["noise"] for r in runs]
    return {
        "runs": len(runs),
        "vo_nees_gps_good_median": median([v["nees6_mean_model_gps_good"] for v in vo]),
        "vo_nees_in_outage_median": median([v["nees6_mean_model_in_outage"] for v in vo]),
        "rmse_gps_m_median": median([r["rmse_gps_m"] for r in runs]),
        "nees_after_30s_median": median([n for n, _ in late]),
        "runs_above_bound_after_30s": sum(1 for n, b in late if n is not None and n > b),
        "end_error_pct_median": median(ends),
        "end_error_pct_max": max(ends) if ends else None,
        "vo_scale_median": [median([s["vo_scale"][i] for s in scales]) for i in range(6)],
        "gps_scale_median": [median([s["gps_scale_horizontal"] for s in scales]),
                             median([s["gps_scale_vertical"] for s in scales])],
    }


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--drive", required=True, help="drive folder (raw sync/extract or synthetic)")
    ap.add_argument("--scenario", required=True, help="built-in name or YAML")
    ap.add_argument("--seeds", type=int, default=20, help="seeds 1..N (default 20)")
    ap.add_argument("--replay", default=os.path.join(here, "..", "..", "build", "bin", "locaid-replay"))
    ap.add_argument("--cache-dir", default=tempfile.gettempdir(), help="where the VO cache goes")
    ap.add_argument("--jobs", type=int, default=1, help="parallel replays (default 1)")
    ap.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    args = ap.parse_args()
    if args.seeds < 1:
        ap.error("--seeds must be >= 1")
    if not os.path.isdir(args.drive):
        ap.error(f"--drive {args.drive}: no such folder")
    key = os.path.abspath(args.drive).replace("/", "_")
    cache = os.path.join(args.cache_dir, f"noise_learning{key}.vocache")
    replay(args, "learned", 1, cache)  # writes the VO cache once
    result = {}
    for case in CASES:
        with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            futures = [pool.submit(replay, args, case, s, cache) for s in range(1, args.seeds + 1)]
            runs = []
            for f in futures:
                runs.append(f.result())
                print(f"noise_learning: {case} {len(runs)}/{args.seeds}", file=sys.stderr)
        result[case] = summarise(runs)
    if args.json:
        print(json.dumps(result, indent=1))
        return
    for case, r in result.items():
        print(f"{case}: " + ", ".join(f"{k} {v}" for k, v in r.items()))


if __name__ == "__main__":
    main()
