#!/usr/bin/python3
"""Seed sweep of one drive: filter accuracy AND consistency over many GPS-noise seeds.

One seed is one draw of the GPS noise; on a short drive the end-of-outage
error depends on that draw as much as on the filter. The runs are
`locaid-sweep`'s (docs/sweeps.md): this writes a manifest of the drive, the
scenarios, seeds 1..N and IMU on (and off with --no-imu-too), runs
`locaid-sweep run` (one VO run per drive through its VO cache, resumable in
--out), then reads every run's `locaid-replay --json` from the sweep folder
and reports per case the figures the sweep's own summary does not:

  - rmse_gps_m, end_error_pct (every outage), added_error_pct (what the
    outage added to the error it started with), reconverge_s: median / p90 / max
    (reconverge_s: time from the outage's end to the first frame within
    2 sigma_h of the truth; outages that never get there are counted apart)
  - NEES: per-run mean 3-dof position NEES against the run's own 99 %
    chi-square bound (chi2_0.99(3n)/n over its n frames); runs above it
  - max vertical error of every run (worst run)
  - GPS gate: fixes rejected (horizontal part / vertical part) over all fixes
    fused or rejected, against the gate's nominal false-alarm rate; the longest
    run of consecutive rejections; position resets to GPS
  - VO updates rejected by the filter's VO gate

  bench/fusion/outage_sweep.py --drive DIR --scenario scenarios/outage-10s-middle.yaml \\
      [--scenario urban-canyon ...] [--seeds 50] [--no-imu-too] [--jobs 2] [--json] [--runs-csv F] \\
      [--out SWEEP_DIR] [--replay-arg=ARG ...]

Without --out the sweep folder is a temporary one, removed at the end; with
it, a second call does only what is missing (locaid-sweep's keys). Speed
sensors (`speed:`) and camera faults come from the scenario file; --ekf,
--vehicle-constraints and --replay-arg pass through to every run.

Progress goes to stderr; with --json one object goes to stdout. Exit status 0
even when a target is missed: this measures, it does not judge.
"""
import argparse
import glob
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile

GATE_PROBABILITY = 0.999  # EkfConfig gps.gate_probability (each of the two gates)


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


class ReplayFailed(Exception):
    pass


def run_sweep(sweep, drive, scenarios, seeds, imus, extra, jobs, out):
    """locaid-sweep run over the cases; returns {(scenario, imu, seed): replay JSON}."""
    manifest = os.path.join(out, "manifest.yaml")
    os.makedirs(out, exist_ok=True)
    with open(manifest, "w") as f:
        f.write("recordings:\n  - path: %s\n" % json.dumps(drive))
        f.write("scenarios: %s\n" % json.dumps(scenarios))
        f.write("seeds: {from: 1, to: %d}\n" % seeds)
        f.write("imu: %s\n" % json.dumps(["on" if i else "off" for i in imus]))
        f.write("replay_args: %s\n" % json.dumps(extra))
    # Its output is progress for a person: stderr, so that --json keeps stdout to itself.
    run = subprocess.run([sweep, "run", manifest, "--out", os.path.join(out, "sweep"), "--jobs", str(jobs)],
                         stdout=sys.stderr)
    if run.returncode not in (0, 1):
        raise ReplayFailed(f"locaid-sweep run exited with {run.returncode}")
    runs, failed = {}, []
    for path in glob.glob(os.path.join(out, "sweep", "runs", "*.json")):
        with open(path) as f:
            r = json.load(f)
        if r.get("stage") != "filter":
            continue
        if r.get("status") != "done":
            failed.append(f"{r['id']}: {r.get('error', 'failed')}")
            continue
        scenario = r["args"][r["args"].index("--scenario") + 1]
        runs[(scenario, r["imu"], r["seed"])] = r["metrics"]
    if failed:
        raise ReplayFailed("runs failed:\n  " + "\n  ".join(sorted(failed)))
    return runs


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--drive", required=True, help="drive folder (raw sync/extract or synthetic)")
    ap.add_argument("--scenario", action="append", required=True, help="built-in name or YAML (repeatable)")
    ap.add_argument("--seeds", type=int, default=10, help="seeds 1..N (default 10)")
    ap.add_argument("--no-imu-too", action="store_true", help="also run every case without IMU")
    ap.add_argument("--sweep", default=os.path.join(here, "..", "..", "build", "bin", "locaid-sweep"),
                    help="locaid-sweep binary (default build/bin/locaid-sweep; it runs the locaid-replay beside it)")
    ap.add_argument("--out", help="sweep folder, kept (default: a temporary one, removed at the end)")
    ap.add_argument("--ekf", action="append", default=[], help="NAME=VALUE passed to locaid-replay --ekf")
    ap.add_argument("--replay-arg", action="append", default=[],
                    help="one more locaid-replay argument for every run, e.g. --replay-arg=--vo-rotation-noise=learned")
    ap.add_argument("--vehicle-constraints", choices=["auto", "on", "off"],
                    help="pass --vehicle-constraints to locaid-replay (its default: auto)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="parallel replays (default: cores)")
    ap.add_argument("--runs-csv", help="also write one line per run to this CSV")
    ap.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    args = ap.parse_args()
    if args.seeds < 1:
        ap.error("--seeds must be >= 1")
    if args.jobs < 1:
        ap.error("--jobs must be >= 1")
    if not os.access(args.sweep, os.X_OK):
        ap.error(f"{args.sweep}: not an executable (build first, or pass --sweep)")
    if not os.path.isdir(args.drive):
        ap.error(f"{args.drive}: no such drive folder")

    drive = os.path.realpath(args.drive)
    scenarios = [os.path.realpath(s) if os.path.isfile(s) else s for s in args.scenario]
    extra = [a for e in args.ekf for a in ("--ekf", e)] + args.replay_arg
    if args.vehicle_constraints:
        extra += ["--vehicle-constraints", args.vehicle_constraints]
    imus = [True, False] if args.no_imu_too else [True]
    out = args.out or tempfile.mkdtemp(prefix="outage_sweep_")
    try:
        all_runs = run_sweep(args.sweep, drive, scenarios, args.seeds, imus, extra, args.jobs, out)
    finally:
        if not args.out:
            shutil.rmtree(out, ignore_errors=True)
    result = {"drive": drive, "seeds": args.seeds, "ekf": args.ekf, "replay_args": args.replay_arg,
              "gate_probability": GATE_PROBABILITY,
              "cases": []}
    runs_out = []
    for given, scenario, imu in [(g, s, imu) for g, s in zip(args.scenario, scenarios) for imu in imus]:
        runs = {seed: j for (sc, i, seed), j in all_runs.items() if sc == scenario and i == imu}
        if len(runs) != args.seeds:
            raise ReplayFailed(f"{scenario} ({'IMU' if imu else 'no IMU'}): {len(runs)} of {args.seeds} runs found")
        rmse, end_pct, added_pct, reconv, nees_ratio, max_up = [], [], [], [], [], []
        modes, vo_health, speed_scale = {}, {}, []
        fixes = rej_h = rej_v = resets = vo_rej = never = 0
        over_bound, longest_run = [], 0
        for seed in sorted(runs):
            j = runs[seed]
            rmse.append(j["rmse_gps_m"])
            for o in j["outages"]:
                end_pct.append(o["end_error_pct"])
                if o.get("added_error_pct") is not None:
                    added_pct.append(o["added_error_pct"])
                if o["reconverge_s"] >= 0:
                    reconv.append(o["reconverge_s"])
                else:
                    never += 1  # no frame within 2 sigma_h before the next outage or the end
            nees_ratio.append(j["nees_mean"] / j["nees_bound_99"])
            if j["nees_mean"] > j["nees_bound_99"]:
                over_bound.append(seed)
            max_up.append(j["max_vertical_error_m"])
            for name, n in j.get("modes", {}).items():
                modes[name] = modes.get(name, 0) + n
            for name, n in j.get("vo_health", {}).items():
                vo_health[name] = vo_health.get(name, 0) + n
            if j.get("vehicle", {}).get("speed_used", 0) > 0:
                speed_scale.append(j["vehicle"]["speed_scale_error"])
            fixes += j["gps_used"] + j["gps_rejected"]
            rej_h += j["gps_rejected"]
            rej_v += j["gps_rejected_vertical"]
            resets += j["gps_resets"]
            vo_rej += j["vo_rejected_by_gate"]
            longest_run = max(longest_run, j["max_gps_rejection_run"], j["max_gps_rejection_run_vertical"])
            runs_out.append({"scenario": given, "use_imu": imu, "seed": seed, "nees_mean": j["nees_mean"],
                             "nees_bound_99": j["nees_bound_99"], "max_vertical_error_m": j["max_vertical_error_m"],
                             "gps_rejected": j["gps_rejected"], "gps_rejected_vertical": j["gps_rejected_vertical"],
                             "gps_resets": j["gps_resets"], "rmse_gps_m": j["rmse_gps_m"],
                             "end_error_pct": [o["end_error_pct"] for o in j["outages"]]})
        result["cases"].append({
            "scenario": given, "use_imu": imu, "rmse_gps_m": summary(rmse),
            "end_error_pct": summary(end_pct), "added_error_pct": summary(added_pct),
            "reconverge_s": summary(reconv), "modes": modes, "vo_health": vo_health,
            "speed_scale_error": summary(speed_scale),
            "reconverge_never": never,
            "nees_over_bound_runs": over_bound, "nees_mean_over_bound": summary(nees_ratio),
            "max_vertical_error_m": summary(max_up),
            "gps_fixes": fixes, "gps_rejected": rej_h, "gps_rejected_vertical": rej_v,
            "gps_expected_false_alarms": fixes * (1 - GATE_PROBABILITY),
            "gps_longest_rejection_run": longest_run, "gps_resets": resets,
            "vo_rejected_per_run": vo_rej / len(runs)})
    print("", file=sys.stderr)
    if args.runs_csv:
        with open(args.runs_csv, "w") as f:
            f.write("scenario,use_imu,seed,nees_mean,nees_bound_99,max_vertical_error_m,gps_rejected,"
                    "gps_rejected_vertical,gps_resets,rmse_gps_m,end_error_pct\n")
            for r in runs_out:
                f.write(f"{r['scenario']},{int(r['use_imu'])},{r['seed']},{r['nees_mean']:.3f},"
                        f"{r['nees_bound_99']:.3f},{r['max_vertical_error_m']:.3f},{r['gps_rejected']},"
                        f"{r['gps_rejected_vertical']},{r['gps_resets']},{r['rmse_gps_m']:.3f},"
                        f"{' '.join('%.3f' % v for v in r['end_error_pct'])}\n")
    if args.json:
        print(json.dumps(result, indent=2))
        return
    print(f"{drive}, seeds 1..{args.seeds}" + (f", --ekf {' '.join(args.ekf)}" if args.ekf else ""))
    for c in result["cases"]:
        def fmt(s, f):
            return "-" if s is None else "/".join(f % s[k] for k in ("median", "p90", "max"))
        print(f"{c['scenario']} ({'IMU' if c['use_imu'] else 'no IMU'})")
        print(f"  rmse_gps_m med/p90/max        {fmt(c['rmse_gps_m'], '%.3f')}")
        print(f"  end_error_pct med/p90/max     {fmt(c['end_error_pct'], '%.2f')}")
        print(f"  added_error_pct med/p90/max   {fmt(c['added_error_pct'], '%.2f')}")
        if c["speed_scale_error"]:
            print(f"  speed scale error med/p90/max {fmt(c['speed_scale_error'], '%.4f')}")
        print(f"  poses per mode {c['modes']}; VO health {c['vo_health']}")
        print(f"  reconverge_s med/p90/max      {fmt(c['reconverge_s'], '%.2f')}"
              + (f"   never: {c['reconverge_never']} outages" if c['reconverge_never'] else ""))
        print(f"  NEES/bound99 med/p90/max      {fmt(c['nees_mean_over_bound'], '%.2f')}"
              f"   runs over the bound: {len(c['nees_over_bound_runs'])} {c['nees_over_bound_runs'] or ''}")
        print(f"  max vertical error m          {fmt(c['max_vertical_error_m'], '%.2f')}")
        print(f"  GPS fixes {c['gps_fixes']}: rejected {c['gps_rejected']} horizontal, "
              f"{c['gps_rejected_vertical']} vertical (nominal {c['gps_expected_false_alarms']:.1f} each); "
              f"longest run {c['gps_longest_rejection_run']}; resets {c['gps_resets']}")
        print(f"  VO updates rejected per run   {c['vo_rejected_per_run']:.1f}")


if __name__ == "__main__":
    try:
        main()
    except ReplayFailed as e:
        sys.exit(f"outage_sweep.py: {e}")
    except KeyboardInterrupt:
        sys.exit(130)
