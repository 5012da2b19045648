#!/usr/bin/python3
"""How close the filter is to the best any real-time estimator can do.

Reads a per-frame CSV of locaid-replay --out-csv (or locaid-score). At every
GPS fix k it computes the causal least-squares position: the 2D rigid fit
(east, north, yaw) of the ground-truth track (that is, relative motion known
perfectly, better than any VO) to fixes 1..k, evaluated at fix k. No causal
estimator that sees the same fixes can beat it on average, whatever its
odometry, so its RMSE is a lower bound for rmse_gps_m on that noise draw.

  bench/fusion/causal_bound.py run.csv [--skip-fixes 0] [--json]

Prints the bound and the filter's own horizontal RMSE at the same frames.
The ground truth of each fix is taken at the fix's own time (columns
gps_gt_e/gps_gt_n), the estimate at the frame the fix was fed at.
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
    need = {"gt_e", "gt_n", "est_e", "est_n", "gps_e", "gps_n", "gps_rejected", "initialized", "mode",
            "gps_gt_e", "gps_gt_n"}
    if not rows or not need <= set(rows[0]):
        sys.exit(f"{args.csv}: not a locaid-replay CSV (needs columns {', '.join(sorted(need))})")

    fixes = [i for i, r in enumerate(rows) if r["gps_e"] and r["gps_gt_e"] and r["gps_rejected"] == "0"]
    z = np.array([[float(rows[i]["gps_e"]), float(rows[i]["gps_n"])] for i in fixes])
    gt_fix = np.array([[float(rows[i]["gps_gt_e"]), float(rows[i]["gps_gt_n"])] for i in fixes])
    bound, filt = [], []
    for k in range(args.min_fixes, len(fixes) + 1):
        q, p = gt_fix[:k], z[:k]
        qm, pm = q.mean(0), p.mean(0)
        h = (q - qm).T @ (p - pm)
        psi = math.atan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1])
        rot = np.array([[math.cos(psi), -math.sin(psi)], [math.sin(psi), math.cos(psi)]])
        i = fixes[k - 1]
        r = rows[i]
        if r["initialized"] != "1" or r["mode"] not in ("GPS_FUSED", "GPS_DEGRADED"):
            continue
        # Both at the fix time: the filter's estimate at the frame carries the
        # motion since the fix, the bound is moved by the same true motion.
        gt_row = np.array([float(r["gt_e"]), float(r["gt_n"])])
        bound.append(float(np.linalg.norm(rot @ (gt_fix[k - 1] - qm) + pm - gt_fix[k - 1])))
        filt.append(float(np.linalg.norm(np.array([float(r["est_e"]), float(r["est_n"])]) - gt_row)))
    if not bound:
        sys.exit(f"{args.csv}: no initialised frames with an accepted fix")
    rms = lambda v: math.sqrt(sum(x * x for x in v) / len(v))
    out = {"csv": args.csv, "fixes": len(bound), "causal_ls_rmse_m": rms(bound), "filter_rmse_m": rms(filt)}
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        print(f"{args.csv}: {len(bound)} accepted fixes; causal least-squares bound {out['causal_ls_rmse_m']:.3f} m, "
              f"filter {out['filter_rmse_m']:.3f} m (horizontal RMSE at the same frames)")


if __name__ == "__main__":
    main()
