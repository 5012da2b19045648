#!/usr/bin/python3
"""Forward filter against the smoother over many GPS-noise seeds.

  bench/fusion/smoother_seeds.py --drive DIR --scenario S --seeds 50 [--lag 2]
      [--cache-dir DIR] [--json OUT] [-- extra locaid-replay options]

Runs `locaid-replay --json --smooth` (or `--lag L`) once per seed, VO once
per drive (--vo-cache), and prints, per outage of the scenario, median / p90 /
max over the seeds of the error at the outage's end, the largest error inside
it and its RMSE, forward and smoothed, the ratios of the medians the issue
targets, the seeds on which the smoothed largest error is worse than the
forward's, and the RMSE while GPS is used.

It also prints the floor an outage's information sets ("end-pinned"): the
forward track through the outage mapped onto the truth by the one 2D
rotation, scale and shift that makes both of its ends exact (what a perfect
smoother knows at the ends, nothing more), from the forward run's per-frame
CSV; its RMSE and largest error inside the outage.
"""
import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
REPLAY = os.path.join(ROOT, "build", "bin", "locaid-replay")


def pct(values, q):
    v = sorted(values)
    if not v:
        return float("nan")
    k = (len(v) - 1) * q
    lo, hi = int(k), min(int(k) + 1, len(v) - 1)
    return v[lo] + (v[hi] - v[lo]) * (k - lo)


def end_pinned_floor(csv_path):
    """Per outage: (rmse, max) of the forward track mapped by the 2D similarity pinning both ends."""
    rows = list(csv.DictReader(open(csv_path)))
    out, i = [], 0
    while i < len(rows):
        if rows[i]["in_outage"] != "1":
            i += 1
            continue
        j = i
        while j + 1 < len(rows) and rows[j + 1]["in_outage"] == "1":
            j += 1
        a, b = max(i - 1, 0), j  # last frame with GPS before it, last frame of it
        est = [complex(float(r["est_e"]), float(r["est_n"])) for r in rows[a:b + 1]]
        gt = [complex(float(r["gt_e"]), float(r["gt_n"])) for r in rows[a:b + 1]]
        d = est[-1] - est[0]
        s = (gt[-1] - gt[0]) / d if abs(d) > 1e-9 else 1
        mapped = [gt[0] + s * (e - est[0]) for e in est]
        errs = [abs(m - g) for m, g in zip(mapped, gt)][1:]  # the outage's frames
        out.append(((sum(e * e for e in errs) / len(errs)) ** 0.5, max(errs)))
        i = j + 1
    return out


def run_seed(args, seed, cache, tmp, extra):
    smooth = ["--lag", str(args.lag)] if args.lag else ["--smooth"]
    base = [REPLAY, "--drive", args.drive, "--scenario", args.scenario, "--seed", str(seed), "--vo-cache", cache,
            "--json"] + extra
    res = subprocess.run(base + smooth, capture_output=True, text=True)
    if res.returncode != 0:
        sys.exit(f"seed {seed}: locaid-replay failed:\n{res.stderr[-2000:]}")
    j = json.loads(res.stdout)
    floor = []
    if not args.no_floor:
        fwd_csv = os.path.join(tmp, f"fwd{seed}.csv")
        subprocess.run(base + ["--out-csv", fwd_csv], capture_output=True, text=True, check=True)
        floor = end_pinned_floor(fwd_csv)
        os.remove(fwd_csv)
    return j, floor


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--drive", required=True)
    p.add_argument("--scenario", required=True)
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument("--first-seed", type=int, default=1)
    p.add_argument("--lag", type=float, default=0, help="fixed lag in s instead of the whole drive")
    p.add_argument("--cache-dir", default=None, help="where the VO cache goes (default: a temporary folder)")
    p.add_argument("--no-floor", action="store_true", help="skip the end-pinned floor (one replay less per seed)")
    p.add_argument("--json", default=None, help="write every seed's figures here")
    args, extra = p.parse_known_args()
    extra = [e for e in extra if e != "--"]
    with tempfile.TemporaryDirectory() as tmp:
        cache = os.path.join(args.cache_dir or tmp, "vo.cache")
        seeds = []
        for k in range(args.seeds):
            seed = args.first_seed + k
            j, floor = run_seed(args, seed, cache, tmp, extra)
            seeds.append({"seed": seed, "forward": {"rmse_gps_m": j["rmse_gps_m"], "nees_mean": j["nees_mean"],
                                                    "outages": j["outages"]},
                          "smoothed": j["smoothed"], "floor": floor})
            print(f"\rseed {seed} ({k + 1}/{args.seeds})", end="", file=sys.stderr, flush=True)
        print(file=sys.stderr)
    if args.json:
        json.dump(seeds, open(args.json, "w"), indent=1)
    report(args, seeds)


def line(name, f, s):
    print(f"  {name:34s} forward {pct(f, .5):7.3f} / {pct(f, .9):7.3f} / {max(f):7.3f}   "
          f"smoothed {pct(s, .5):7.3f} / {pct(s, .9):7.3f} / {max(s):7.3f}")


def report(args, seeds):
    what = f"fixed lag {args.lag} s" if args.lag else "offline"
    print(f"{args.drive}  scenario {args.scenario}  {len(seeds)} seeds  smoother: {what}")
    print("  (median / p90 / max over seeds)")
    line("RMSE while GPS used, m", [s["forward"]["rmse_gps_m"] for s in seeds],
         [s["smoothed"]["rmse_gps_m"] for s in seeds])
    line("NEES mean", [s["forward"]["nees_mean"] for s in seeds], [s["smoothed"]["nees_mean"] for s in seeds])
    f_rmse = statistics.median(s["forward"]["rmse_gps_m"] for s in seeds)
    s_rmse = statistics.median(s["smoothed"]["rmse_gps_m"] for s in seeds)
    print(f"  RMSE while GPS used: smoothed / forward (medians) {s_rmse / f_rmse:.2f}")
    for k in range(len(seeds[0]["forward"]["outages"])):
        fo = [s["forward"]["outages"][k] for s in seeds]
        so = [s["smoothed"]["outages"][k] for s in seeds]
        print(f"  outage {k + 1}: {fo[0]['duration_s']:.1f} s from {fo[0]['start_s']:.1f} s, "
              f"{statistics.median(o['distance_m'] for o in fo):.0f} m")
        for key, name in (("end_error_m", "error at its end, m"), ("end_error_pct", "error at its end, %"),
                          ("max_error_m", "largest error inside, m"), ("rmse_m", "RMSE over its frames, m")):
            line(name, [o[key] for o in fo], [o[key] for o in so])
        med = lambda xs, key: statistics.median(o[key] for o in xs)  # noqa: E731
        print(f"    smoothed max inside / forward end error (medians): "
              f"{med(so, 'max_error_m') / med(fo, 'end_error_m'):.2f}")
        print(f"    smoothed end error / forward end error (medians): "
              f"{med(so, 'end_error_m') / med(fo, 'end_error_m'):.2f}")
        print(f"    smoothed RMSE inside / forward RMSE inside (medians): {med(so, 'rmse_m') / med(fo, 'rmse_m'):.2f}")
        worse = [s["seed"] for s, f, m in zip(seeds, fo, so) if m["max_error_m"] > f["max_error_m"]]
        print(f"    seeds where the smoothed largest error inside is worse than the forward's: "
              f"{len(worse)} {worse[:10]}")
        floors = [s["floor"][k] for s in seeds if len(s["floor"]) > k]
        if floors:
            print(f"    end-pinned floor (medians): RMSE inside {statistics.median(f[0] for f in floors):.3f} m, "
                  f"largest error {statistics.median(f[1] for f in floors):.3f} m")


if __name__ == "__main__":
    main()
