#!/usr/bin/python3
"""locaid-sweep-plot DIR: the end-of-outage error pictures of a sweep.

Reads DIR/results.csv (written by `locaid-sweep report`) and writes
  end_error_by_scenario.png   the first outage's end error (% of the distance
                              driven in it) of every done run, per scenario and
                              IMU setting, over all recordings
  end_error_by_recording.png  the same per recording (all scenarios), so a bad
                              recording stands out
and prints the names of the files it wrote, one per line (none when no done
run has an outage). In a smoothed sweep (results.csv has end_error_pct_smoothed)
each group has two boxes, forward and smoothed, side by side. Needs
python3-matplotlib.
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def boxes(ax, groups, ylabel):
    labels = list(groups)
    data = [groups[k] for k in labels]
    box = ax.boxplot(data, whis=(0, 100), widths=0.5, patch_artist=True)  # whiskers at min / max: the tail is the point
    for patch, label in zip(box["boxes"], labels):
        patch.set_facecolor("#c6dbef" if label.endswith("smoothed") else "white")
    for i, values in enumerate(data, start=1):  # every run as a dot over its box
        ax.plot([i + 0.12 * ((j % 5) - 2) / 2 for j in range(len(values))], values, ".", alpha=0.5, color="C1")
    ax.set_xticks(range(1, len(labels) + 1))
    ax.set_xticklabels([f"{k}\n(n={len(groups[k])})" for k in labels], rotation=20, ha="right", fontsize=8)
    ax.set_ylabel(ylabel)
    ax.grid(axis="y", alpha=0.3)


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: locaid-sweep-plot DIR")
    folder = sys.argv[1]
    with open(os.path.join(folder, "results.csv"), newline="") as f:
        reader = csv.DictReader(f)
        smoothed = "end_error_pct_smoothed" in (reader.fieldnames or [])
        rows = [r for r in reader if r["status"] == "done" and r["end_error_pct"] != ""]
    if not rows:
        return
    # forward (and smoothed) values per label: in a smoothed sweep, boxes side by side
    sides = [("end_error_pct", "")]
    if smoothed:
        sides = [("end_error_pct", " | forward"), ("end_error_pct_smoothed", " | smoothed")]
    by_scenario, by_recording = {}, {}
    for r in rows:
        scenario = r["scenario"] + ("" if r["imu"] == "on" else " (no IMU)")
        recording = os.path.basename(r["recording"].rstrip("/"))
        for column, suffix in sides:
            if r[column] == "":
                continue
            by_scenario.setdefault(scenario + suffix, []).append(float(r[column]))
            by_recording.setdefault(recording + suffix, []).append(float(r[column]))
    for name, groups, title in (
        ("end_error_by_scenario.png", by_scenario, "per scenario, all recordings"),
        ("end_error_by_recording.png", by_recording, "per recording, all scenarios"),
    ):
        fig, ax = plt.subplots(figsize=(max(6, 1.2 * len(groups) + 2), 4.5))
        boxes(ax, groups, "end-of-outage error (% of distance)")
        ax.set_title(f"End of the first outage: {title}")
        fig.tight_layout()
        fig.savefig(os.path.join(folder, name), dpi=100)
        plt.close(fig)
        print(name)


if __name__ == "__main__":
    main()
