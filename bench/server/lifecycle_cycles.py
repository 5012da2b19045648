#!/usr/bin/python3
"""Memory and disk of locaid-server over many session start/stop cycles.

Starts a real locaid-server on 127.0.0.1 and runs N cycles; each cycle starts
and stops (with remove, and without: those are pruned by max_ended_sessions)
one session of every source kind: live, synthetic (a tiny render) and a KITTI
drive rendered once beforehand. Every `--every` cycles it samples the
server's resident memory (/proc/PID/status VmRSS) and the bytes under its
work directory, and prints one JSON object at the end:

  bench/server/lifecycle_cycles.py [--cycles 1000] [--every 100] [--server build/bin/locaid-server]

Needs the Python stubs the build generates (build/python) and locaid-synth.
"""
import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time


def dir_bytes(path):
    total = 0
    for root, _, files in os.walk(path):
        for f in files:
            try:
                total += os.path.getsize(os.path.join(root, f))
            except OSError:
                pass
    return total


def rss_bytes(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    return 0


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    build = os.path.join(here, "..", "..", "build")
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cycles", type=int, default=1000)
    ap.add_argument("--every", type=int, default=100)
    ap.add_argument("--server", default=os.path.join(build, "bin", "locaid-server"))
    ap.add_argument("--synth", default=os.path.join(build, "bin", "locaid-synth"))
    ap.add_argument("--stubs", default=os.path.join(build, "python"))
    args = ap.parse_args()
    if args.cycles < 1 or args.every < 1:
        ap.error("--cycles and --every must be >= 1")
    sys.path.insert(0, args.stubs)
    import grpc
    from locaid.v1 import localization_pb2 as pb, localization_pb2_grpc as rpc

    tmp = tempfile.mkdtemp(prefix="locaid_cycles_")
    drive_root = os.path.join(tmp, "kitti")
    subprocess.run([args.synth, "-q", "--out", drive_root, "--frames", "5", "--width", "160", "--height", "64",
                    "--seed", "1"], check=True)
    drive = next(os.path.join(drive_root, d) for d in os.listdir(drive_root) if d.endswith("_sync"))
    work = os.path.join(tmp, "work")
    port_file = os.path.join(tmp, "port")
    log = open(os.path.join(tmp, "server.log"), "w")
    server = subprocess.Popen([args.server, "--listen", "127.0.0.1:0", "--port-file", port_file,
                               "--work-dir", work, "--max-ended-sessions", "16"], stdout=log, stderr=log)
    try:
        for _ in range(1000):
            if os.path.exists(port_file) and os.path.getsize(port_file) > 0:
                break
            time.sleep(0.01)
        with open(port_file) as f:
            port = int(f.read())
        stub = rpc.LocalizationStub(grpc.insecure_channel(f"127.0.0.1:{port}"))
        live = pb.LiveSource(fx=100, fy=100, cx=16, cy=12, baseline_m=0.5, width=32, height=24)
        requests = {
            "live": pb.StartSessionRequest(live=live),
            "synthetic": pb.StartSessionRequest(synthetic=pb.SyntheticSource(
                seed=3, frames=2, options_yaml="width: 64\nheight: 48\n")),
            "kitti": pb.StartSessionRequest(kitti=pb.KittiSource(path=drive), playback_rate=0),
        }
        samples = []
        t0 = time.monotonic()
        for cycle in range(1, args.cycles + 1):
            for kind, req in requests.items():
                s = stub.StartSession(req, timeout=30)
                if kind == "synthetic":  # let the render finish sometimes, cancel it other times
                    time.sleep(0.02 if cycle % 2 else 0)
                stub.StopSession(pb.StopSessionRequest(session_id=s.id, remove=cycle % 3 != 0), timeout=30)
            if cycle % args.every == 0 or cycle == 1:
                n = len(stub.ListSessions(pb.ListSessionsRequest(), timeout=30).sessions)
                samples.append({"cycle": cycle, "rss_bytes": rss_bytes(server.pid), "work_dir_bytes": dir_bytes(work),
                                "sessions_listed": n, "elapsed_s": round(time.monotonic() - t0, 1)})
                print(json.dumps(samples[-1]), file=sys.stderr)
        first, last = samples[0], samples[-1]
        mid = samples[len(samples) // 2]
        print(json.dumps({"cycles": args.cycles, "kinds": list(requests), "samples": samples,
                          "rss_growth_second_half_bytes": last["rss_bytes"] - mid["rss_bytes"],
                          "rss_first_bytes": first["rss_bytes"], "rss_last_bytes": last["rss_bytes"],
                          "work_dir_last_bytes": last["work_dir_bytes"]}, indent=1))
    finally:
        server.send_signal(signal.SIGTERM)
        server.wait(timeout=30)
        log.close()


if __name__ == "__main__":
    main()
