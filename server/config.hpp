// Server configuration: command-line flags (CLI11) plus an optional YAML file,
// validated once in ValidateConfig with messages naming the field.
#pragma once

#include <sys/un.h>

#include <cstddef>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace locaid::server {

class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A live camera session the server starts itself, for a car that boots
// into localisation (the YAML key `live_cameras`): the keys of
// LiveSource.cameras, with the camera_info files as paths on the server, and
// an optional gpsd. Started once the server listens, and retried every 5 s
// while it cannot start (cameras that come up after the server).
struct BootCameras {
  std::string left_pipeline, right_pipeline, stereo_pipeline;
  std::string left_camera_info, right_camera_info;  // camera_info YAML files
  std::string gpsd;                                 // HOST:PORT or HOST; empty: no gpsd
  double pair_tolerance_ms = 0, stall_timeout_s = 0;  // 0: the defaults (10 ms, 1 s)
  bool no_imu = false;                              // LiveSource.no_imu: a car without IMU
  std::string scenario;                             // empty: default_scenario
};

struct ServerConfig {
  std::string listen = "127.0.0.1:50051";  // host:port; port 0 picks a free one
  // Optional second listener on a Unix-domain socket at this path (absolute or
  // relative to the working directory, without "unix:"); empty = TCP only.
  // Same credentials and token as `listen`. The socket file is made 0660
  // after bind and removed on clean shutdown; a stale socket file left by a
  // crashed server is replaced, anything else at the path is refused.
  std::string listen_unix;
  std::string tls_cert_file;               // PEM; TLS when cert and key are set
  std::string tls_key_file;
  std::string token;                       // bearer token; empty = no auth
  std::string token_file;                  // alternative: first line of this file
  size_t max_receive_mb = 32;              // largest accepted message (pushed frames)
  size_t history_size = 1000;              // default poses kept per session
  size_t max_history_size = 100000;        // upper bound for a session's history
  size_t queue_size = 256;                 // default per-subscriber queue (poses)
  size_t max_queue_size = 10000;
  size_t max_sessions = 16;
  // Keeping real time (docs/api.md "Keeping real time"). A paced session
  // whose newest pose is more than behind_threshold_s late (or whose next
  // pose is that overdue) is falling behind. max_cpu_cores > 0: a real-time
  // session (paced or live) is admitted only while the real-time sessions'
  // measured CPU (last ~5 s of their threads) plus its estimate stays within
  // it; the estimate is the mean cost per unit rate of the sessions running
  // for >= 5 s, or session_cpu_cores_prior before there is one. 0 = off.
  double behind_threshold_s = 0.1;
  double max_cpu_cores = 0;
  double session_cpu_cores_prior = 0.5;
  size_t max_subscribers_per_session = 4096;
  std::string work_dir;                    // synthetic drives; empty = $TMPDIR/locaid-server-<pid>
  std::string default_scenario = "open-sky";
  std::string default_vo_method = "default";
  size_t synthetic_default_frames = 100;
  // Largest synthetic drive a session may ask for (frames, or the frames a
  // length_m drive needs at its slowest speed): 3000 = 5 min at 10 Hz, about
  // 1.3 GB of PNGs at KITTI size.
  size_t max_synthetic_frames = 3000;
  // Sessions that may prepare their input (render a synthetic drive) at the
  // same time; StartSession beyond is RESOURCE_EXHAUSTED. Each render uses
  // one core.
  size_t max_concurrent_renders = 2;
  // Ended sessions (FINISHED, STOPPED, FAILED; not removed) are kept for their
  // history and GetSession, at most this many (the oldest go first) and at
  // most this long after they ended; checked whenever a session starts or
  // sessions are listed. Each keeps up to history_size poses (~1 KB each).
  size_t max_ended_sessions = 64;
  double ended_session_ttl_s = 3600;
  double keepalive_time_s = 20;            // HTTP/2 pings on idle connections
  double keepalive_timeout_s = 10;
  double shutdown_grace_s = 1.5;           // streams still open this long after SIGTERM are cancelled
  // Upper bound on glibc malloc's arenas (mallopt M_ARENA_MAX, set by
  // locaid-server before its first thread); 0 = glibc's default of 8 per
  // core. Threads started per session and per stream otherwise spread freed
  // memory over up to 8 arenas a core, which glibc keeps: RSS grew with every
  // round of sessions (docs/reliability.md "Memory under fan-out").
  // MALLOC_ARENA_MAX (or glibc.malloc.arena_max in GLIBC_TUNABLES) in the
  // environment wins.
  size_t malloc_arena_max = 2;
  std::string port_file;                   // write the bound port here once listening
  // host:port of the Prometheus /metrics endpoint; empty = off (default).
  // Plain HTTP without the token: bind it to loopback or a pod network.
  std::string metrics_listen;
  bool log_shutdown = false;               // print shutdown timings (locaid-server sets it)
  std::optional<BootCameras> live_cameras;  // YAML only: a camera session started at boot
};

// Applies a YAML file (keys = field names above) onto `config`. Throws
// ConfigError "FILE: key 'x': reason" for unknown keys or wrong types.
void ApplyYamlConfig(const std::filesystem::path& file, ServerConfig* config);
// Throws ConfigError naming the field when a value is out of range or a file
// is unreadable; reads token_file into token.
void ValidateConfig(ServerConfig* config);

// Number parsing with precise errors "FIELD: value 'TEXT' is REASON" (FIELD
// and its ": " are left out when empty). Exposed for tests.
size_t ParseSizeField(const std::string& field, const std::string& text);
double ParseRealField(const std::string& field, const std::string& text);
// Port of a "host:port" listen address; ConfigError naming `listen`, the
// port text and the reason (not a number, out of [0, 65535]).
int ParseListenPort(const std::string& listen);
// Checks a `listen_unix` path without touching it: non-empty, no "unix:"
// prefix, no NUL byte, shorter than the 108-byte sun_path (so at most 107
// bytes), not ending in '/', and its parent directory exists. ConfigError
// "listen_unix: ..." naming the path and the reason.
void CheckListenUnixPath(const std::string& path);
// The largest malloc_arena_max (glibc's own default is 8 per core).
inline constexpr size_t kMaxMallocArenas = 1024;
// The most bytes a `listen_unix` path may have (sizeof(sockaddr_un::sun_path) - 1).
inline constexpr size_t kMaxUnixPathBytes = sizeof(sockaddr_un{}.sun_path) - 1;

}  // namespace locaid::server
