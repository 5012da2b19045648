#!/usr/bin/python3
"""How long StopSession takes while sessions are still rendering their drive.

Starts a real locaid-server on 127.0.0.1 (--max-concurrent-renders N), and
per round starts N synthetic sessions of full-size drives (--frames 2000: a
render of a minute or more each), waits --wait-s for the renders to be under
way, then stops all N at once (StopSession with remove, one thread and one
connection each) while ListSessions is called from the main thread. Prints
one JSON object: every StopSession and ListSessions time in ms (client wall
clock, call to answer) and their min / median / max.

  bench/server/stop_latency.py [--rounds 5] [--renders 3] [--frames 2000] [--server build/bin/locaid-server]

Needs the Python stubs the build generates (build/python). The target is
200 ms (docs/benchmarks.md, "Service"); tests/server check that a stop cancels the render, not
how fast it returns: timing is measured here.
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


def stats(values):
    return {"min": min(values), "median": statistics.median(values), "max": max(values), "n": len(values)}


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    build = os.path.join(here, "..", "..", "build")
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rounds", type=int, default=5, help="rounds of N renders stopped at once (default 5)")
    ap.add_argument("--renders", type=int, default=3, help="renders at once (default 3)")
    ap.add_argument("--frames", type=int, default=2000, help="frames per synthetic drive (default 2000)")
    ap.add_argument("--wait-s", type=float, default=0.5, help="from the starts to the stops (default 0.5)")
    ap.add_argument("--server", default=os.path.join(build, "bin", "locaid-server"))
    ap.add_argument("--stubs", default=os.path.join(build, "python"))
    args = ap.parse_args()
    if args.rounds < 1 or args.renders < 1 or args.frames < 2 or args.wait_s < 0:
        ap.error("--rounds, --renders >= 1, --frames >= 2, --wait-s >= 0")
    if not os.access(args.server, os.X_OK):
        ap.error(f"{args.server}: not an executable (build first, or pass --server)")
    sys.path.insert(0, args.stubs)
    try:
        import grpc
        from locaid.v1 import localization_pb2 as pb, localization_pb2_grpc as rpc
    except ImportError as e:
        ap.error(f"{e} (the Python stubs are built into {args.stubs})")

    tmp = tempfile.mkdtemp(prefix="locaid_stop_latency_")
    try:
        with LocalServer(args.server, tmp, ["--max-concurrent-renders", str(args.renders)]) as server:
            run(args, pb, rpc, grpc, server.address)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def run(args, pb, rpc, grpc, address):
    # One connection per stopper (a channel of its own, not shared with the others').
    own = [rpc.LocalizationStub(grpc.insecure_channel(address, options=[("grpc.use_local_subchannel_pool", 1)]))
           for _ in range(args.renders)]
    main_stub = rpc.LocalizationStub(grpc.insecure_channel(address))
    main_stub.ListSessions(pb.ListSessionsRequest(), timeout=30)  # connected before timing
    for stub in own:
        stub.ListSessions(pb.ListSessionsRequest(), timeout=30)
    stop_ms, list_ms, states = [], [], []
    for round_ in range(args.rounds):
        ids = []
        for i in range(args.renders):
            s = main_stub.StartSession(pb.StartSessionRequest(
                synthetic=pb.SyntheticSource(seed=round_ * args.renders + i + 1, frames=args.frames),
                playback_rate=0), timeout=30)
            ids.append(s.id)
        time.sleep(args.wait_s)
        results = [None] * len(ids)

        def stop(i):
            t0 = time.monotonic()
            out = own[i].StopSession(pb.StopSessionRequest(session_id=ids[i], remove=True), timeout=30)
            results[i] = ((time.monotonic() - t0) * 1e3, pb.SessionState.Name(out.state))

        threads = [threading.Thread(target=stop, args=(i,)) for i in range(len(ids))]
        for t in threads:
            t.start()
        t0 = time.monotonic()
        main_stub.ListSessions(pb.ListSessionsRequest(), timeout=30)
        list_ms.append((time.monotonic() - t0) * 1e3)
        for t in threads:
            t.join()
        for ms, state in results:
            stop_ms.append(ms)
            states.append(state)
        left = len(main_stub.ListSessions(pb.ListSessionsRequest(), timeout=30).sessions)
        print(f"round {round_ + 1}: stop {' '.join('%.1f' % r[0] for r in results)} ms, "
              f"list {list_ms[-1]:.1f} ms, sessions left {left}", file=sys.stderr)
    print(json.dumps({"rounds": args.rounds, "renders": args.renders, "frames": args.frames,
                      "wait_s": args.wait_s, "stop_ms": stats(stop_ms), "list_sessions_ms": stats(list_ms),
                      "stop_ms_all": [round(v, 1) for v in stop_ms],
                      "states": sorted(set(states))}, indent=1))


if __name__ == "__main__":
    main()
