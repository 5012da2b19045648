#!/usr/bin/python3
"""Python client of locaid-server.

Stubs are generated at build time into <build>/python (proto/CMakeLists.txt);
put that folder on PYTHONPATH (or pass --stubs DIR):

  PYTHONPATH=build/python /usr/bin/python3 clients/python/locaid_client.py \
      --server 127.0.0.1:50051 subscribe s1 --from-start --csv poses.csv

--server takes host:port or, for a server started with --listen-unix PATH,
unix:PATH (unix:/abs/path, unix:relative/path or unix:///abs/path); the
target goes to grpc.insecure_channel / grpc.secure_channel as is.

The CSV has the same columns as `locaid subscribe --format csv`
(CSV_COLUMNS below), which clients/plot_outage.py reads.
"""
import argparse
import csv
import errno
import io
import math
import os
import sys
import time

CSV_COLUMNS = [
    "t_s", "frame_index", "sequence", "e_m", "n_m", "u_m", "lat_deg", "lon_deg", "alt_m",
    "qw", "qx", "qy", "qz", "ve_mps", "vn_mps", "vu_mps", "sigma_e_m", "sigma_n_m", "sigma_u_m",
    "mode", "seconds_since_gps", "vo_inliers", "gps_used", "gps_rejected", "gps_outage",
    "processing_latency_ms", "delay_ms", "dropped", "gps_resets", "smoothed", "vo_health",
]


def enum_name(enum, value, prefix):
    """The proto's name of an enum value without its prefix (as the C++ client writes it); the number if unknown."""
    try:
        return enum.Name(value).removeprefix(prefix)
    except ValueError:
        return str(value)


def mode_name(pb2, mode):
    return enum_name(pb2.Mode, mode, "MODE_")


def _import_stubs(stubs_dir):
    if stubs_dir:
        sys.path.insert(0, stubs_dir)
    try:
        import grpc  # noqa: F401
        from locaid.v1 import localization_pb2, localization_pb2_grpc
    except ImportError as e:
        sys.exit("error: cannot import the generated stubs (%s); build the project and set "
                 "PYTHONPATH=<build>/python or pass --stubs" % e)
    return localization_pb2, localization_pb2_grpc


def make_channel(args):
    import grpc
    options = [("grpc.keepalive_time_ms", 30000), ("grpc.max_receive_message_length", 64 << 20)]
    if args.tls_ca:
        with open(args.tls_ca, "rb") as f:
            creds = grpc.ssl_channel_credentials(root_certificates=f.read())
        return grpc.secure_channel(args.server, creds, options=options)
    return grpc.insecure_channel(args.server, options=options)


def metadata(args):
    return [("authorization", "Bearer " + args.token)] if args.token else []


def seconds(t_ns):
    """t_ns as seconds to the nanosecond, as the CLI writes it ("%.12g" keeps Unix times to 10 ms)."""
    whole, frac = divmod(abs(t_ns), 10**9)
    return "%s%d.%09d" % ("-" if t_ns < 0 else "", whole, frac)


def pose_row(pb2, p, delay_ms):
    cov = list(p.covariance)
    sigma = [math.sqrt(max(0.0, cov[i * 7])) if len(cov) == 36 else float("nan") for i in range(3)]
    return [
        seconds(p.t_ns), p.frame_index, p.sequence,
        p.position_enu_m.x, p.position_enu_m.y, p.position_enu_m.z,
        p.latitude_deg, p.longitude_deg, p.altitude_m,
        p.orientation_enu_body.w, p.orientation_enu_body.x, p.orientation_enu_body.y, p.orientation_enu_body.z,
        p.velocity_enu_mps.x, p.velocity_enu_mps.y, p.velocity_enu_mps.z,
        sigma[0], sigma[1], sigma[2],
        mode_name(pb2, p.mode), p.seconds_since_gps, p.vo_inliers, p.gps_used, p.gps_rejected,
        1 if p.gps_outage_active else 0, p.processing_latency_ms, delay_ms, p.dropped_for_subscriber,
        p.gps_resets, 1 if p.smoothed else 0, enum_name(pb2.VoHealth, p.vo_health, "VO_HEALTH_"),
    ]


class RecordError(Exception):
    pass


class CsvRecorder:
    """Appends one complete CSV line per pose with a single unbuffered write.

    A killed client leaves a valid file. When a write fails (disk full,
    file-size limit, I/O error) the partial line is cut off, so the file ends
    with the last complete pose, and RecordError says how many it holds.
    """

    def __init__(self, path):
        self.path = path
        self.fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        self.good = 0  # bytes of complete lines
        self.rows = 0
        self.write(CSV_COLUMNS, header=True)

    def write(self, row, header=False):
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerow(row)
        data = buf.getvalue().encode()
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(self.fd, view):]
        except OSError as e:
            os.ftruncate(self.fd, self.good)
            what = "the header" if header else "pose %d" % (self.rows + 1)
            raise RecordError("recording to '%s' failed while writing %s: %s (%s); kept %d complete poses, "
                              "the file ends with the last complete pose" % (
                                  self.path, what, e.strerror, errno.errorcode.get(e.errno, e.errno), self.rows))
        self.good += len(data)
        if not header:
            self.rows += 1

    def close(self):
        os.close(self.fd)


def subscribe(args, pb2, pb2_grpc):
    import grpc
    stub = pb2_grpc.LocalizationStub(make_channel(args))
    req = pb2.StreamPosesRequest(session_id=args.session, from_start=args.from_start, queue_size=args.queue,
                                 smoothing_lag_s=args.lag)
    recorder = None
    n = 0
    try:
        if args.csv:
            recorder = CsvRecorder(args.csv)
        for p in stub.StreamPoses(req, timeout=args.stream_timeout_s, metadata=metadata(args)):
            delay_ms = (time.time_ns() - p.published_unix_ns) * 1e-6
            n += 1
            if recorder:
                recorder.write(pose_row(pb2, p, delay_ms))
            else:
                print("seq=%d t=%.3f enu=(%.3f,%.3f,%.3f) mode=%s delay_ms=%.3f dropped=%d" % (
                    p.sequence, p.t_ns * 1e-9, p.position_enu_m.x, p.position_enu_m.y, p.position_enu_m.z,
                    mode_name(pb2, p.mode), delay_ms, p.dropped_for_subscriber), flush=True)
            if args.max and n >= args.max:
                break
    except grpc.RpcError as e:
        sys.stderr.write("error: %s: %s\n" % (e.code().name, e.details()))
        return 1
    except RecordError as e:
        sys.stderr.write("error: %s\n" % e)
        return 4
    except OSError as e:
        sys.stderr.write("error: %s: %s\n" % (args.csv, e.strerror))
        return 4
    finally:
        if recorder:
            recorder.close()
    sys.stderr.write("received %d poses\n" % n)
    return 0


def stats(args, pb2, pb2_grpc):
    import grpc
    stub = pb2_grpc.LocalizationStub(make_channel(args))
    try:
        s = stub.GetStats(pb2.GetStatsRequest(session_id=args.session), timeout=args.timeout_s,
                          metadata=metadata(args))
    except grpc.RpcError as e:
        sys.stderr.write("error: %s: %s\n" % (e.code().name, e.details()))
        return 1
    print(s)
    return 0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--server", default="127.0.0.1:50051",
                    help="host:port, or unix:PATH for the server's --listen-unix socket (default %(default)s)")
    ap.add_argument("--token", default=os.environ.get("LOCAID_TOKEN", ""))
    ap.add_argument("--tls-ca", default="")
    ap.add_argument("--stubs", default="", help="folder with the generated locaid/v1/*_pb2.py")
    ap.add_argument("--timeout-s", type=float, default=10.0)
    sub = ap.add_subparsers(dest="command", required=True)
    s = sub.add_parser("subscribe", help="stream poses; print or record CSV")
    s.add_argument("session")
    s.add_argument("--from-start", action="store_true")
    s.add_argument("--csv", default="", help="record to this CSV file")
    s.add_argument("--max", type=int, default=0)
    s.add_argument("--queue", type=int, default=0)
    s.add_argument("--lag", type=float, default=0.0,
                   help="smoothed poses S seconds (sensor time) behind the session (0 = causal; docs/api.md)")
    s.add_argument("--stream-timeout-s", type=float, default=24 * 3600.0)
    st = sub.add_parser("stats", help="session statistics")
    st.add_argument("session")
    args = ap.parse_args(argv)
    pb2, pb2_grpc = _import_stubs(args.stubs)
    return {"subscribe": subscribe, "stats": stats}[args.command](args, pb2, pb2_grpc)


if __name__ == "__main__":
    sys.exit(main())
