// The optional Unix-domain socket listener (--listen-unix / listen_unix): the
// real server (in-process with the fake estimator, and the real
// locaid-server binary) on 127.0.0.1 plus a socket in the test's temporary
// folder, driven by the real `locaid` CLI and the Python client.
#include "test_support.hpp"

#include "needs_tool.hpp"

#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>

#include <cstring>
#include <stdexcept>

namespace locaid::server::testing {
namespace {

bool IsSocket(const std::filesystem::path& p) {
  struct stat st {};
  return ::lstat(p.c_str(), &st) == 0 && S_ISSOCK(st.st_mode);
}

unsigned Mode(const std::filesystem::path& p) {
  struct stat st {};
  return ::lstat(p.c_str(), &st) == 0 ? static_cast<unsigned>(st.st_mode & 07777) : 0u;
}

// A socket bound at `p`; listening when `listen` (a live socket), else
// closed at once, leaving the file behind as a crashed server would.
int BindUnix(const std::filesystem::path& p, bool listen) {
  const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
  EXPECT_GE(fd, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strncpy(addr.sun_path, p.c_str(), sizeof(addr.sun_path) - 1);
  EXPECT_EQ(::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)), 0) << std::strerror(errno);
  if (listen) {
    EXPECT_EQ(::listen(fd, 4), 0);
    return fd;
  }
  ::close(fd);
  return -1;
}

std::string ConfigErrorOf(ServerConfig c) {
  try {
    ValidateConfig(&c);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

std::string StartErrorOf(const ServerConfig& c) {
  try {
    LocalizationServer server(c, FakeFactory());
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

bool HavePythonGrpc() { return std::system("/usr/bin/python3 -c 'import grpc' 2>/dev/null") == 0; }

size_t CountLinesStartingWith(const std::string& text, const std::string& prefix) {
  size_t n = 0;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) n += line.rfind(prefix, 0) == 0 ? 1 : 0;
  return n;
}

TEST(UnixSocketConfig, PathErrorsNameTheKeyAndTheReason) {
  const ScopedTempDir dir("uds");  // under $TMPDIR: short enough for sun_path
  ServerConfig c = LoopbackConfig(dir / "work");
  c.listen_unix = (dir / "ok.sock").string();
  EXPECT_EQ(ConfigErrorOf(c), "");

  // sun_path holds 108 bytes with the terminating NUL: 107 is the longest.
  const std::string base = (dir / "").string();
  c.listen_unix = base + std::string(kMaxUnixPathBytes - base.size(), 'a');
  ASSERT_EQ(c.listen_unix.size(), 107u);
  EXPECT_EQ(ConfigErrorOf(c), "");
  c.listen_unix += "a";
  std::string e = ConfigErrorOf(c);
  EXPECT_NE(e.find("listen_unix: path '" + c.listen_unix + "' is 108 bytes"), std::string::npos) << e;
  EXPECT_NE(e.find("shorter than 108 bytes"), std::string::npos) << e;

  c.listen_unix = (dir / "missing" / "s.sock").string();
  e = ConfigErrorOf(c);
  EXPECT_NE(e.find("listen_unix: directory '" + (dir / "missing").string() + "'"), std::string::npos) << e;
  EXPECT_NE(e.find("does not exist"), std::string::npos) << e;

  std::ofstream(dir / "file") << "x";
  c.listen_unix = (dir / "file" / "s.sock").string();
  e = ConfigErrorOf(c);
  EXPECT_NE(e.find("is not a directory"), std::string::npos) << e;

  c.listen_unix = "unix:" + (dir / "s.sock").string();
  e = ConfigErrorOf(c);
  EXPECT_NE(e.find("without the 'unix:' prefix"), std::string::npos) << e;

  c.listen_unix = (dir / "sub").string() + "/";
  e = ConfigErrorOf(c);
  EXPECT_NE(e.find("ends in '/'"), std::string::npos) << e;

  EXPECT_NE(ConfigErrorOf([] {
              ServerConfig empty;
              empty.listen_unix = std::string("a\0b", 3);
              return empty;
            }())
                .find("NUL"),
            std::string::npos);
  EXPECT_THROW(CheckListenUnixPath(""), ConfigError);  // locaid-server --listen-unix ''
}

TEST(UnixSocketConfig, YamlKeyIsReadAndAnEmptyValueIsAnError) {
  const ScopedTempDir dir("uds");
  const auto good = dir / "good.yaml", empty = dir / "empty.yaml";
  std::ofstream(good) << "listen: 127.0.0.1:0\nlisten_unix: " << (dir / "s.sock").string() << "\n";
  std::ofstream(empty) << "listen: 127.0.0.1:0\nlisten_unix: ''\n";
  ServerConfig c;
  ApplyYamlConfig(good, &c);
  EXPECT_EQ(c.listen_unix, (dir / "s.sock").string());
  EXPECT_NO_THROW(ValidateConfig(&c));
  ServerConfig d;
  try {
    ApplyYamlConfig(empty, &d);
    FAIL() << "an empty listen_unix was accepted";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(empty.string() + ":2: key 'listen_unix': empty path"), std::string::npos) << what;
  }
}

class UnixSocketTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = tmp_.path();
    sock_ = dir_ / "locaid.sock";
    target_ = "unix:" + sock_.string();
  }
  void TearDown() override {
    if (server_) server_->Shutdown();
  }
  ServerConfig Config() const {
    ServerConfig c = LoopbackConfig(dir_ / "work");
    c.listen_unix = sock_.string();
    return c;
  }
  void Start(const ServerConfig& c) { server_ = std::make_unique<LocalizationServer>(c, FakeFactory()); }

  const ScopedTempDir tmp_{"uds"};  // under $TMPDIR: short enough for sun_path
  std::filesystem::path dir_, sock_;
  std::string target_;
  std::unique_ptr<LocalizationServer> server_;
};

TEST_F(UnixSocketTest, BothListenersServeTheCliAndTheSocketFileIs0660) {
  Start(Config());
  EXPECT_EQ(server_->unix_target(), target_);
  EXPECT_FALSE(server_->replaced_stale_socket());
  ASSERT_TRUE(IsSocket(sock_));
  EXPECT_EQ(Mode(sock_), 0660u);
  CliResult r = RunCliAt(target_, {"health"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "SERVING\n");
  EXPECT_EQ(RunCli(server_->port(), {"health"}).out, "SERVING\n");
  // unix:RELATIVE resolves against the client's working directory.
  r = RunShell("cd " + ShellQuote(dir_.string()) + " && " + ShellQuote(std::string(LOCAID_BIN_DIR) + "/locaid") +
               " --server unix:locaid.sock health");
  EXPECT_EQ(r.out, "SERVING\n") << r.err;
  // unix:///ABS is the URI form of the same target.
  EXPECT_EQ(RunCliAt("unix://" + sock_.string(), {"health"}).out, "SERVING\n");

  constexpr int kFrames = 6;
  r = RunCliAt(target_, {"session", "start", "--synthetic", "7", "--frames", std::to_string(kFrames), "--history",
                         "100"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string id = r.out.substr(0, r.out.find('\n'));
  ASSERT_FALSE(id.empty());
  r = RunCliAt(target_, {"subscribe", id, "--from-start", "--max", std::to_string(kFrames), "--stream-timeout-s",
                         "60"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(CountLinesStartingWith(r.out, "seq="), static_cast<size_t>(kFrames)) << r.out;
  // The same session through TCP: one server behind both listeners.
  r = RunCli(server_->port(), {"session", "get", id});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out.rfind(id + " ", 0), 0u) << r.out;
}

TEST_F(UnixSocketTest, TokenIsRequiredOnTheSocketToo) {
  ServerConfig c = Config();
  c.token = "s3cret";
  Start(c);
  CliResult r = RunCliAt(target_, {"session", "list"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("UNAUTHENTICATED: missing"), std::string::npos) << r.err;
  r = RunCliAt(target_, {"session", "list"}, {"--token", "wrong"});
  EXPECT_NE(r.err.find("UNAUTHENTICATED: invalid bearer token"), std::string::npos) << r.err;
  r = RunCliAt(target_, {"subscribe", "s1", "--stream-timeout-s", "10"});  // the streaming method as well
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("UNAUTHENTICATED"), std::string::npos) << r.err;
  r = RunCliAt(target_, {"session", "list"}, {"--token", "s3cret"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
}

TEST_F(UnixSocketTest, StaleSocketFileIsReplaced) {
  BindUnix(sock_, false);
  ASSERT_TRUE(IsSocket(sock_));
  EXPECT_EQ(InspectUnixSocketPath(sock_.string()), UnixPathState::kStaleSocket);
  Start(Config());
  EXPECT_TRUE(server_->replaced_stale_socket());
  EXPECT_EQ(Mode(sock_), 0660u);
  EXPECT_EQ(RunCliAt(target_, {"health"}).out, "SERVING\n");
}

TEST_F(UnixSocketTest, ASocketInUseIsRefusedAndLeftAlone) {
  Start(Config());
  // A second server on the same path (gRPC alone would unlink the first's socket).
  ServerConfig second = Config();
  second.work_dir = (dir_ / "work2").string();
  const std::string e = StartErrorOf(second);
  EXPECT_NE(e.find("listen_unix '" + sock_.string() + "': another process is listening"), std::string::npos) << e;
  EXPECT_TRUE(IsSocket(sock_));
  EXPECT_EQ(RunCliAt(target_, {"health"}).out, "SERVING\n");  // the first one still serves it
}

TEST_F(UnixSocketTest, ARegularFileDirectoryOrSymlinkAtThePathIsRefusedAndKept) {
  std::ofstream(sock_) << "keep me\n";
  std::string e = StartErrorOf(Config());
  EXPECT_NE(e.find("listen_unix '" + sock_.string() + "': exists and is a regular file, not a socket"),
            std::string::npos)
      << e;
  EXPECT_EQ(Slurp(sock_), "keep me\n");

  std::filesystem::remove(sock_);
  std::filesystem::create_directories(sock_ / "inside");
  e = StartErrorOf(Config());
  EXPECT_NE(e.find("exists and is a directory"), std::string::npos) << e;
  EXPECT_TRUE(std::filesystem::is_directory(sock_ / "inside"));

  std::filesystem::remove_all(sock_);
  std::filesystem::create_symlink(dir_ / "elsewhere.sock", sock_);
  e = StartErrorOf(Config());
  EXPECT_NE(e.find("exists and is a symbolic link"), std::string::npos) << e;
  EXPECT_TRUE(std::filesystem::is_symlink(std::filesystem::symlink_status(sock_)));
}

TEST_F(UnixSocketTest, RelativePathIsBoundInTheWorkingDirectoryAndRemovedOnShutdown) {
  const auto cwd = std::filesystem::current_path();
  std::filesystem::current_path(dir_);
  ServerConfig c = Config();
  c.listen_unix = "rel.sock";
  std::string error;
  try {
    Start(c);
  } catch (const std::exception& ex) {
    error = ex.what();
  }
  std::filesystem::current_path(cwd);
  ASSERT_EQ(error, "");
  EXPECT_TRUE(IsSocket(dir_ / "rel.sock"));
  EXPECT_EQ(RunCliAt("unix:" + (dir_ / "rel.sock").string(), {"health"}).out, "SERVING\n");
  std::filesystem::current_path(dir_);
  server_->Shutdown();
  std::filesystem::current_path(cwd);
  EXPECT_FALSE(std::filesystem::exists(std::filesystem::symlink_status(dir_ / "rel.sock")));
}

TEST_F(UnixSocketTest, TlsConfiguredAppliesOnTheSocketToo) {
  LOCAID_NEEDS_TOOL(test_support::HaveCommand("openssl"), "openssl not installed");
  const auto cert = dir_ / "cert.pem", key = dir_ / "key.pem";
  const CliResult gen = RunShell("openssl req -x509 -newkey rsa:2048 -nodes -days 1 -subj /CN=localhost -addext "
                                 "subjectAltName=IP:127.0.0.1,DNS:localhost -keyout " +
                                 key.string() + " -out " + cert.string());
  ASSERT_EQ(gen.exit_code, 0) << gen.err;
  ServerConfig c = Config();
  c.tls_cert_file = cert.string();
  c.tls_key_file = key.string();
  Start(c);
  // gRPC names a unix: target "localhost" for the certificate check.
  CliResult r = RunCliAt(target_, {"health"}, {"--tls-ca", cert.string()});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "SERVING\n");
  r = RunCliAt(target_, {"session", "list"}, {"--timeout-s", "3"});  // plaintext client
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("UNAVAILABLE"), std::string::npos) << r.err;
}

TEST_F(UnixSocketTest, PythonClientSubscribesOverTheSocket) {
  LOCAID_NEEDS_TOOL(HavePythonGrpc(), "python3-grpcio not installed");
  Start(Config());
  constexpr int kFrames = 5;
  CliResult r = RunCliAt(target_, {"session", "start", "--synthetic", "3", "--frames", std::to_string(kFrames),
                                   "--history", "100"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string id = r.out.substr(0, r.out.find('\n'));
  const auto csv = dir_ / "poses.csv";
  const CliResult py = RunShell("PYTHONPATH=" + ShellQuote(LOCAID_PYTHON_STUBS) + " /usr/bin/python3 " +
                                ShellQuote(std::string(LOCAID_SOURCE_DIR) + "/clients/python/locaid_client.py") +
                                " --server " + ShellQuote(target_) + " subscribe " + id + " --from-start --max " +
                                std::to_string(kFrames) + " --csv " + ShellQuote(csv.string()));
  ASSERT_EQ(py.exit_code, 0) << py.out << py.err;
  const std::string text = Slurp(csv);
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), kFrames + 1) << text;  // header + poses
}

TEST(UnixSocketCli, BadServerAddressesAreUsageErrors) {
  struct Case {
    std::string address, message;
  };
  const std::vector<Case> cases = {
      {"localhost", "expected host:port or unix:PATH"},
      {"unix:", "unix: needs a socket path"},
      {"unix://relative", "unix://PATH needs an absolute path"},
      {"127.0.0.1:99999", "port '99999' is not a number in [1, 65535]"},
      {"127.0.0.1:", "port '' is not a number"},
      {":50051", "the host before ':' is empty"},
      {"::1:50051", "an IPv6 host must be in brackets"},
      {"unix:/" + std::string(110, 'a'), "the socket path is 111 bytes, must be < 108"},
  };
  for (const auto& c : cases) {
    const CliResult r = RunCliAt(c.address, {"health"});
    EXPECT_EQ(r.exit_code, 2) << c.address;
    EXPECT_NE(r.err.find("error: --server '" + c.address + "': " + c.message), std::string::npos)
        << c.address << ": " << r.err;
  }
  // A well-formed socket path nobody listens on is an RPC error, not a usage error.
  const ScopedTempDir dir("uds");
  const CliResult r = RunCliAt("unix:" + (dir / "nobody.sock").string(), {"health"}, {"--timeout-s", "2"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("UNAVAILABLE"), std::string::npos) << r.err;
}

// The real locaid-server binary: the startup line names the socket; SIGKILL
// leaves a stale socket file that the next server replaces; SIGTERM removes it.
TEST(UnixSocketProcess, StaleFileAfterACrashIsReplacedAndSigtermRemovesTheSocket) {
  const ScopedTempDir dir("uds");
  const auto sock = dir / "locaid.sock";
  const std::string target = "unix:" + sock.string();
  {
    ServerProcess crashed(dir / "a", {"--listen-unix", sock.string()});
    ASSERT_GT(crashed.port(), 0) << crashed.log();
    EXPECT_EQ(RunCliAt(target, {"health"}).out, "SERVING\n");
    ASSERT_TRUE(crashed.process().Signal(SIGKILL));
    ASSERT_TRUE(crashed.process().Wait(10));
  }
  ASSERT_TRUE(IsSocket(sock)) << "SIGKILL should leave the socket file behind";
  ServerProcess server(dir / "b", {"--listen-unix", sock.string()});
  ASSERT_GT(server.port(), 0) << server.log();
  const std::string log = server.log();
  EXPECT_NE(log.find("listening on 127.0.0.1:" + std::to_string(server.port()) + " and " + target + " (mode 0660)"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("(replaced a stale socket file)"), std::string::npos) << log;
  EXPECT_EQ(Mode(sock), 0660u);
  EXPECT_EQ(RunCliAt(target, {"health"}).out, "SERVING\n");
  ASSERT_TRUE(server.process().Signal(SIGTERM));
  ASSERT_TRUE(server.process().Wait(10)) << "locaid-server did not exit after SIGTERM";
  EXPECT_EQ(server.process().exit_code(), 0) << server.log();
  EXPECT_FALSE(std::filesystem::exists(std::filesystem::symlink_status(sock))) << "socket file left after SIGTERM";
}

TEST(UnixSocketProcess, ARegularFileAtThePathStopsStartupWithAClearError) {
  const ScopedTempDir dir("uds");
  const auto path = dir / "locaid.sock";
  std::ofstream(path) << "not a socket\n";
  ServerProcess server(dir / "run", {"--listen-unix", path.string()});
  ASSERT_TRUE(server.process().Wait(10));
  EXPECT_EQ(server.process().exit_code(), 1);
  EXPECT_NE(server.log().find("locaid-server: listen_unix '" + path.string() +
                              "': exists and is a regular file, not a socket; not replacing it"),
            std::string::npos)
      << server.log();
  EXPECT_EQ(Slurp(path), "not a socket\n");
}

TEST(UnixSocketProcess, ConfigErrorsExitWithCode2) {
  const ScopedTempDir dir("uds");
  ServerProcess missing(dir / "run", {"--listen-unix", (dir / "nope" / "s.sock").string()});
  ASSERT_TRUE(missing.process().Wait(10));
  EXPECT_EQ(missing.process().exit_code(), 2);
  EXPECT_NE(missing.log().find("locaid-server: config: listen_unix: directory '" + (dir / "nope").string() +
                               "'"),
            std::string::npos)
      << missing.log();
  ServerProcess empty(dir / "run2", {"--listen-unix", ""});
  ASSERT_TRUE(empty.process().Wait(10));
  EXPECT_EQ(empty.process().exit_code(), 2);
  EXPECT_NE(empty.log().find("listen_unix: path is empty"), std::string::npos) << empty.log();
}

}  // namespace
}  // namespace locaid::server::testing
