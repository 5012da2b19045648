#!/usr/bin/python3
"""Plot a locaid-replay CSV (--out-csv): top view and error over time.

Usage: /usr/bin/python3 clients/plot_outage.py RUN.csv [--out PREFIX]
Writes PREFIX_track.png (ground truth, degraded GPS when the CSV has fixes,
VO-only and fused tracks, outage segments marked) and PREFIX_error.png
(horizontal error with the 3-sigma bound in metres, outage windows shaded,
the error at the end of each outage labelled). Needs Debian's python3-matplotlib.
"""
import argparse
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402


def read(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit(f"{path}: no rows")
    needed = {"t_s", "gt_e", "gt_n", "est_e", "est_n", "gps_e", "gps_n", "vo_e", "vo_n",
              "sigma_e", "sigma_n", "err_h", "mode", "in_outage", "initialized"}
    missing = needed - set(rows[0].keys())
    if missing:
        sys.exit(f"{path}: missing columns {sorted(missing)}")
    return rows


def windows(rows):
    out, start = [], None
    for r in rows:
        t, o = float(r["t_s"]), r["in_outage"] == "1"
        if o and start is None:
            start = t
        if not o and start is not None:
            out.append((start, t))
            start = None
    if start is not None:
        out.append((start, float(rows[-1]["t_s"])))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("csv")
    ap.add_argument("--out", help="output prefix (default: CSV path without .csv)")
    a = ap.parse_args()
    rows = read(a.csv)
    prefix = a.out or (a.csv[:-4] if a.csv.endswith(".csv") else a.csv)
    f = lambda r, k: float(r[k]) if r[k] != "" else math.nan  # empty: no ground truth at that frame
    init = [r for r in rows if r["initialized"] == "1"]
    gps = [r for r in rows if r["gps_e"] != ""]
    name = os.path.basename(a.csv)

    fig, ax = plt.subplots(figsize=(9, 8))
    ax.plot([f(r, "gt_e") for r in rows], [f(r, "gt_n") for r in rows], "k-", lw=2, label="ground truth (OXTS)")
    if gps:  # a recording scored by locaid-score carries no fixes: nothing to draw, no legend entry
        ax.plot([f(r, "gps_e") for r in gps], [f(r, "gps_n") for r in gps], ".", color="tab:orange", ms=3,
                label="degraded GPS")
    rej = [r for r in gps if r.get("gps_rejected") == "1"]
    if rej:
        ax.plot([f(r, "gps_e") for r in rej], [f(r, "gps_n") for r in rej], "x", color="red", ms=6,
                label="GPS rejected by the gate")
    vo = [r for r in rows if r["vo_e"] != ""]  # empty in recordings scored by locaid-score
    if vo:
        ax.plot([f(r, "vo_e") for r in vo], [f(r, "vo_n") for r in vo], "-", color="tab:green", lw=1,
                label="VO only")
    ax.plot([f(r, "est_e") for r in init], [f(r, "est_n") for r in init], "-", color="tab:blue", lw=1.2,
            label="fused")
    first = True
    for t0, t1 in windows(rows):
        seg = [r for r in rows if t0 <= f(r, "t_s") <= t1]
        ax.plot([f(r, "gt_e") for r in seg], [f(r, "gt_n") for r in seg], "-", color="magenta", lw=5, alpha=0.35,
                label="GPS outage" if first else None)
        first = False
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best")
    ax.set_title(f"{name}: top view (ENU, origin at the first GPS fix)" +
                 ("" if gps else "\nGPS fixes not in this recording"))
    fig.tight_layout()
    fig.savefig(prefix + "_track.png", dpi=110)

    fig, ax = plt.subplots(figsize=(11, 4.5))
    t = [f(r, "t_s") for r in init]
    ax.plot(t, [f(r, "err_h") for r in init], "-", color="tab:blue", label="horizontal error")
    ax.plot(t, [3 * math.hypot(f(r, "sigma_e"), f(r, "sigma_n")) for r in init], "--", color="tab:gray",
            label="3 sigma (horizontal)")
    for i, (t0, t1) in enumerate(windows(rows)):
        ax.axvspan(t0, t1, color="magenta", alpha=0.15, label="GPS outage" if i == 0 else None)
        # The figure an outage is judged by: the error where GPS comes back.
        end = [r for r in init if r["in_outage"] == "1" and t0 <= f(r, "t_s") <= t1]
        if end:
            e = f(end[-1], "err_h")
            ax.annotate(f"{e:.2f} m", (f(end[-1], "t_s"), e), textcoords="offset points", xytext=(4, 6),
                        fontsize=9, color="tab:blue")
    ax.set_xlabel("time since the first frame (s)")
    ax.set_ylabel("horizontal error (m)")
    # Log-like above 1 m (an outage's growth), linear below; ticks labelled in
    # plain metres so a value can be read off.
    ax.set_yscale("symlog", linthresh=1.0, linscale=1.0)
    drawn = [f(r, "err_h") for r in init] + [3 * math.hypot(f(r, "sigma_e"), f(r, "sigma_n")) for r in init]
    top = max([v for v in drawn if not math.isnan(v)] + [1.0])
    ticks = [v for v in (0, 0.25, 0.5, 0.75, 1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000) if v <= 2 * top]
    ax.yaxis.set_major_locator(matplotlib.ticker.FixedLocator(ticks))
    ax.yaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
    ax.yaxis.set_minor_locator(matplotlib.ticker.NullLocator())
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left")
    ax.set_title(f"{name}: horizontal error of the fused pose, outages shaded (end-of-outage error labelled)")
    fig.tight_layout()
    fig.savefig(prefix + "_error.png", dpi=110)
    print(prefix + "_track.png")
    print(prefix + "_error.png")


if __name__ == "__main__":
    main()
