#!/usr/bin/python3
"""Contract suite: a real locaid-server driven from proto/ alone.

Stubs are generated at test time from proto/locaid/v1/*.proto (and the
standard grpc.health.v1 service, written out here) with Debian's
python3-grpc-tools into a temporary folder: nothing of the project's C++ or
its own Python client is used, as an outside client in another language would
see the service. Every RPC gets valid, boundary and hostile input and the
exact status code is asserted; after each case the server must still answer
health checks. Bounded: a few seconds of sessions, a handful of threads.

    tests/contract/contract_suite.py --server build/bin/locaid-server --proto proto [-v]

Registered in CTest (tests/CMakeLists.txt), so deploy/test.sh runs it.
"""
import argparse
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import unittest

import grpc
from grpc_tools import protoc

HEALTH_PROTO = """syntax = "proto3";
package grpc.health.v1;
message HealthCheckRequest { string service = 1; }
message HealthCheckResponse {
  enum ServingStatus { UNKNOWN = 0; SERVING = 1; NOT_SERVING = 2; SERVICE_UNKNOWN = 3; }
  ServingStatus status = 1;
}
service Health { rpc Check(HealthCheckRequest) returns (HealthCheckResponse); }
"""

ARGS = None
pb = rpc = hpb = hrpc = None  # generated modules


def generate_stubs(proto_root, out):
    # The file sits outside a grpc/ folder so its module does not collide with
    # the grpc package; the proto package (the wire name) is grpc.health.v1.
    health_dir = os.path.join(out, "proto_health", "locaid_contract_health")
    os.makedirs(health_dir)
    with open(os.path.join(health_dir, "health.proto"), "w") as f:
        f.write(HEALTH_PROTO)
    for root, rel in ((proto_root, "locaid/v1/localization.proto"),
                      (os.path.join(out, "proto_health"), "locaid_contract_health/health.proto")):
        rc = protoc.main(["protoc", "-I" + root, "--python_out=" + out, "--grpc_python_out=" + out,
                          os.path.join(root, rel)])
        if rc != 0:
            sys.exit(f"protoc failed on {rel}")
    sys.path.insert(0, out)
    global pb, rpc, hpb, hrpc
    from locaid.v1 import localization_pb2 as pb_mod, localization_pb2_grpc as rpc_mod
    from locaid_contract_health import health_pb2 as hpb_mod, health_pb2_grpc as hrpc_mod
    pb, rpc, hpb, hrpc = pb_mod, rpc_mod, hpb_mod, hrpc_mod


class Server:
    """build/bin/locaid-server on 127.0.0.1, port from --port-file."""

    def __init__(self, workdir, extra=()):
        self.dir = tempfile.mkdtemp(dir=workdir)
        port_file = os.path.join(self.dir, "port")
        self.log = open(os.path.join(self.dir, "server.log"), "w")
        self.proc = subprocess.Popen([ARGS.server, "--listen", "127.0.0.1:0", "--port-file", port_file,
                                      "--work-dir", os.path.join(self.dir, "work"), *extra],
                                     stdout=self.log, stderr=subprocess.STDOUT)
        self.port = 0
        for _ in range(1000):
            if os.path.exists(port_file):
                with open(port_file) as f:
                    text = f.read().strip()
                if text:
                    self.port = int(text)
                    break
            if self.proc.poll() is not None:
                break
            time.sleep(0.01)
        if not self.port:
            with open(os.path.join(self.dir, "server.log")) as f:
                raise RuntimeError("locaid-server did not start: " + f.read())
        self.channel = grpc.insecure_channel(f"127.0.0.1:{self.port}",
                                             options=[("grpc.max_send_message_length", 64 << 20)])
        self.stub = rpc.LocalizationStub(self.channel)
        self.health = hrpc.HealthStub(self.channel)

    def stop(self):
        self.channel.close()
        self.proc.send_signal(signal.SIGTERM)
        try:
            self.proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            raise
        self.log.close()


def live_source(w=32, h=24):
    return pb.LiveSource(fx=100, fy=100, cx=w / 2, cy=h / 2, baseline_m=0.5, width=w, height=h)


class Contract(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.workdir = tempfile.mkdtemp(prefix="locaid_contract_")
        cls.server = Server(cls.workdir)
        cls.stub = cls.server.stub

    @classmethod
    def tearDownClass(cls):
        cls.server.stop()
        shutil.rmtree(cls.workdir, ignore_errors=True)

    def tearDown(self):
        # Whatever a case did, the server keeps serving.
        for service in ("", "locaid.v1.Localization"):
            r = self.server.health.Check(hpb.HealthCheckRequest(service=service), timeout=5)
            self.assertEqual(r.status, hpb.HealthCheckResponse.SERVING, service)

    def code(self, call, request, timeout=10):
        try:
            call(request, timeout=timeout)
            return grpc.StatusCode.OK, ""
        except grpc.RpcError as e:
            return e.code(), e.details() or ""

    def start_live(self, **kw):
        return self.stub.StartSession(pb.StartSessionRequest(live=live_source(), **kw), timeout=10)

    def stop(self, sid, remove=False):
        return self.stub.StopSession(pb.StopSessionRequest(session_id=sid, remove=remove), timeout=10)

    # ------------------------------------------------------------ unknown ids
    def test_unknown_and_hostile_ids_are_not_found_with_a_short_message(self):
        for sid in ("s1", "nope", "x" * (1 << 20), "\u00e9\u4e2d", "s0000000000000"):
            for call, req in ((self.stub.GetSession, pb.GetSessionRequest(session_id=sid)),
                              (self.stub.GetStats, pb.GetStatsRequest(session_id=sid)),
                              (self.stub.StopSession, pb.StopSessionRequest(session_id=sid)),
                              (self.stub.SetScenario, pb.SetScenarioRequest(
                                  session_id=sid, scenario=pb.Scenario(name="open-sky"))),
                              (self.stub.InjectOutage, pb.InjectOutageRequest(
                                  session_id=sid, action=pb.InjectOutageRequest.START_NOW)),
                              (self.stub.InjectCameraFault, pb.InjectCameraFaultRequest(
                                  session_id=sid, action=pb.InjectCameraFaultRequest.STOP_NOW))):
                code, msg = self.code(call, req)
                self.assertEqual(code, grpc.StatusCode.NOT_FOUND, (call, sid[:20], msg[:100]))
                self.assertLessEqual(len(msg), 1100)
        code, _ = self.code(self.stub.GetSession, pb.GetSessionRequest(session_id=""))
        self.assertEqual(code, grpc.StatusCode.INVALID_ARGUMENT)
        stream = self.stub.StreamPoses(pb.StreamPosesRequest(session_id="nope"), timeout=10)
        with self.assertRaises(grpc.RpcError) as e:
            next(stream)
        self.assertEqual(e.exception.code(), grpc.StatusCode.NOT_FOUND)

    # --------------------------------------------------------- StartSession
    def test_start_session_rejects_bad_numbers_before_ok(self):
        bad = [
            pb.StartSessionRequest(),  # no source
            pb.StartSessionRequest(live=live_source(), playback_rate=math.nan),
            pb.StartSessionRequest(live=live_source(), playback_rate=1e-300),
            pb.StartSessionRequest(live=live_source(), playback_rate=-1),
            pb.StartSessionRequest(live=live_source(), playback_rate=math.inf),
            pb.StartSessionRequest(live=pb.LiveSource(fx=math.nan, fy=1, baseline_m=1, width=8, height=8)),
            pb.StartSessionRequest(live=pb.LiveSource(fx=1, fy=1, baseline_m=0, width=8, height=8)),
            pb.StartSessionRequest(live=live_source(), scenario=pb.Scenario(name="no-such")),
            pb.StartSessionRequest(live=live_source(), scenario=pb.Scenario(yaml="gps: [")),
            pb.StartSessionRequest(live=live_source(), vo_method="no-such"),
            pb.StartSessionRequest(live=live_source(), scenario=pb.Scenario(
                yaml="base: open-sky\noutages:\n  - {start_s: 1e300, duration_s: 1}\n")),
            pb.StartSessionRequest(live=live_source(), scenario=pb.Scenario(
                yaml="base: open-sky\noutages:\n  - {start_s: 1, duration_s: 1e300}\n")),
            pb.StartSessionRequest(kitti=pb.KittiSource(path="")),
            pb.StartSessionRequest(kitti=pb.KittiSource(path="/nonexistent/drive")),
            pb.StartSessionRequest(kitti=pb.KittiSource(path="/" + "p" * (31 << 20))),
            pb.StartSessionRequest(kitti=pb.KittiSource(path=self.workdir, first_frame=-1)),
            pb.StartSessionRequest(kitti=pb.KittiSource(path=self.workdir, first_frame=10, last_frame=5)),
            pb.StartSessionRequest(synthetic=pb.SyntheticSource(frames=100000)),
            pb.StartSessionRequest(synthetic=pb.SyntheticSource(frames=1)),
            pb.StartSessionRequest(synthetic=pb.SyntheticSource(frames=20, options_yaml="width: [")),
            pb.StartSessionRequest(synthetic=pb.SyntheticSource(frames=20, options_yaml="colour: red")),
            pb.StartSessionRequest(synthetic=pb.SyntheticSource(frames=20, options_yaml="width: 100000")),
            pb.StartSessionRequest(synthetic=pb.SyntheticSource(frames=20, options_yaml="frame_rate_hz: 0")),
            pb.StartSessionRequest(synthetic=pb.SyntheticSource(frames=20, options_yaml="noise_sigma_dn: .nan")),
        ]
        before = len(self.stub.ListSessions(pb.ListSessionsRequest(), timeout=10).sessions)
        for req in bad:
            code, msg = self.code(self.stub.StartSession, req, timeout=60)
            self.assertEqual(code, grpc.StatusCode.INVALID_ARGUMENT, (str(req)[:200], msg[:200]))
            self.assertLessEqual(len(msg), 1100)
        after = len(self.stub.ListSessions(pb.ListSessionsRequest(), timeout=10).sessions)
        self.assertEqual(before, after, "a refused request left a session behind")
        empty_dir = tempfile.mkdtemp(dir=self.workdir)
        code, _ = self.code(self.stub.StartSession, pb.StartSessionRequest(kitti=pb.KittiSource(path=empty_dir)))
        self.assertEqual(code, grpc.StatusCode.FAILED_PRECONDITION)

    def test_boundary_rates_are_accepted(self):
        for rate in (0.0, 0.001, 1000.0):
            s = self.start_live(playback_rate=rate)
            self.assertTrue(s.id.startswith("s") and len(s.id) == 13, s.id)
            self.stop(s.id, remove=True)

    # ----------------------------------------------------------- lifecycle
    def test_controls_follow_the_session_state(self):
        s = self.start_live()
        self.assertEqual(s.state, pb.SESSION_STATE_RUNNING)
        ok = self.stub.InjectOutage(pb.InjectOutageRequest(session_id=s.id, action=pb.InjectOutageRequest.START_NOW),
                                    timeout=10)
        self.assertEqual(ok.id, s.id)
        code, _ = self.code(self.stub.InjectOutage, pb.InjectOutageRequest(
            session_id=s.id, action=pb.InjectOutageRequest.WINDOW, start_s=-1, duration_s=1))
        self.assertEqual(code, grpc.StatusCode.INVALID_ARGUMENT)
        code, _ = self.code(self.stub.InjectOutage, pb.InjectOutageRequest(
            session_id=s.id, action=pb.InjectOutageRequest.START_NOW, duration_s=math.nan))
        self.assertEqual(code, grpc.StatusCode.INVALID_ARGUMENT)
        for huge in (1e300, 1e7, -1e300):
            code, _ = self.code(self.stub.InjectOutage, pb.InjectOutageRequest(
                session_id=s.id, action=pb.InjectOutageRequest.WINDOW, start_s=1, duration_s=huge))
            self.assertEqual(code, grpc.StatusCode.INVALID_ARGUMENT, huge)
        code, _ = self.code(self.stub.InjectOutage, pb.InjectOutageRequest(
            session_id=s.id, action=pb.InjectOutageRequest.WINDOW, start_s=1e300, duration_s=1))
        self.assertEqual(code, grpc.StatusCode.INVALID_ARGUMENT)
        code, _ = self.code(self.stub.SetScenario, pb.SetScenarioRequest(session_id=s.id))
        self.assertEqual(code, grpc.StatusCode.INVALID_ARGUMENT)
        dark = pb.CameraFault(kind=pb.CameraFault.DARK, gain=0.1, noise_dn=3)
        ok = self.stub.InjectCameraFault(pb.InjectCameraFaultRequest(
            session_id=s.id, action=pb.InjectCameraFaultRequest.START_NOW, fault=dark), timeout=10)
        self.assertEqual(ok.id, s.id)
        for fault in (pb.CameraFault(), pb.CameraFault(kind=pb.CameraFault.DARK, gain=math.nan),
                      pb.CameraFault(kind=pb.CameraFault.DARK, gain=2), pb.CameraFault(kind=99),
                      pb.CameraFault(kind=pb.CameraFault.FROZEN, noise_dn=1),
                      pb.CameraFault(kind=pb.CameraFault.BLUR, blur_sigma_px=1e300),
                      pb.CameraFault(kind=pb.CameraFault.DROP, duration_s=-1)):
            code, msg = self.code(self.stub.InjectCameraFault, pb.InjectCameraFaultRequest(
                session_id=s.id, action=pb.InjectCameraFaultRequest.START_NOW, fault=fault))
            self.assertEqual(code, grpc.StatusCode.INVALID_ARGUMENT, (str(fault), msg))
        code, _ = self.code(self.stub.InjectCameraFault, pb.InjectCameraFaultRequest(
            session_id=s.id, action=pb.InjectCameraFaultRequest.WINDOW, fault=pb.CameraFault(
                kind=pb.CameraFault.DROP, start_s=1e300, duration_s=1)))
        self.assertEqual(code, grpc.StatusCode.INVALID_ARGUMENT)
        stopped = self.stop(s.id)
        self.assertEqual(stopped.state, pb.SESSION_STATE_STOPPED)
        for call, req in ((self.stub.InjectOutage, pb.InjectOutageRequest(
                              session_id=s.id, action=pb.InjectOutageRequest.START_NOW)),
                          (self.stub.SetScenario, pb.SetScenarioRequest(
                              session_id=s.id, scenario=pb.Scenario(name="open-sky"))),
                          (self.stub.InjectCameraFault, pb.InjectCameraFaultRequest(
                              session_id=s.id, action=pb.InjectCameraFaultRequest.STOP_NOW))):
            code, _ = self.code(call, req)
            self.assertEqual(code, grpc.StatusCode.FAILED_PRECONDITION)
        self.assertEqual(self.stub.GetSession(pb.GetSessionRequest(session_id=s.id), timeout=10).state,
                         pb.SESSION_STATE_STOPPED)
        self.stop(s.id, remove=True)
        code, _ = self.code(self.stub.GetSession, pb.GetSessionRequest(session_id=s.id))
        self.assertEqual(code, grpc.StatusCode.NOT_FOUND)

    def test_concurrent_start_and_stop(self):
        # 6 clients run 5 start/stop cycles each at once; every cycle must
        # complete. 6 sessions are below max_sessions (16), but
        # RESOURCE_EXHAUSTED is the documented answer at the cap, so a start
        # refused with it is retried (bounded) rather than ending the worker.
        workers, cycles, max_retries = 6, 5, 200
        done = [0] * workers
        ids = [[] for _ in range(workers)]
        errors = []

        def worker(i):
            retries = 0
            try:
                while done[i] < cycles:
                    try:
                        s = self.start_live()
                    except grpc.RpcError as e:
                        if e.code() == grpc.StatusCode.RESOURCE_EXHAUSTED and retries < max_retries:
                            retries += 1
                            time.sleep(0.05)
                            continue
                        raise
                    ids[i].append(s.id)
                    stopped = self.stop(s.id, remove=True)
                    if stopped.state != pb.SESSION_STATE_STOPPED:
                        errors.append(f"worker {i}: {s.id} stopped in state {stopped.state}")
                    done[i] += 1
            except Exception as e:  # noqa: BLE001 -- any failure of a worker fails the case
                errors.append(f"worker {i} after {done[i]} cycles: {e!r}")
        threads = [threading.Thread(target=worker, args=(i,)) for i in range(workers)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=120)  # a guard against a hang, not a speed requirement
        self.assertEqual([t.name for t in threads if t.is_alive()], [], "workers still running")
        self.assertEqual(errors, [])
        self.assertEqual(done, [cycles] * workers)
        started = {sid for per_worker in ids for sid in per_worker}
        self.assertEqual(len(started), workers * cycles, "a session id was handed out twice")
        listed = {s.id for s in self.stub.ListSessions(pb.ListSessionsRequest(), timeout=10).sessions}
        self.assertEqual(started & listed, set(), "removed sessions are still listed")

    def test_synthetic_session_is_starting_and_a_stop_cancels_its_render(self):
        # 1500 full-size frames render for minutes: a StopSession that waited
        # for the render would miss its deadline, and the session would have
        # played frames. How fast the stop returns is a benchmark figure.
        s = self.stub.StartSession(pb.StartSessionRequest(synthetic=pb.SyntheticSource(seed=5, frames=1500)),
                                   timeout=30)
        self.assertEqual(s.state, pb.SESSION_STATE_STARTING)
        stopped = self.stub.StopSession(pb.StopSessionRequest(session_id=s.id), timeout=30)
        self.assertEqual(stopped.state, pb.SESSION_STATE_STOPPED)
        after = self.stub.GetSession(pb.GetSessionRequest(session_id=s.id), timeout=10)
        self.assertEqual(after.state, pb.SESSION_STATE_STOPPED)
        self.assertEqual(after.stats.frames_in, 0, "the session played frames: the render was not cancelled")
        self.stop(s.id, remove=True)

    def test_push_stream_contract(self):
        call = self.stub.PushSensorData(iter([pb.PushRequest(frame=pb.StereoFrame(t_ns=1))]), timeout=10)
        with self.assertRaises(grpc.RpcError) as e:
            list(call)
        self.assertEqual(e.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)
        w, h = 32, 24
        gray = bytes(w * h)
        msgs = [pb.PushRequest(start=pb.PushStart(live=live_source(w, h)))]
        msgs += [pb.PushRequest(frame=pb.StereoFrame(t_ns=(i + 1) * 100_000_000, encoding=pb.IMAGE_ENCODING_GRAY8,
                                                     left=gray, right=gray)) for i in range(3)]
        msgs.append(pb.PushRequest(frame=pb.StereoFrame(t_ns=4 * 100_000_000, encoding=pb.IMAGE_ENCODING_GRAY8,
                                                        left=b"x", right=b"x")))  # wrong byte count: counted
        msgs.append(pb.PushRequest())  # empty item: rejected, stream goes on
        responses = list(self.stub.PushSensorData(iter(msgs), timeout=30))
        self.assertTrue(responses[0].HasField("session"))
        self.assertEqual(sum(r.HasField("pose") for r in responses), 3)
        self.assertTrue(any(r.HasField("rejected") for r in responses))
        sid = responses[0].session.id
        stats = self.stub.GetStats(pb.GetStatsRequest(session_id=sid), timeout=10)
        self.assertEqual(stats.frames_corrupt, 1)


class Restart(unittest.TestCase):
    def test_ids_from_before_a_restart_name_nothing(self):
        workdir = tempfile.mkdtemp(prefix="locaid_contract_restart_")
        try:
            a = Server(workdir)
            ids = {a.stub.StartSession(pb.StartSessionRequest(live=live_source()), timeout=10).id for _ in range(3)}
            a.stop()
            b = Server(workdir)
            try:
                for sid in ids:
                    with self.assertRaises(grpc.RpcError) as e:
                        b.stub.GetSession(pb.GetSessionRequest(session_id=sid), timeout=10)
                    self.assertEqual(e.exception.code(), grpc.StatusCode.NOT_FOUND)
                new = b.stub.StartSession(pb.StartSessionRequest(live=live_source()), timeout=10).id
                self.assertNotIn(new, ids)
            finally:
                b.stop()
        finally:
            shutil.rmtree(workdir, ignore_errors=True)


def main():
    global ARGS
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--server", required=True, help="locaid-server binary")
    ap.add_argument("--proto", required=True, help="folder holding locaid/v1/localization.proto")
    ap.add_argument("-v", action="store_true", help="verbose")
    ARGS, rest = ap.parse_known_args()
    if not os.access(ARGS.server, os.X_OK):
        ap.error(f"{ARGS.server}: not an executable")
    stubs = tempfile.mkdtemp(prefix="locaid_contract_stubs_")
    try:
        generate_stubs(os.path.abspath(ARGS.proto), stubs)
        prog = unittest.main(argv=[sys.argv[0], *rest], verbosity=2 if ARGS.v else 1, exit=False)
        sys.exit(0 if prog.result.wasSuccessful() else 1)
    finally:
        shutil.rmtree(stubs, ignore_errors=True)


if __name__ == "__main__":
    main()
