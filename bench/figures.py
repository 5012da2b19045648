#!/usr/bin/python3
"""Re-runs every deterministic figure of docs/benchmarks.md and compares it
with the published value at the digits the document prints.

The published values are in bench/figures.tsv, one figure a line:

  figure   what it is (the table prints it)
  run      the measurement that produces it (the RUNS table below: a command)
  keys     comma-separated names of the run's values, one per number in `published`
  published  the text as docs/benchmarks.md prints it, e.g. "2.11 / 4.68 / 8.04"
  anchor   a text that is on exactly one line of the documents (DOCS: docs/benchmarks.md
           and the detail tables moved out of it); `published` must be on that same
           line (so the documents and the file cannot drift)

Every number in `published` is compared with its key's value rounded to the
same number of decimals (thousands commas and a leading + are kept). A line
whose published numbers differ from today's is DIFF; a published text that is
not on its anchor line is DOC. Timing figures (ms/frame, frames/s, poses/s)
are not deterministic and are not here: docs/benchmarks.md gives them with the
date and command of their measurement.

  bench/figures.sh [--fast] [--only RUN ...] [--list] [--bin-dir build/bin]
                   [--data ../shared/data/kitti] [--work DIR] [--jobs N] [--values FILE]

--fast runs the figures that take a few minutes on 2 cores (real excerpt,
devkit, simulator, MCAP sizes; the test command runs it); without it every
figure, including the synthetic drives (renders included, ~1 h on 2 cores).
Exit status: 0 every figure as published, 1 a difference or a failed run,
77 the shared KITTI data is absent (figures.sh says so and skips).
"""
import argparse
import csv
import json
import math
import os
import re
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
REAL = "raw/2011_09_26/2011_09_26_drive_unknown_extract"
# The documents the published figures are on: benchmarks.md and the detail tables moved out of it.
DOCS = ["docs/benchmarks.md", "docs/experiments/vo-synthetic-drives.md"]
# A number as printed: 1,009 / 0.957 / +0.15; a '-' right after a digit is a range ("0.267-0.419"), not a sign.
NUMBER = re.compile(r"(?:(?<![\w.])[+-])?(?:\d{1,3}(?:,\d{3})+|\d+)(?:\.\d+)?")


class RunFailed(Exception):
    pass


class Context:
    def __init__(self, args):
        self.bin = os.path.abspath(args.bin_dir)
        self.data = os.path.abspath(args.data)
        self.work = args.work
        self.jobs = args.jobs
        self.verbose = args.verbose
        self.commands = []  # (run, command as shown)
        self._synth = {}

    def exe(self, name):
        path = os.path.join(self.bin, name)
        if not os.access(path, os.X_OK):
            raise RunFailed(f"{path}: not built")
        return path

    def real(self):
        return os.path.join(self.data, REAL)

    def run(self, cmd, run_name):
        shown = " ".join(shlex.quote(c) for c in cmd)
        for long in (self.bin, self.data, ROOT):  # paths as seen from the repository root
            shown = shown.replace(long + "/", os.path.relpath(long, ROOT) + "/" if long != ROOT else "")
        self.commands.append((run_name, shown))
        if self.verbose:
            print(f"  $ {shown}", file=sys.stderr, flush=True)
        p = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
        if p.returncode != 0:
            tail = "\n".join(p.stderr.strip().splitlines()[-3:])
            raise RunFailed(f"{shown}\nexit status {p.returncode}: {tail}")
        return p.stdout

    def json(self, cmd, run_name):
        out = self.run(cmd, run_name)
        try:
            return json.loads(out)
        except json.JSONDecodeError as e:
            raise RunFailed(f"{cmd[0]}: output is not JSON ({e})")

    def render(self, name, options, run_name):
        """The drive `locaid-synth OPTIONS` renders, in WORK/NAME. Rendered once per run; a --work folder
        kept from an earlier run is reused when its marker names the same options and the same
        locaid-synth binary (size, mtime): a render is byte-identical for the same options."""
        out = os.path.join(self.work, name)
        if out not in self._synth:
            synth = self.exe("locaid-synth")
            st = os.stat(synth)
            marker = f"{' '.join(options)}\nlocaid-synth {st.st_size} {st.st_mtime_ns}\n"
            marker_path = os.path.join(out, "rendered-by-figures.txt")
            try:
                with open(marker_path) as f:
                    reuse = f.read() == marker
            except OSError:
                reuse = False
            if reuse:
                self.commands.append((run_name, f"(reused {out}: locaid-synth --out {out} {' '.join(options)})"))
            else:
                shutil.rmtree(out, ignore_errors=True)
                self.run([synth, "--out", out] + options + ["-q"], run_name)
                with open(marker_path, "w") as f:
                    f.write(marker)
            drives = [d for d in os.listdir(out) if d.endswith("_sync")]
            if len(drives) != 1:
                raise RunFailed(f"{out}: expected one *_sync drive, found {drives}")
            self._synth[out] = os.path.join(out, drives[0])
        return self._synth[out]

    def synth(self, length_m, seed, run_name):
        """The drive of `locaid-synth --length-m L --seed S`."""
        return self.render(f"synth-{length_m}m-s{seed}", ["--length-m", str(length_m), "--seed", str(seed)],
                           run_name)


def percentiles(values):
    """median / p90 / max of a list as locaid-sweep's summary gives them (numpy's default interpolation)."""
    s = sorted(values)
    k = (len(s) - 1) * 0.9
    lo, hi = int(k), min(int(k) + 1, len(s) - 1)
    return {"median": statistics.median(s), "p90": s[lo] + (s[hi] - s[lo]) * (k - lo), "max": s[-1]}


# --- the runs: each returns {key: value} ---------------------------------

def devkit(ctx):
    odo = os.path.join(ctx.data, "odometry")
    out = {}
    for key, seq, name in (("orb", "00", "00_ORB_SLAM_from_evo"), ("sptam", "00", "00_SPTAM_from_evo"),
                           ("itl00", "00", "00_kitti-eval-itl_example"), ("itl04", "04", "04_kitti-eval-itl_example")):
        j = ctx.json([ctx.exe("locaid-eval"), "--json", "--gt", f"{odo}/poses/{seq}.txt",
                      "--est", f"{odo}/reference_results/{name}.txt"], "devkit")
        out[f"{key}.t_err"] = j["t_err"]
        out[f"{key}.r_err"] = j["r_err_rad_per_m"]
        out[f"{key}.segments"] = j["segments"]
    return out


def vo_method_values(out, prefix, j):
    out[f"{prefix}.t_rel"] = j.get("t_rel_pct", math.nan)
    out[f"{prefix}.r_rel"] = j.get("r_rel_deg_per_100m", math.nan)
    out[f"{prefix}.final"] = j["final_error_pct"]
    out[f"{prefix}.frames"] = j["evaluated_frames"]
    out[f"{prefix}.length"] = j["length_m"]
    if "failed_frames" in j:
        out[f"{prefix}.failed"] = j["failed_frames"]
        out[f"{prefix}.degraded"] = j["degraded_frames"]
    if "boresight_fit" in j:
        b = j["boresight_fit"]
        out[f"{prefix}.boresight_yaw"] = b["yaw_deg"]
        out[f"{prefix}.boresight_pitch"] = b["pitch_deg"]
        out[f"{prefix}.boresight_t_rel"] = b["t_rel_pct"]


def vo_real(ctx):
    runs = ctx.json([ctx.exe("vo_bench"), "--drive", ctx.real(), "--method", "all", "--lengths", "25", "50", "75",
                     "100", "--reference-floor"], "vo_real")
    out = {}
    for j in runs:
        vo_method_values(out, "floor" if j["method"] == "reference_floor" else j["method"], j)
        if "oxts_pos_accuracy_median_m" in j:
            out["oxts_pos_accuracy_m"] = j["oxts_pos_accuracy_median_m"]
    return out


def vo_real_velocity(ctx):
    runs = ctx.json([ctx.exe("vo_bench"), "--drive", ctx.real(), "--method", "all", "--lengths", "25", "50", "75",
                     "100", "--reference", "oxts-velocity", "--fit-boresight"], "vo_real_velocity")
    out = {}
    for j in runs:
        vo_method_values(out, j["method"], j)
    return out


def vo_synth(ctx):
    out = {}
    for seed in (1, 2, 3):
        drive = ctx.synth(1100, seed, "vo_synth")
        runs = ctx.json([ctx.exe("vo_bench"), "--drive", drive, "--method", "all", "--lengths", "100", "200", "300",
                         "400", "500", "600", "700", "800", "--reference-floor"], "vo_synth")
        for j in runs:
            vo_method_values(out, f"s{seed}." + ("floor" if j["method"] == "reference_floor" else j["method"]), j)
    for m in ("default", "thesis"):
        for v in ("t_rel", "r_rel"):
            seeds = [out[f"s{seed}.{m}.{v}"] for seed in (1, 2, 3)]
            out[f"{m}.{v}_min"], out[f"{m}.{v}_max"] = min(seeds), max(seeds)
    return out


def vo_motorway(ctx):
    """Motorway drives (20-30 m/s, 300-1500 m curves), default and --anisotropic render, default VO."""
    out = {}
    for seed in (1, 2):
        for aniso in (False, True):
            name = f"h{seed}{'a' if aniso else ''}"
            drive = ctx.render(f"motorway-{name}", ["--length-m", "2000", "--seed", str(seed), "--speed-min", "20",
                                                    "--speed-max", "30", "--radius-min", "300", "--radius-max",
                                                    "1500"] + (["--anisotropic"] if aniso else []), "vo_motorway")
            runs = ctx.json([ctx.exe("vo_bench"), "--drive", drive, "--method", "default",
                             "--lengths", "100", "200", "300", "400", "500", "600", "700", "800"], "vo_motorway")
            vo_method_values(out, f"{name}.default", runs[0])
    for render, names in (("iso", ("h1", "h2")), ("aniso", ("h1a", "h2a"))):
        for v in ("t_rel", "r_rel"):
            both = [out[f"{n}.default.{v}"] for n in names]
            out[f"{render}.{v}_min"], out[f"{render}.{v}_max"] = min(both), max(both)
    return out


def sweep_values(out, prefix, g):
    """A sweep group's figures (locaid-sweep's summary.json): every outage's end error, RMSE while GPS is
    used, reconvergence, NEES, vertical error, the GPS gates, VO gated."""
    def put(name, d):
        for q in ("median", "p90", "max"):
            out[f"{prefix}.{name}_{q}"] = d[q] if d else math.nan
    put("end", g["end_error_pct_every"])
    put("rmse", g["rmse_gps_m"])
    put("reconverge", g["reconverge_s"])
    out[f"{prefix}.reconverge_never"] = g["reconverge_never"]
    out[f"{prefix}.runs"] = g["runs"]
    out[f"{prefix}.nees_over"] = len(g["nees_over_bound_seeds"])
    out[f"{prefix}.vertical_max"] = g["max_vertical_error_m"]["max"]
    out[f"{prefix}.fixes"] = g["gps_fixes"]
    out[f"{prefix}.rejected_h"] = g["gps_rejected"]
    out[f"{prefix}.rejected_v"] = g["gps_rejected_vertical"]
    out[f"{prefix}.nominal"] = g["gps_expected_false_alarms"]
    out[f"{prefix}.longest_run"] = g["gps_longest_rejection_run"]
    out[f"{prefix}.resets"] = g["gps_resets"]
    out[f"{prefix}.vo_gated"] = g["vo_rejected_per_run"]


def sweep(ctx, run_name, drive, scenarios, seeds, no_imu_too, ekf=(), options=()):
    """The scenarios over GPS-noise seeds 1..SEEDS (IMU on, and off with no_imu_too) as a locaid-sweep
    (docs/sweeps.md; one VO run per drive, resumable in WORK/sweep-RUN): its summary.json groups, one per
    scenario x IMU in that order."""
    out = os.path.join(ctx.work, f"sweep-{run_name}")
    os.makedirs(out, exist_ok=True)
    scenarios = [os.path.realpath(os.path.join(ROOT, s)) if os.path.isfile(os.path.join(ROOT, s)) else s
                 for s in scenarios]
    imus = [True, False] if no_imu_too else [True]
    replay_args = [a for e in ekf for a in ("--ekf", e)] + list(options)
    manifest = os.path.join(out, "manifest.yaml")
    with open(manifest, "w") as f:
        f.write("recordings:\n  - path: %s\n" % json.dumps(os.path.realpath(drive)))
        f.write("scenarios: %s\n" % json.dumps(scenarios))
        f.write("seeds: {from: 1, to: %d}\n" % seeds)
        f.write("imu: %s\n" % json.dumps(["on" if i else "off" for i in imus]))
        f.write("replay_args: %s\n" % json.dumps(replay_args))
    folder = os.path.join(out, "sweep")
    ctx.run([ctx.exe("locaid-sweep"), "run", manifest, "--out", folder, "--jobs", str(ctx.jobs)], run_name)
    with open(os.path.join(folder, "summary.json")) as f:
        groups = json.load(f)
    expected = [(s, imu) for s in scenarios for imu in imus]
    if len(groups) != len(expected) or any(g["imu"] != imu for g, (_, imu) in zip(groups, expected)):
        raise RunFailed(f"{folder}/summary.json: {len(groups)} groups, expected {len(expected)} (scenario x IMU)")
    for g, (s, _) in zip(groups, expected):
        if g["done"] != seeds:
            raise RunFailed(f"{s} ({'IMU' if g['imu'] else 'no IMU'}): {g['done']} of {seeds} runs done")
    return {"seeds": seeds, "groups": groups}


SCENARIO_KEY = {"scenarios/outage-10s-middle.yaml": "outage", "urban-canyon": "urban", "tunnel-30s": "tunnel"}


def sweep_real(ctx):
    r = sweep(ctx, "sweep_real", ctx.real(), ["scenarios/outage-10s-middle.yaml"], 50, True)
    out = {}
    for g in r["groups"]:
        sweep_values(out, "imu" if g["imu"] else "noimu", g)
    return out


def sweep_synth(ctx):
    scenarios = ["scenarios/outage-10s-middle.yaml", "urban-canyon", "tunnel-30s"]
    r = sweep(ctx, "sweep_synth", ctx.synth(2200, 3, "sweep_synth"), scenarios, 50, True)
    out = {}
    cases = [(s, imu) for s in scenarios for imu in (True, False)]
    for g, (scenario, imu) in zip(r["groups"], cases):
        sweep_values(out, f"{SCENARIO_KEY[scenario]}.{'imu' if imu else 'noimu'}", g)
    return out


def tunnel_values(out, prefix, g):
    """The Tunnel table's columns: end and added error of every outage (median / p90 / max), speed scale error."""
    for name, key in (("end", "end_error_pct_every"), ("added", "added_error_pct")):
        for q in ("median", "p90", "max"):
            out[f"{prefix}.{name}_{q}"] = g[key][q] if g[key] else math.nan
    speed = g.get("speed_scale_error")
    out[f"{prefix}.speed_median"] = speed["median"] if speed else math.nan
    out[f"{prefix}.speed_max"] = speed["max"] if speed else math.nan
    out[f"{prefix}.speed_p90"] = speed["p90"] if speed else math.nan


TUNNEL_KEY = {"frozen-speed": "frozen_speed", "blind-mems-speed": "dark_speed", "frozen": "frozen",
              "blind-mems": "dark"}


def tunnel_real(ctx):
    """The real-excerpt Tunnel table: camera faults change what VO sees, so no VO cache (20 seeds x 4)."""
    out = {}
    for scenarios, options in ((["frozen-speed", "blind-mems-speed"], ()),
                               (["frozen", "blind-mems"], ("--vehicle-constraints", "on"))):
        paths = [f"scenarios/tunnel-10s-late-{s}.yaml" for s in scenarios]
        r = sweep(ctx, "tunnel_real", ctx.real(), paths, 20, False, options=options)
        for g, name in zip(r["groups"], scenarios):
            tunnel_values(out, TUNNEL_KEY[name], g)
        out["runs"] = r["seeds"]
    return out


def tunnel_bound(ctx):
    """Perfect dead reckoning on the same 20 GPS draws as the frozen + speed row: the causal least-squares
    fit of the true track to the fixes before the outage (bench/fusion/causal_bound.py), carried to its end."""
    bound, filt = [], []
    for seed in range(1, 21):
        csv_path = os.path.join(ctx.work, f"tunnel-bound-s{seed}.csv")
        ctx.json([ctx.exe("locaid-replay"), "--drive", ctx.real(), "--scenario",
                  "scenarios/tunnel-10s-late-frozen-speed.yaml", "--seed", str(seed), "--json", "--out-csv", csv_path],
                 "tunnel_bound")
        b = ctx.json(["/usr/bin/python3", os.path.join(HERE, "fusion", "causal_bound.py"), "--json", csv_path],
                     "tunnel_bound")
        bound.append(b["outages"][0]["bound_end_error_pct"])
        filt.append(b["outages"][0]["filter_end_error_pct"])
    out = {"runs": 20, "over_1": sum(v > 1.0 for v in bound), "over_2": sum(v > 2.0 for v in bound),
           "over_3": sum(v > 3.0 for v in bound)}
    for name, values in (("bound", bound), ("filter", filt)):
        for q, v in percentiles(values).items():
            out[f"{name}.{q}"] = v
    return out


def tunnel_gps(ctx):
    """The frozen + speed row with better fixes: the outage's error follows the GPS before it."""
    with open(os.path.join(ROOT, "scenarios", "tunnel-10s-late-frozen-speed.yaml")) as f:
        base = f.read()
    out = {}
    for name, sigma in (("s05", "0.5"), ("s015", "0.15")):
        path = os.path.join(ctx.work, f"tunnel-gps-{sigma}.yaml")
        with open(path, "w") as f:
            f.write(base.replace("base: open-sky\n", f"base: open-sky\ngps: {{sigma_h_m: {sigma}}}\n", 1))
        r = sweep(ctx, "tunnel_gps", ctx.real(), [path], 20, False)
        tunnel_values(out, name, r["groups"][0])
    return out


def tunnel_synth(ctx):
    r = sweep(ctx, "tunnel_synth", ctx.synth(2000, 3, "tunnel_synth"),
              ["scenarios/tunnel-30s-blind-mems-speed.yaml"], 20, False)
    out = {"runs": r["seeds"]}
    tunnel_values(out, "dark_speed", r["groups"][0])
    return out


DARK_GAINS = (("g100", None), ("g25", "0.25"), ("g12", "0.12"), ("g06", "0.06"), ("g03", "0.03"), ("g02", "0.02"))


def dark_real(ctx):
    """VO on dark frames: a dark fault of gain G (3 DN noise) over the whole real excerpt."""
    out = {}
    for name, gain in DARK_GAINS:
        scenario = "open-sky"
        if gain:
            scenario = os.path.join(ctx.work, f"dark-{gain}.yaml")
            with open(scenario, "w") as f:
                f.write(f"base: open-sky\ncamera: [{{start_s: 0, duration_s: 1000, fault: dark, gain: {gain}, "
                        "noise_dn: 3}]\n")
        j = ctx.json([ctx.exe("locaid-replay"), "--drive", ctx.real(), "--scenario", scenario, "--json"], "dark_real")
        out[f"{name}.lost"] = j["vo_lost_frames"]
        out[f"{name}.dark"] = j["vo_health"].get("dark", 0)
        err = j.get("vo_error") or {}
        out[f"{name}.err_along"] = err["rms_error_t_m_r_rad"][0] if err.get("frames") else math.nan
    out["frames"] = j["frames"]
    return out


def lever_arm(ctx):
    drive = ctx.synth(2200, 3, "lever_arm")
    out = {}
    for name, ekf in (("off", ()), ("on", ("gps_lever_arm_x_m=1.2", "gps_lever_arm_y_m=0.9"))):
        r = sweep(ctx, "lever_arm", drive, ["scenarios/open-sky-antenna-1.5m.yaml"], 10, False, ekf)
        sweep_values(out, name, r["groups"][0])
        nees = r["groups"][0]["nees_mean_over_bound"]
        out[f"{name}.nees_ratio_max"] = nees["max"]
    out["ratio"] = out["on.rmse_median"] / out["off.rmse_median"]
    return out


def urban_bound(ctx):
    """Causal least-squares bound (bench/fusion/causal_bound.py) of urban-canyon, seeds 1-10."""
    drive = ctx.synth(2200, 3, "urban_bound")
    cache = os.path.join(ctx.work, "urban-bound.vo.cache")
    bound, filt, rmse = [], [], []
    for seed in range(1, 11):
        csv_path = os.path.join(ctx.work, f"urban-s{seed}.csv")
        j = ctx.json([ctx.exe("locaid-replay"), "--drive", drive, "--scenario", "urban-canyon", "--seed", str(seed),
                      "--vo-cache", cache, "--json", "--out-csv", csv_path], "urban_bound")
        b = ctx.json(["/usr/bin/python3", os.path.join(HERE, "fusion", "causal_bound.py"), "--json", csv_path],
                     "urban_bound")
        bound.append(b["causal_ls_rmse_m"])
        filt.append(b["filter_rmse_m"])
        rmse.append(j["rmse_gps_m"])
    return {"bound_median": statistics.median(bound), "filter_median": statistics.median(filt),
            "rmse_median": statistics.median(rmse), "seeds": 10}


def urban_2drms(ctx):
    r = sweep(ctx, "urban_2drms", ctx.synth(2200, 3, "urban_2drms"), ["scenarios/urban-canyon-2drms.yaml"], 10, True)
    out = {}
    for g in r["groups"]:
        sweep_values(out, "imu" if g["imu"] else "noimu", g)
    return out


def replay_urban(ctx):
    j = ctx.json([ctx.exe("locaid-replay"), "--drive", ctx.synth(2200, 3, "replay_urban"), "--scenario",
                  "urban-canyon", "--json"], "replay_urban")
    return {"rmse": j["rmse_gps_m"], "frames": j["frames"]}


def consistency_sim(ctx):
    j = ctx.json([ctx.exe("fusion_consistency_sim"), "--runs", "1000"], "consistency_sim")
    return {"runs": j["runs"], "over": j["runs_over_bound_99"], "share_pct": 100 * j["share_over_bound"],
            "nees_mean": j["nees_mean"], "groups": j["groups_of_50"], "tail_over": j["groups_max_over_3x_median"],
            "end_median_m": j["end_error_median_m"], "end_max_m": j["end_error_max_m"]}


def ekf_nees_test(ctx):
    out_text = ctx.run([ctx.exe("fusion_tests"), "--gtest_filter=EkfNees.*"], "ekf_nees_test")
    out = {}
    for m in re.finditer(r"^(IMU|no-IMU) NEES mean (\S+) bounds \[(\S+), (\S+)\]", out_text, re.M):
        prefix = "imu" if m.group(1) == "IMU" else "noimu"
        out[f"{prefix}.nees"] = float(m.group(2))
        out["lo"], out["hi"] = float(m.group(3)), float(m.group(4))
    if "imu.nees" not in out or "noimu.nees" not in out:
        raise RunFailed("fusion_tests --gtest_filter=EkfNees.*: no 'NEES mean' lines in its output")
    return out


def mcap(ctx):
    out = {}
    for level, prefix in ((None, "l1"), (3, "l3")):
        j = ctx.json([ctx.exe("mcap_write_bench"), "--poses", "20000", "--out-dir", ctx.work]
                     + ([] if level is None else ["--zstd-level", str(level)]), "mcap")
        for r in j:
            name = f"{prefix}.{'none' if r['compression'] == 'none' else 'zstd'}"
            out[f"{name}.bytes_per_pose"] = r["bytes_per_pose"]
            out[f"{name}.mb"] = r["bytes"] / 1e6
            out[f"{name}.messages"] = r["messages"]
            out["poses"] = r["poses"]
    return out


def smoother_values(ctx, run_name, drive, scenario, seeds):
    """Medians over seeds of bench/fusion/smoother_seeds.py: per outage k (o1, o2, ...) the forward / smoothed
    end error, smoothed largest error inside, forward / smoothed RMSE inside, the end-pinned floor; the RMSE
    while GPS is used."""
    out_json = os.path.join(ctx.work, f"{run_name}.json")
    ctx.run(["/usr/bin/python3", os.path.join(HERE, "fusion", "smoother_seeds.py"), "--drive", drive,
             "--scenario", scenario, "--seeds", str(seeds), "--cache-dir", ctx.work, "--json", out_json], run_name)
    with open(out_json) as f:
        runs = json.load(f)
    med = statistics.median
    out = {"gps_f": med(r["forward"]["rmse_gps_m"] for r in runs),
           "gps_s": med(r["smoothed"]["rmse_gps_m"] for r in runs)}
    for k in range(len(runs[0]["forward"]["outages"])):
        fo = [r["forward"]["outages"][k] for r in runs]
        so = [r["smoothed"]["outages"][k] for r in runs]
        o = f"o{k + 1}"
        out[f"{o}.end_f"] = med(x["end_error_m"] for x in fo)
        out[f"{o}.end_s"] = med(x["end_error_m"] for x in so)
        out[f"{o}.max_s"] = med(x["max_error_m"] for x in so)
        out[f"{o}.rmse_f"] = med(x["rmse_m"] for x in fo)
        out[f"{o}.rmse_s"] = med(x["rmse_m"] for x in so)
        out[f"{o}.floor_rmse"] = med(r["floor"][k][0] for r in runs)
        out[f"{o}.floor_max"] = med(r["floor"][k][1] for r in runs)
    return out


def smoother_real(ctx):
    return smoother_values(ctx, "smoother_real", ctx.real(), "scenarios/outage-10s-middle.yaml", 50)


def smoother_route(ctx):
    poses = os.path.join(ctx.data, "odometry", "poses", "00.txt")
    times = os.path.join(ctx.data, "odometry", "sequences", "00", "times.txt")
    drive = ctx.render("route00-1200m", ["--route", poses, "--times", times, "--length-m", "1200"], "smoother_route")
    return smoother_values(ctx, "smoother_route", drive, "scenarios/route-outage-30s-60s.yaml", 20)


# name -> (fast?, function). Order: cheap first.
RUNS = {
    "devkit": (True, devkit),
    "mcap": (True, mcap),
    "ekf_nees_test": (True, ekf_nees_test),
    "consistency_sim": (True, consistency_sim),
    "vo_real": (True, vo_real),
    "vo_real_velocity": (True, vo_real_velocity),
    "sweep_real": (True, sweep_real),
    "dark_real": (True, dark_real),
    "tunnel_real": (True, tunnel_real),
    "tunnel_bound": (True, tunnel_bound),
    "replay_urban": (False, replay_urban),
    "urban_bound": (False, urban_bound),
    "urban_2drms": (False, urban_2drms),
    "lever_arm": (False, lever_arm),
    "sweep_synth": (False, sweep_synth),
    "tunnel_synth": (False, tunnel_synth),
    "tunnel_gps": (False, tunnel_gps),
    "vo_synth": (False, vo_synth),
    "vo_motorway": (False, vo_motorway),
    "smoother_real": (False, smoother_real),
    "smoother_route": (False, smoother_route),
}


# --- comparison ------------------------------------------------------------

def fmt_like(token, value):
    """`value` printed as `token` is: same decimals, thousands commas, sign."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "nan"
    decimals = len(token.split(".")[1]) if "." in token else 0
    text = f"{value:,.{decimals}f}" if "," in token else f"{value:.{decimals}f}"
    if text.startswith("-") and float(text.replace(",", "")) == 0:
        text = text[1:]
    if token.startswith("+") and not text.startswith("-"):
        text = "+" + text
    return text


def today_text(published, values):
    tokens = list(NUMBER.finditer(published))
    pieces, last = [], 0
    for m, v in zip(tokens, values):
        pieces.append(published[last:m.start()])
        pieces.append(fmt_like(m.group(0), v))
        last = m.end()
    pieces.append(published[last:])
    return "".join(pieces)


def read_figures(path):
    with open(path, newline="") as f:
        rows = [r for r in csv.reader(f, delimiter="\t", quoting=csv.QUOTE_NONE) if r and not r[0].startswith("#")]
    header, rows = rows[0], rows[1:]
    need = ["figure", "run", "keys", "published", "anchor"]
    if header != need:
        sys.exit(f"{path}: header must be {' '.join(need)} (tab-separated), is {header}")
    figures = []
    for n, r in enumerate(rows, start=2):
        if len(r) != len(need):
            sys.exit(f"{path}: line {n}: {len(r)} fields, want {len(need)}")
        fig = dict(zip(need, r))
        fig["keys"] = [k.strip() for k in fig["keys"].split(",")]
        if fig["run"] not in RUNS:
            sys.exit(f"{path}: line {n}: unknown run {fig['run']} (known: {', '.join(RUNS)})")
        if len(NUMBER.findall(fig["published"])) != len(fig["keys"]):
            sys.exit(f"{path}: line {n}: {len(NUMBER.findall(fig['published']))} numbers in "
                     f"'{fig['published']}' for {len(fig['keys'])} keys")
        figures.append(fig)
    return figures


def doc_check(fig, doc_lines):
    """'' if `published` is on the one line holding `anchor`, else what is wrong."""
    lines = [l for l in doc_lines if fig["anchor"] in l]
    if len(lines) != 1:
        return f"anchor '{fig['anchor']}' is on {len(lines)} lines of the documents (want 1)"
    if fig["published"] not in lines[0]:
        return f"'{fig['published']}' is not on the line of '{fig['anchor']}'"
    return ""


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--fast", action="store_true", help="only the runs of a few minutes (the test command's)")
    ap.add_argument("--only", action="append", default=[], metavar="RUN", help="only this run (repeatable)")
    ap.add_argument("--list", action="store_true", help="list the runs and figures, run nothing")
    ap.add_argument("--bin-dir", default=os.path.join(ROOT, "build", "bin"), help="built programs (build/bin)")
    ap.add_argument("--data", default=os.path.join(ROOT, "..", "shared", "data", "kitti"),
                    help="shared KITTI excerpts (../shared/data/kitti)")
    ap.add_argument("--figures", default=os.path.join(HERE, "figures.tsv"), help="published values")
    ap.add_argument("--doc", action="append", metavar="FILE",
                    help="a document the figures are on (repeatable; default: " + ", ".join(DOCS) + ")")
    ap.add_argument("--work", help="scratch folder for drives, VO caches and MCAP files (default: a new "
                                   "temporary folder, removed at the end)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="parallel replays in sweeps")
    ap.add_argument("--verbose", "-v", action="store_true", help="print each command as it starts")
    ap.add_argument("--values", metavar="FILE", help="also write every value each run measured (JSON)")
    args = ap.parse_args()
    for r in args.only:
        if r not in RUNS:
            ap.error(f"--only {r}: unknown run (known: {', '.join(RUNS)})")

    figures = read_figures(args.figures)
    doc_lines = []
    for doc in args.doc or [os.path.join(ROOT, d) for d in DOCS]:
        with open(doc) as f:
            doc_lines += f.read().splitlines()
    selected = [r for r in RUNS if (not args.only or r in args.only) and (not args.fast or RUNS[r][0])]
    # Every line of figures.tsv against the document, whatever runs: cheap, and
    # a published value changed in one place only shows up in --fast too.
    doc_problems = [(f, p) for f in figures for p in [doc_check(f, doc_lines)] if p]
    if args.list:
        for r in RUNS:
            n = sum(1 for f in figures if f["run"] == r)
            print(f"{r:18} {'fast' if RUNS[r][0] else 'full':5} {n} figures")
        for f, p in doc_problems:
            print(f"DOC {f['figure']}: {p}")
        return 1 if doc_problems else 0
    if not os.path.isdir(os.path.join(args.data, REAL)):
        print(f"SKIP: {os.path.abspath(args.data)} has no {REAL} (the shared KITTI excerpts); "
              "no figure was checked", flush=True)
        return 77

    own_work = args.work is None
    args.work = os.path.abspath(args.work or tempfile.mkdtemp(prefix="locaid-figures-"))
    os.makedirs(args.work, exist_ok=True)
    ctx = Context(args)
    values, failed, seconds = {}, {}, {}
    try:
        for r in selected:
            print(f"[{time.strftime('%H:%M:%S')}] {r} ...", file=sys.stderr, flush=True)
            t0 = time.monotonic()
            try:
                values[r] = RUNS[r][1](ctx)
            except (RunFailed, KeyError, OSError) as e:
                failed[r] = f"{type(e).__name__}: {e}"
            seconds[r] = time.monotonic() - t0
            print(f"[{time.strftime('%H:%M:%S')}] {r}: {seconds[r]:.0f} s"
                  + (" FAILED" if r in failed else ""), file=sys.stderr, flush=True)
            if args.values:  # after every run: an interrupted run keeps what it measured
                with open(args.values, "w") as f:
                    json.dump({"runs": values, "seconds": seconds, "failed": failed, "commands": ctx.commands}, f,
                              indent=1)
    finally:
        if own_work:
            shutil.rmtree(args.work, ignore_errors=True)

    rows, bad = [], 0
    for fig, problem in doc_problems:
        if fig["run"] not in selected:
            rows.append((fig, "(not run)", "DOC", problem))
            bad += 1
    for fig in figures:
        if fig["run"] not in selected:
            continue
        doc_problem = doc_check(fig, doc_lines)
        if fig["run"] in failed:
            rows.append((fig, "(run failed)", "FAIL"))
            bad += 1
            continue
        missing = [k for k in fig["keys"] if k not in values[fig["run"]]]
        if missing:
            rows.append((fig, f"(no value {', '.join(missing)})", "FAIL"))
            bad += 1
            continue
        today = today_text(fig["published"], [values[fig["run"]][k] for k in fig["keys"]])
        status = "OK" if today == fig["published"] else "DIFF"
        if doc_problem:
            status = "DOC" if status == "OK" else status + "+DOC"
        if status != "OK":
            bad += 1
        rows.append((fig, today, status, doc_problem))

    order = list(RUNS)
    rows.sort(key=lambda row: order.index(row[0]["run"]))  # stable: figures.tsv order within a run
    w_fig = max([len(r[0]["figure"]) for r in rows] + [6])
    w_pub = max([len(r[0]["published"]) for r in rows] + [9])
    w_today = max([len(r[1]) for r in rows] + [5])
    print(f"{'figure':{w_fig}}  {'published':{w_pub}}  {'today':{w_today}}  status")
    run = None
    for row in rows:
        fig, today, status = row[0], row[1], row[2]
        if fig["run"] != run:
            run = fig["run"]
            print(f"-- {run} ({seconds.get(run, 0):.0f} s)")
        print(f"{fig['figure']:{w_fig}}  {fig['published']:{w_pub}}  {today:{w_today}}  {status}")
        if len(row) > 3 and row[3]:
            print(f"{'':{w_fig}}  ^ {row[3]}")
    for r, why in failed.items():
        print(f"\nrun {r} failed:\n{why}")
    print("\ncommands (from the repository root):")
    for r, c in ctx.commands:
        print(f"  [{r}] {c}")
    n = len(rows)
    print(f"\n{n - bad} of {n} figures as published; {bad} not"
          f" ({'--only ' + ' '.join(args.only) if args.only else '--fast' if args.fast else 'full run'}"
          f", {sum(seconds.values()):.0f} s)")
    return 1 if bad or failed else 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except KeyboardInterrupt:
        sys.exit(130)
