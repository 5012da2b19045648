#!/usr/bin/python3
"""How close the filter is to the best any real-time estimator can do.

Reads a per-frame CSV of locaid-replay --out-csv (or locaid-score). At every
GPS fix k it computes the causal least-squares position: the 2D rigid fit
(east, north, yaw) of the ground-truth track (that is, relative motion known
perfectly, better than any VO) to fixes 1..k, evaluated at fix k. No causal
estimator that sees the same fixes can beat it on average, whatever its
odometry, so its RMSE is a lower bound for rmse_gps_m on that noise draw.

  bench/fusion/causal_bound.py run.csv [--min-fixes 6] [--json]

Prints the bound and the filter's own horizontal RMSE at the same frames.
For every outage (CSV column in_outage) it also prints the bound on the
end-of-outage error: the same rigid fit to the accepted fixes before the
outage, carried along the ground-truth track to the outage's last frame,
against the filter's error there (both also in % of the distance driven in
the outage, as locaid-replay's end_error_pct).
The ground truth of each fix is taken at the fix's own time (columns
gps_gt_e/gps_gt_n), the estimate at the frame the fix was fed at.

Which fixes it counts ("N fixes scored"): the CSV has one row per frame and
shows the LAST fix fed in that frame; the fit uses every row whose fix the gate
accepted, and the bound is scored at those rows from the --min-fixes-th on,
where the filter was initialised and in a GPS mode. So N is smaller than
locaid-replay's gps_used, which counts every fix the filter used: also a
frame's earlier fixes (when two or more fixes fall in one frame interval) and
the fixes buffered before the filter started and used to initialise it. The
output gives the count at each step (JSON "fix_accounting"). Measured with
the fixes of locaid-replay --out-mcap: real excerpt, outage-10s-middle seed 2:
gps_used 94 = 81 frames with a fix (11 of them got 2-4 fixes) + 13; 61 scored.
Synthetic 2.2 km drive (locaid-synth --length-m 2200 --seed 3), tunnel-30s:
gps_used 1345 = 1013 frames with a fix (332 of them got 2) + 332; 996 scored.
The fit sees only the CSV's fixes: where frames got several, the bound is that
of an estimator with fewer fixes than the filter had (a looser bound; the
CSV would need every fix for the exact one).
"""
import argparse
import csv
import json
import math
import sys

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("csv", help="CSV from locaid-replay --out-csv")
    ap.add_argument("--min-fixes", type=int, default=6, help="fixes before the first estimate (default 6)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    try:
        with open(args.csv, newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        sys.exit(f"{args.csv}: {e.strerror}")
    need = {"t_s", "in_outage", "gt_e", "gt_n", "est_e", "est_n", "gps_e", "gps_n", "gps_rejected", "initialized", "mode",
            "gps_gt_e", "gps_gt_n"}
    if not rows or not need <= set(rows[0]):
        sys.exit(f"{args.csv}: not a locaid-replay CSV (needs columns {', '.join(sorted(need))})")

    fix_rows = [i for i, r in enumerate(rows) if r["gps_e"]]
    fixes = [i for i in fix_rows if rows[i]["gps_gt_e"] and rows[i]["gps_rejected"] == "0"]
    z = np.array([[float(rows[i]["gps_e"]), float(rows[i]["gps_n"])] for i in fixes])
    gt_fix = np.array([[float(rows[i]["gps_gt_e"]), float(rows[i]["gps_gt_n"])] for i in fixes])
    bound, filt = [], []
    skipped_uninitialised = skipped_no_gt = skipped_mode = 0
    for k in range(args.min_fixes, len(fixes) + 1):
        rot, qm, pm = rigid_fit(gt_fix[:k], z[:k])
        i = fixes[k - 1]
        r = rows[i]
        if r["initialized"] != "1":
            skipped_uninitialised += 1
            continue
        if r["gt_e"] == "":
            skipped_no_gt += 1
            continue
        if r["mode"] not in ("GPS_FUSED", "GPS_DEGRADED"):
            skipped_mode += 1
            continue
        # Both at the fix time: the filter's estimate at the frame carries the
        # motion since the fix, the bound is moved by the same true motion.
        gt_row = np.array([float(r["gt_e"]), float(r["gt_n"])])
        bound.append(float(np.linalg.norm(rot @ (gt_fix[k - 1] - qm) + pm - gt_fix[k - 1])))
        filt.append(float(np.linalg.norm(np.array([float(r["est_e"]), float(r["est_n"])]) - gt_row)))
    if not bound:
        sys.exit(f"{args.csv}: no initialised frames with an accepted fix")
    rms = lambda v: math.sqrt(sum(x * x for x in v) / len(v))
    accounting = {"frames": len(rows), "frames_with_a_fix": len(fix_rows), "accepted": len(fixes),
                  "before_min_fixes": min(len(fixes), args.min_fixes - 1),
                  "filter_not_initialised": skipped_uninitialised, "no_ground_truth": skipped_no_gt,
                  "not_in_a_gps_mode": skipped_mode, "scored": len(bound)}
    out = {"csv": args.csv, "fixes": len(bound), "causal_ls_rmse_m": rms(bound), "filter_rmse_m": rms(filt),
           "fix_accounting": accounting, "outages": outage_bounds(rows, fixes, z, gt_fix, args.min_fixes)}
    if args.json:
        print(json.dumps(out, indent=2))
        return
    print(f"{args.csv}: {len(bound)} fixes scored; causal least-squares bound {out['causal_ls_rmse_m']:.3f} m, "
          f"filter {out['filter_rmse_m']:.3f} m (horizontal RMSE at the same frames)")
    a = accounting
    print(f"  fixes: {a['frames_with_a_fix']} of {a['frames']} frames show one (the last fed in the frame; "
          f"locaid-replay's gps_used also counts a frame's other fixes and those the filter started from), "
          f"{a['accepted']} accepted by the gate (with ground truth); not scored: {a['before_min_fixes']} before --min-fixes, "
          f"{a['filter_not_initialised']} before the filter was initialised"
          + (f", {a['no_ground_truth']} without ground truth" if a["no_ground_truth"] else "")
          + (f", {a['not_in_a_gps_mode']} not in a GPS mode" if a["not_in_a_gps_mode"] else "")
          + ". The fit uses only the fixes the CSV shows (see --help)")
    for o in out["outages"]:
        if o["bound_end_error_m"] is None:
            print(f"  outage at {o['start_s']:.1f} s: only {o['fixes_before']} accepted fixes before it, no bound")
            continue
        print(f"  outage at {o['start_s']:.1f} s ({o['distance_m']:.1f} m, {o['fixes_before']} fixes before): "
              f"end error bound {o['bound_end_error_m']:.2f} m ({o['bound_end_error_pct']:.2f} %), "
              f"filter {o['filter_end_error_m']:.2f} m ({o['filter_end_error_pct']:.2f} %)")


def rigid_fit(q, p):
    """2D rotation + translation that maps q onto p in least squares: (rot, q_mean, p_mean)."""
    qm, pm = q.mean(0), p.mean(0)
    h = (q - qm).T @ (p - pm)
    psi = math.atan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1])
    return np.array([[math.cos(psi), -math.sin(psi)], [math.sin(psi), math.cos(psi)]]), qm, pm


def outage_bounds(rows, fixes, z, gt_fix, min_fixes):
    """Per outage window (runs of in_outage == 1): the causal LS end-of-outage error bound."""
    xy = lambda r, a, b: np.array([float(r[a]), float(r[b])])
    windows, start = [], None
    for i, r in enumerate(rows):
        if r.get("in_outage") == "1" and start is None:
            start = i
        elif r.get("in_outage") != "1" and start is not None:
            windows.append((start, i - 1))
            start = None
    if start is not None:
        windows.append((start, len(rows) - 1))
    t0 = float(rows[0]["t_s"])
    result = []
    for i0, i1 in windows:
        k = sum(1 for i in fixes if i < i0)
        # Frames without ground truth (empty gt columns) are skipped; the
        # outage ends at its last frame that has it.
        # Distance from the last frame before the outage, as locaid-replay.
        with_gt = [i for i in range(max(i0 - 1, 0), i1 + 1) if rows[i]["gt_e"] != ""]
        if not with_gt or with_gt[-1] < i0:
            continue
        i1 = with_gt[-1]
        gt_end = xy(rows[i1], "gt_e", "gt_n")
        dist = sum(float(np.linalg.norm(xy(rows[b], "gt_e", "gt_n") - xy(rows[a], "gt_e", "gt_n")))
                   for a, b in zip(with_gt, with_gt[1:]))
        filt = float(np.linalg.norm(xy(rows[i1], "est_e", "est_n") - gt_end))
        o = {"start_s": float(rows[i0]["t_s"]) - t0, "distance_m": dist, "fixes_before": k,
             "filter_end_error_m": filt, "filter_end_error_pct": 100 * filt / dist if dist > 0 else None,
             "bound_end_error_m": None, "bound_end_error_pct": None}
        if k >= max(min_fixes, 2):
            rot, qm, pm = rigid_fit(gt_fix[:k], z[:k])
            b = float(np.linalg.norm(rot @ (gt_end - qm) + pm - gt_end))
            o["bound_end_error_m"] = b
            o["bound_end_error_pct"] = 100 * b / dist if dist > 0 else None
        result.append(o)
    return result


if __name__ == "__main__":
    main()
