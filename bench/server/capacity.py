#!/usr/bin/python3
"""How many real-time sessions of the real KITTI excerpt one server keeps.

For each N of --sessions, starts a fresh locaid-server on 127.0.0.1, starts N
sessions of the drive at --rate (1 = real time) and subscribes to each one's
poses (one gRPC channel per session). After --warmup-s it measures for
--window-s: per session the poses per second received, and over all poses of
the window the processing latency (PoseUpdate.processing_latency_ms), the
lateness against real time (behind_real_time_s), and the delivery delay
(receipt minus published_unix_ns). Also: how many sessions flagged
falling_behind and how soon after their start (the first pose that says so) and how soon after its lag began (the
first pose of the unbroken run of late poses, > 5 ms, that ends in the flag),
the server's CPU use over the window (cores, /proc), and per-session stats
(GetStats) at the end of the window. Prints one JSON object (a line per N
goes to stderr as it runs).

  bench/server/capacity.py --drive DIR [--sessions 1 8 16 24 32] [--rate 1]
      [--warmup-s 2] [--window-s 15] [--server-arg=--max-cpu-cores=1.8 ...]

The drive must last longer than warmup + window (the shared excerpt: 19.8 s).
Needs the Python stubs the build generates (build/python).
"""
import argparse
import json
import os
import shutil
import statistics
import sys
import tempfile
import threading
import time

from local_server import LocalServer


def pct(values, q):
    if not values:
        return None
    v = sorted(values)
    return v[min(len(v) - 1, int(round(q / 100.0 * (len(v) - 1))))]


def summary(values):
    if not values:
        return {"n": 0}
    return {"n": len(values), "p50": pct(values, 50), "p90": pct(values, 90), "p99": pct(values, 99),
            "max": max(values)}


def cpu_seconds(pid):
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def detection_delay_s(lateness, on_time_s=0.005):
    """Seconds from the onset of a lag that never recovered (the first pose of the late run that
    ends in the first falling_behind pose: every pose of it later than on_time_s) to that flag."""
    if not lateness or not lateness[-1][2]:
        return None
    onset = len(lateness) - 1
    while onset > 0 and lateness[onset - 1][1] > on_time_s:
        onset -= 1
    return lateness[-1][0] - lateness[onset][0]


class Subscriber(threading.Thread):
    """Reads one session's pose stream; keeps what arrived inside the window."""

    def __init__(self, pb, rpc, grpc, address, session_id, started):
        super().__init__(daemon=True)
        self.channel = grpc.insecure_channel(address, options=[("grpc.use_local_subchannel_pool", 1)])
        self.stub = rpc.LocalizationStub(self.channel)
        self.pb, self.session_id, self.started = pb, session_id, started
        self.window = None  # (t0, t1) monotonic
        self.received, self.latency_ms, self.behind_s, self.delay_ms = 0, [], [], []
        self.first_behind_s = None  # seconds after the session's start of the first falling_behind pose
        self.lateness = []  # (receipt, behind_real_time_s, falling_behind) of every pose until the first flag
        self.error = None

    def run(self):
        try:
            for p in self.stub.StreamPoses(self.pb.StreamPosesRequest(session_id=self.session_id)):
                now = time.monotonic()
                if self.first_behind_s is None:
                    self.lateness.append((now, p.behind_real_time_s, p.falling_behind))
                    if p.falling_behind:
                        self.first_behind_s = now - self.started
                if self.window and self.window[0] <= now <= self.window[1]:
                    self.received += 1
                    self.latency_ms.append(p.processing_latency_ms)
                    self.behind_s.append(p.behind_real_time_s)
                    self.delay_ms.append((time.time_ns() - p.published_unix_ns) / 1e6)
        except Exception as e:  # the stream ends with the session (stopped at the end of the run)
            if "CANCELLED" not in str(e):
                self.error = str(e)


def run_n(args, pb, rpc, grpc, n):
    tmp = tempfile.mkdtemp(prefix="locaid_capacity_")
    try:
        with LocalServer(args.server, tmp, ["--max-sessions", str(max(n, 16))] + args.server_arg) as server:
            return measure(args, pb, rpc, grpc, n, server)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def measure(args, pb, rpc, grpc, n, server):
    address = server.address
    stub = rpc.LocalizationStub(grpc.insecure_channel(address))
    subs, refused = [], []
    for i in range(n):
        try:
            s = stub.StartSession(pb.StartSessionRequest(kitti=pb.KittiSource(path=args.drive),
                                                         playback_rate=args.rate), timeout=30)
        except grpc.RpcError as e:
            refused.append(e.details())
            continue
        sub = Subscriber(pb, rpc, grpc, address, s.id, time.monotonic())
        sub.start()
        subs.append(sub)
    t0 = time.monotonic() + args.warmup_s
    for sub in subs:
        sub.window = (t0, t0 + args.window_s)
    time.sleep(max(0.0, t0 - time.monotonic()))
    cpu0, wall0 = cpu_seconds(server.process.pid), time.monotonic()
    time.sleep(args.window_s)
    cores = (cpu_seconds(server.process.pid) - cpu0) / (time.monotonic() - wall0)
    stats = [stub.GetStats(pb.GetStatsRequest(session_id=sub.session_id), timeout=30) for sub in subs]
    for sub in subs:
        stub.StopSession(pb.StopSessionRequest(session_id=sub.session_id, remove=True), timeout=30)
    for sub in subs:
        sub.join(timeout=10)
    fps = [sub.received / args.window_s for sub in subs]
    behind = [s.behind_real_time_s for s in stats]
    flagged = [sub.first_behind_s for sub in subs if sub.first_behind_s is not None]
    return {
        "sessions": n, "admitted": len(subs), "refused": len(refused),
        "refusal": refused[0] if refused else None,
        "fps_per_session": {"min": min(fps) if fps else None, "median": statistics.median(fps) if fps else None},
        "processing_latency_ms": summary([v for sub in subs for v in sub.latency_ms]),
        "behind_real_time_s": summary([v for sub in subs for v in sub.behind_s]),
        "delivery_delay_ms": summary([v for sub in subs for v in sub.delay_ms]),
        "falling_behind_sessions": len(flagged),
        "first_falling_behind_s_after_start": summary(flagged),
        "falling_behind_detection_s": summary([d for d in (detection_delay_s(sub.lateness) for sub in subs)
                                               if d is not None]),
        "stats_behind_real_time_s_end": summary(behind),
        "stats_cpu_cores_per_session": summary([s.cpu_cores for s in stats]),
        "server_cpu_cores": cores,
        "subscriber_errors": [sub.error for sub in subs if sub.error],
    }


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    build = os.path.join(here, "..", "..", "build")
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--drive", required=True, help="KITTI drive folder (e.g. ../shared/data/kitti/raw/.../..._extract)")
    ap.add_argument("--sessions", type=int, nargs="+", default=[1, 8, 16, 24, 32])
    ap.add_argument("--rate", type=float, default=1.0, help="playback rate of every session (default 1)")
    ap.add_argument("--warmup-s", type=float, default=2.0)
    ap.add_argument("--window-s", type=float, default=15.0)
    ap.add_argument("--server", default=os.path.join(build, "bin", "locaid-server"))
    ap.add_argument("--server-arg", action="append", default=[], help="extra locaid-server flag (repeatable)")
    ap.add_argument("--stubs", default=os.path.join(build, "python"))
    args = ap.parse_args()
    if min(args.sessions) < 1 or args.rate <= 0 or args.warmup_s < 0 or args.window_s <= 0:
        ap.error("--sessions >= 1, --rate > 0, --warmup-s >= 0, --window-s > 0")
    if max(args.sessions) > 256:
        ap.error("--sessions: at most 256 (a bounded load test)")
    if not os.access(args.server, os.X_OK):
        ap.error(f"{args.server}: not an executable (build first, or pass --server)")
    args.drive = os.path.abspath(args.drive)
    if not os.path.isdir(args.drive):
        ap.error(f"--drive {args.drive}: not a folder")
    sys.path.insert(0, args.stubs)
    try:
        import grpc
        from locaid.v1 import localization_pb2 as pb, localization_pb2_grpc as rpc
    except ImportError as e:
        ap.error(f"{e} (the Python stubs are built into {args.stubs})")
    results = []
    for n in args.sessions:
        r = run_n(args, pb, rpc, grpc, n)
        results.append(r)
        print(f"N={n}: admitted {r['admitted']}, fps min/median {r['fps_per_session']['min']}/"
              f"{r['fps_per_session']['median']}, processing p50/p99 {r['processing_latency_ms'].get('p50')}/"
              f"{r['processing_latency_ms'].get('p99')} ms, behind p99 {r['behind_real_time_s'].get('p99')} s, "
              f"falling behind {r['falling_behind_sessions']}, server {r['server_cpu_cores']:.2f} cores",
              file=sys.stderr)
    print(json.dumps({"drive": args.drive, "rate": args.rate, "warmup_s": args.warmup_s, "window_s": args.window_s,
                      "cores": os.cpu_count(), "server_args": args.server_arg, "results": results}, indent=1))


if __name__ == "__main__":
    main()
