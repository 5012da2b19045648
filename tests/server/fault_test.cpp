// Fault tests on the real server (issue 7): a drive that goes bad mid-session,
// a recording client whose disk fills, clients killed mid-stream, SIGTERM
// with 100 open streams. The server is the real build/bin/locaid-server
// process with the real estimator where the estimator matters, the clients
// are the real `locaid` CLI as subprocesses plus in-test stream readers.
#include "test_support.hpp"


#include <nlohmann/json.hpp>

#include <sys/mount.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <random>
#include <regex>
#include <set>

namespace locaid::server::testing {
namespace {

namespace fs = std::filesystem;

// Small and fast: 40 frames of 320x96 px render in about a second.
constexpr int kSynthWidth = 320;
constexpr int kSynthHeight = 96;
constexpr uint64_t kSynthSeed = 3;

std::string FrameFile(int i, const char* ext) {
  char name[32];
  std::snprintf(name, sizeof name, "%010d.%s", i, ext);
  return name;
}

std::vector<std::string> ReadLines(const fs::path& p) {
  std::vector<std::string> lines;
  std::ifstream in(p);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

void WriteLines(const fs::path& p, const std::vector<std::string>& lines) {
  std::ofstream out(p, std::ios::trunc);
  for (const auto& l : lines) out << l << "\n";
}

std::vector<std::string> Split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string cur;
  std::istringstream in(s);
  while (std::getline(in, cur, sep)) out.push_back(cur);
  if (!s.empty() && s.back() == sep) out.push_back("");
  return out;
}

bool IsNumber(const std::string& s) {
  if (s.empty()) return false;
  char* end = nullptr;
  (void)std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size();
}

// Starts a KITTI session; "" (and a test failure) if refused.
std::string StartKitti(v1::Localization::Stub* stub, const fs::path& drive, double rate, uint32_t history) {
  v1::StartSessionRequest req;
  req.mutable_kitti()->set_path(drive.string());
  req.set_playback_rate(rate);
  req.set_history_size(history);
  grpc::ClientContext ctx;
  SetDeadline(&ctx, 30);
  v1::Session resp;
  const grpc::Status s = stub->StartSession(&ctx, req, &resp);
  EXPECT_TRUE(s.ok()) << "StartSession " << drive << ": " << s.error_code() << " " << s.error_message();
  return s.ok() ? resp.id() : "";
}

// Waits (bounded) until the session is no longer STARTING/RUNNING.
v1::Session WaitSessionEnd(v1::Localization::Stub* stub, const std::string& id, double timeout_s) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  v1::Session s = GetSession(stub, id);
  while ((s.state() == v1::SESSION_STATE_RUNNING || s.state() == v1::SESSION_STATE_STARTING) &&
         std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    s = GetSession(stub, id);
  }
  return s;
}

// Data lines of a CLI CSV record (header checked and dropped). Every line
// must be complete: as many fields as the header (31), sequence column == row number + first_seq.
std::vector<std::vector<std::string>> CsvRows(const fs::path& p, const std::string& who) {
  const std::string text = Slurp(p);
  EXPECT_TRUE(text.empty() || text.back() == '\n') << who << ": last line of " << p << " incomplete";
  std::vector<std::string> lines = ReadLines(p);
  std::vector<std::vector<std::string>> rows;
  if (lines.empty()) return rows;
  EXPECT_EQ(lines[0].rfind("t_s,frame_index,sequence,", 0), 0u) << who << ": header " << lines[0];
  const size_t fields = Split(lines[0], ',').size();
  EXPECT_EQ(fields, 31u) << who << ": header " << lines[0];
  for (size_t i = 1; i < lines.size(); ++i) {
    rows.push_back(Split(lines[i], ','));
    EXPECT_EQ(rows.back().size(), fields) << who << ": line " << i + 1 << ": " << lines[i];
  }
  return rows;
}

// ------------------------------------------------ 1. a drive that goes bad --

// After a fault: the server process still runs, and SIGTERM ends it cleanly.
void ExpectStillRunningThenCleanExit(ServerProcess& server) {
  EXPECT_TRUE(server.process().running()) << server.log();
  ASSERT_TRUE(server.process().Signal(SIGTERM));
  ASSERT_TRUE(server.process().Wait(10)) << server.log();
  EXPECT_EQ(server.process().exit_code(), 0) << server.log();
}

// A synthetic drive damaged the ways a real disk or logger does it, played
// by the real estimator: images truncated / overwritten with garbage /
// deleted / repeated, a camera time that jumps back, OXTS records with NaN
// fields, an OXTS time that goes backwards. The session must play to the end, skip and count exactly the
// damaged frames and bad OXTS records, never send a NaN/Inf, and the server
// must keep serving.
TEST(FaultTest, DamagedDriveMidSessionIsSkippedCountedAndTheServerKeepsServing) {
  const ScopedTempDir dir("fault_drive");
  constexpr int kFrames = 40;
  std::string error;
  const fs::path clean = RenderSynthDrive(dir / "clean", kFrames, kSynthSeed, kSynthWidth, kSynthHeight, &error);
  ASSERT_FALSE(clean.empty()) << error;
  fs::copy(dir / "clean", dir / "damaged", fs::copy_options::recursive);
  const fs::path drive = dir / "damaged" / clean.filename();
  const fs::path left = drive / "image_00" / "data", right = drive / "image_01" / "data";

  // Corrupt: frame 10 left truncated to half; frame 20 right keeps its PNG
  // header but the rest is garbage (fixed seed).
  const fs::path truncated = left / FrameFile(10, "png");
  fs::resize_file(truncated, fs::file_size(truncated) / 2);
  {
    const fs::path garbage = right / FrameFile(20, "png");
    std::string bytes = Slurp(garbage);
    ASSERT_GT(bytes.size(), 400u);
    std::mt19937 rng(7);
    for (size_t i = 64; i < bytes.size(); ++i) bytes[i] = static_cast<char>(rng() & 0xff);
    std::ofstream(garbage, std::ios::binary | std::ios::trunc) << bytes;
  }
  // Missing: frame 15 left, frame 25 right.
  ASSERT_TRUE(fs::remove(left / FrameFile(15, "png")));
  ASSERT_TRUE(fs::remove(right / FrameFile(25, "png")));
  // Repeated: frame 30 is a copy of frame 29 (both cameras), a stalled logger.
  for (const fs::path& cam : {left, right}) {
    fs::copy_file(cam / FrameFile(29, "png"), cam / FrameFile(30, "png"), fs::copy_options::overwrite_existing);
  }
  // Camera clock that jumps back: frame 33 stamped 0.2 s before frame 32.
  {
    auto stamps = ReadLines(drive / "image_00" / "timestamps.txt");
    ASSERT_EQ(stamps.size(), static_cast<size_t>(kFrames));
    const double sec = std::stod(stamps[32].substr(17));
    ASSERT_GT(sec, 0.5) << "pick another seed: frame 32 at " << stamps[32];
    char buf[32];
    std::snprintf(buf, sizeof buf, "%012.9f", sec - 0.2);
    stamps[33] = stamps[32].substr(0, 17) + buf;
    WriteLines(drive / "image_00" / "timestamps.txt", stamps);
  }
  const std::set<int64_t> kSkipped = {15, 25}, kCorrupt = {10, 20, 33};
  // OXTS: NaN longitude in record 12, NaN forward velocity (field 9) in 27.
  const fs::path oxts = drive / "oxts" / "data";
  for (const auto& [record, field] : {std::pair{12, 1}, std::pair{27, 8}}) {
    auto fields = Split(ReadLines(oxts / FrameFile(record, "txt")).at(0), ' ');
    ASSERT_EQ(fields.size(), 30u);
    fields[static_cast<size_t>(field)] = "nan";
    std::string line;
    for (const auto& f : fields) line += (line.empty() ? "" : " ") + f;
    WriteLines(oxts / FrameFile(record, "txt"), {line});
  }
  constexpr uint64_t kBadOxts = 2;
  // OXTS time that goes backwards: record 18 stamped 0.15 s before record 17.
  {
    auto stamps = ReadLines(drive / "oxts" / "timestamps.txt");
    ASSERT_GT(stamps.size(), 18u);
    const std::string& t17 = stamps[17];  // "YYYY-MM-DD HH:MM:SS.nnnnnnnnn"
    const double sec = std::stod(t17.substr(17));
    ASSERT_GT(sec, 0.5) << "pick another seed: record 17 at " << t17;
    char buf[32];
    std::snprintf(buf, sizeof buf, "%012.9f", sec - 0.15);
    stamps[18] = t17.substr(0, 17) + buf;
    WriteLines(drive / "oxts" / "timestamps.txt", stamps);
  }

  ServerProcess server(dir / "server");
  ASSERT_GT(server.port(), 0) << "locaid-server did not start: " << server.log();
  auto stub = v1::Localization::NewStub(server.NewChannel());
  const std::string id = StartKitti(stub.get(), drive, 0, 1000);
  ASSERT_FALSE(id.empty()) << "a NaN OXTS record or a bad frame must not refuse the whole drive";

  PoseCollector collector(server.NewChannel(), id, /*from_start=*/true);
  const fs::path csv = dir / "damaged.csv";
  const CliResult cli = RunCli(server.port(), {"subscribe", id, "--from-start", "--format", "csv", "--out",
                                               csv.string(), "--stream-timeout-s", "60"});
  ASSERT_EQ(cli.exit_code, 0) << cli.err;
  ASSERT_TRUE(collector.WaitDone(60));
  EXPECT_TRUE(collector.status().ok()) << collector.status().error_message();

  const v1::Session session = WaitSessionEnd(stub.get(), id, 30);
  EXPECT_EQ(session.state(), v1::SESSION_STATE_FINISHED) << session.error();
  const v1::SessionStats stats = GetStats(stub.get(), id);
  std::cout << "[ damaged  ] frames_in " << stats.frames_in() << " processed " << stats.frames_processed()
            << " skipped " << stats.frames_skipped() << " corrupt " << stats.frames_corrupt() << " oxts_bad_lines "
            << stats.oxts_bad_lines() << " last_input_error '" << stats.last_input_error() << "'\n";
  EXPECT_EQ(stats.frames_in(), static_cast<uint64_t>(kFrames));
  EXPECT_EQ(stats.frames_skipped(), kSkipped.size());
  EXPECT_EQ(stats.frames_corrupt(), kCorrupt.size());
  EXPECT_EQ(stats.frames_processed(), kFrames - kSkipped.size() - kCorrupt.size());
  EXPECT_EQ(stats.oxts_bad_lines(), kBadOxts);
  EXPECT_FALSE(stats.last_input_error().empty());

  // The poses: one per good frame (the repeated one included), in order, with
  // no NaN/Inf anywhere.
  const auto poses = collector.poses();
  std::vector<int64_t> expected_frames;
  for (int64_t i = 0; i < kFrames; ++i) {
    if (!kSkipped.count(i) && !kCorrupt.count(i)) expected_frames.push_back(i);
  }
  ASSERT_EQ(poses.size(), expected_frames.size());
  size_t non_finite = 0;
  for (size_t k = 0; k < poses.size(); ++k) {
    EXPECT_EQ(poses[k].sequence(), k);
    EXPECT_EQ(poses[k].frame_index(), expected_frames[k]);
    const auto bad = NonFinitePoseFields(poses[k]);
    non_finite += bad.empty() ? 0 : 1;
    EXPECT_TRUE(bad.empty()) << "pose " << k << " (frame " << poses[k].frame_index() << "): " << bad.front();
    EXPECT_GE(poses[k].seconds_since_gps(), 0.0) << "pose " << k;  // also false for NaN
    if (k > 0) {
      EXPECT_GT(poses[k].t_ns(), poses[k - 1].t_ns()) << "pose " << k << ": time went backwards";
    }
  }
  EXPECT_EQ(non_finite, 0u);
  // The CLI's record holds the same poses.
  const auto rows = CsvRows(csv, "cli");
  ASSERT_EQ(rows.size(), poses.size());
  for (size_t k = 0; k < rows.size(); ++k) EXPECT_EQ(rows[k][1], std::to_string(expected_frames[k]));

  // Still serving: health, and a second session (the clean drive) plays fully.
  EXPECT_EQ(RunCli(server.port(), {"health"}).out, "SERVING\n");
  const std::string id2 = StartKitti(stub.get(), clean, 0, 1000);
  ASSERT_FALSE(id2.empty());
  PoseCollector second(server.NewChannel(), id2, true);
  ASSERT_TRUE(second.WaitDone(60));
  EXPECT_TRUE(second.status().ok()) << second.status().error_message();
  EXPECT_EQ(second.count(), static_cast<size_t>(kFrames));
  EXPECT_EQ(WaitSessionEnd(stub.get(), id2, 30).state(), v1::SESSION_STATE_FINISHED);
  ExpectStillRunningThenCleanExit(server);
}

// --------------------------------------- 2. a recording client's disk fills --

// An in-process server (deterministic estimator: the recorder is under test)
// with a finished live session holding kPoses poses in its history.
class RecorderFaultTest : public ::testing::TestWithParam<std::string> {
 protected:
  // Enough that every format outgrows the 16 KiB limit and the 32 KiB tmpfs
  // (TUM lines of the fake estimator are ~25 bytes).
  static constexpr int kPoses = 2000;

  void SetUp() override {
    server_ = std::make_unique<LocalizationServer>(LoopbackConfig(dir_ / "work"), FakeFactory());
    port_ = server_->port();
    auto stub = MakeStub(port_);
    {
      v1::StartSessionRequest req;
      *req.mutable_live() = SmallCamera();
      req.set_history_size(kPoses);
      grpc::ClientContext ctx;
      SetDeadline(&ctx);
      v1::Session resp;
      ASSERT_TRUE(stub->StartSession(&ctx, req, &resp).ok());
      id_ = resp.id();
    }
    grpc::ClientContext ctx;
    SetDeadline(&ctx, 60);
    auto stream = stub->PushSensorData(&ctx);
    v1::PushRequest start;
    start.mutable_start()->set_session_id(id_);
    ASSERT_TRUE(stream->Write(start));
    std::thread writer([&] {
      for (int i = 0; i < kPoses; ++i) {
        if (!stream->Write(Gray8Frame((i + 1) * 100'000'000LL))) break;
      }
      stream->WritesDone();
    });
    v1::PushResponse r;
    while (stream->Read(&r)) {
      // The pusher's own pose stream may drop (bounded queue); the history
      // holds every pose (checked below).
    }
    writer.join();
    const grpc::Status s = stream->Finish();
    ASSERT_TRUE(s.ok()) << s.error_message();
    const v1::SessionStats stats = GetStats(stub.get(), id_);
    ASSERT_EQ(stats.frames_processed(), static_cast<uint64_t>(kPoses));
    ASSERT_EQ(stats.poses_published(), static_cast<uint64_t>(kPoses));
  }
  void TearDown() override {
    if (server_) server_->Shutdown();
  }

  struct Run {
    int exit_code = -1, signal = 0;
    std::string err;
  };
  Run Subscribe(const fs::path& out, rlim_t file_size_limit) {
    ChildProcess cli(CliArgv(port_, {"subscribe", id_, "--from-start", "--format", GetParam(), "--out",
                                     out.string(), "--stream-timeout-s", "60"}),
                     {dir_ / "cli.out", dir_ / "cli.err", file_size_limit});
    EXPECT_TRUE(cli.Wait(60)) << "locaid subscribe did not end";
    return {cli.exit_code(), cli.term_signal(), Slurp(dir_ / "cli.err")};
  }

  // The recorder must exit non-zero naming the file, the errno text and the
  // poses kept; the file must hold exactly those poses, complete and
  // parseable.
  void CheckCutRecord(const Run& run, const fs::path& out, const std::string& errno_text) {
    const std::string format = GetParam();
    ASSERT_EQ(run.signal, 0) << "the CLI died of signal " << run.signal << " (" << strsignal(run.signal) << ")";
    EXPECT_EQ(run.exit_code, 4) << run.err;
    EXPECT_NE(run.err.find("'" + out.string() + "'"), std::string::npos) << run.err;
    EXPECT_NE(run.err.find(errno_text), std::string::npos) << run.err;
    std::smatch m;
    ASSERT_TRUE(std::regex_search(run.err, m, std::regex("kept ([0-9]+) complete pose"))) << run.err;
    const size_t kept = std::stoul(m[1]);
    std::cout << "[ " << format << " ] " << errno_text << ": kept " << kept << " of " << kPoses << " poses, "
              << fs::file_size(out) << " bytes\n";
    EXPECT_GT(kept, 0u);
    EXPECT_LT(kept, static_cast<size_t>(kPoses));
    const std::string text = Slurp(out);
    if (format == "geojson") {
      nlohmann::json json;
      ASSERT_NO_THROW(json = nlohmann::json::parse(text)) << "GeoJSON no longer parses; ends with: "
                                                          << text.substr(text.size() - std::min<size_t>(80, text.size()));
      ASSERT_EQ(json.at("features").size(), kept);
      for (size_t i = 0; i < kept; ++i) {
        EXPECT_EQ(json["features"][i]["properties"]["sequence"].get<uint64_t>(), i);
        EXPECT_EQ(json["features"][i]["geometry"]["coordinates"].size(), 3u);
      }
      return;
    }
    ASSERT_FALSE(text.empty());
    EXPECT_EQ(text.back(), '\n') << "partial last line: " << text.substr(text.rfind('\n', text.size() - 2));
    std::vector<std::string> lines = ReadLines(out);
    if (format == "csv") {
      const auto rows = CsvRows(out, "csv");
      ASSERT_EQ(rows.size(), kept);
      for (size_t i = 0; i < rows.size(); ++i) EXPECT_EQ(rows[i][2], std::to_string(i)) << "row " << i;
      return;
    }
    ASSERT_EQ(lines.size(), kept);
    const size_t fields = format == "tum" ? 8 : 12;
    for (size_t i = 0; i < lines.size(); ++i) {
      const auto f = Split(lines[i], ' ');
      ASSERT_EQ(f.size(), fields) << "line " << i + 1 << ": " << lines[i];
      for (const auto& x : f) EXPECT_TRUE(IsNumber(x)) << "line " << i + 1 << ": '" << x << "'";
    }
    // The fake estimator moves 1 m east per pose: x of the last kept pose.
    const auto last = Split(lines.back(), ' ');
    EXPECT_DOUBLE_EQ(std::stod(last[format == "tum" ? 1 : 3]), static_cast<double>(kept - 1));
  }

  const ScopedTempDir dir_{"fault_rec"};  // records, CLI logs, the server's work_dir; outlives the server
  std::unique_ptr<LocalizationServer> server_;
  int port_ = 0;
  std::string id_;
};

TEST_P(RecorderFaultTest, FileSizeLimitKeepsAValidRecordAndExitsWithAPreciseError) {
  constexpr rlim_t kLimitBytes = 16 * 1024;
  // Unlimited, the same command records everything: the limit is the cause.
  const fs::path full = dir_ / ("full." + GetParam());
  const Run ok = Subscribe(full, 0);
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_NE(ok.err.find("received " + std::to_string(kPoses) + " poses"), std::string::npos) << ok.err;
  ASSERT_GT(fs::file_size(full), 36 * 1024u) << "the whole record must outgrow the limit and the 32 KiB tmpfs";

  const fs::path out = dir_ / ("poses." + GetParam());
  const Run run = Subscribe(out, kLimitBytes);
  CheckCutRecord(run, out, "File too large");
  EXPECT_LE(fs::file_size(out), kLimitBytes);
}

// A real full file system: a 32 KiB tmpfs mounted for the test (needs root /
// CAP_SYS_ADMIN; skipped otherwise).
TEST_P(RecorderFaultTest, FullTmpfsKeepsAValidRecordAndExitsWithAPreciseError) {
  const fs::path mnt = dir_ / "tmpfs";
  fs::create_directories(mnt);
  if (::mount("locaid-fault-test", mnt.c_str(), "tmpfs", MS_NOSUID | MS_NODEV, "size=32k,mode=0755") != 0) {
    GTEST_SKIP() << "cannot mount a small tmpfs at " << mnt << " (" << std::strerror(errno)
                 << "): needs root or CAP_SYS_ADMIN; the RLIMIT_FSIZE variant covers the recorder logic";
  }
  struct Unmount {
    fs::path p;
    ~Unmount() { ::umount2(p.c_str(), MNT_DETACH); }
  } unmount{mnt};
  const fs::path out = mnt / ("poses." + GetParam());
  const Run run = Subscribe(out, 0);
  CheckCutRecord(run, out, "No space left on device");
}

INSTANTIATE_TEST_SUITE_P(Formats, RecorderFaultTest, ::testing::Values("csv", "tum", "kitti", "geojson"),
                         [](const auto& info) { return info.param; });

// ------------------------------------------ 3. clients killed mid-stream --

// SIGKILL three of five CLI subscribers mid-stream: the others (and an
// in-test reader) get every pose, the subscriber count drops back while the
// session still runs, the server neither crashes nor stalls.
TEST(FaultTest, ClientsKilledMidStreamDoNotDisturbTheOthers) {
  const ScopedTempDir dir("fault_kill");
  constexpr int kFrames = 60;  // 6 s of sensor time, played at 2x: 3 s (30 s under TSan)
  std::string error;
  const fs::path drive = RenderSynthDrive(dir / "drive", kFrames, kSynthSeed, kSynthWidth, kSynthHeight, &error);
  ASSERT_FALSE(drive.empty()) << error;
  ServerProcess server(dir / "server");
  ASSERT_GT(server.port(), 0) << "locaid-server did not start: " << server.log();
  auto stub = v1::Localization::NewStub(server.NewChannel());
  // The session must outlast the subscribers' start-up, which a sanitizer slows.
  const std::string id = StartKitti(stub.get(), drive, 2.0 / kSanitizerSlowdown, 1000);
  ASSERT_FALSE(id.empty());

  constexpr int kClis = 5, kVictims = 3;
  std::vector<std::unique_ptr<ChildProcess>> clis;
  std::vector<fs::path> csv;
  for (int i = 0; i < kClis; ++i) {
    csv.push_back(dir / ("sub" + std::to_string(i) + ".csv"));
    clis.push_back(std::make_unique<ChildProcess>(
        CliArgv(server.port(), {"subscribe", id, "--from-start", "--format", "csv", "--out", csv.back().string(),
                                "--stream-timeout-s", "60"}),
        ChildProcess::Options{dir / ("sub" + std::to_string(i) + ".out"),
                              dir / ("sub" + std::to_string(i) + ".err"), 0}));
  }
  PoseCollector reader(server.NewChannel(1), id, true);
  const v1::SessionStats attached =
      WaitStats(stub.get(), id, 20 * kSanitizerSlowdown,
                [&](const v1::SessionStats& s) { return s.subscribers() >= kClis + 1; });
  ASSERT_EQ(attached.subscribers(), static_cast<uint32_t>(kClis + 1));

  // Mid-stream: each victim has recorded some poses, the session still runs.
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(20 * kSanitizerSlowdown);
  for (int i = 0; i < kVictims; ++i) {
    while (ReadLines(csv[static_cast<size_t>(i)]).size() < 6 && std::chrono::steady_clock::now() < until) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    ASSERT_TRUE(clis[static_cast<size_t>(i)]->Signal(SIGKILL));
  }
  for (int i = 0; i < kVictims; ++i) {
    ASSERT_TRUE(clis[static_cast<size_t>(i)]->Wait(10));
    EXPECT_EQ(clis[static_cast<size_t>(i)]->term_signal(), SIGKILL);
  }
  const v1::SessionStats after = WaitStats(
      stub.get(), id, 10, [&](const v1::SessionStats& s) { return s.subscribers() <= kClis + 1 - kVictims; });
  const v1::Session during = GetSession(stub.get(), id);
  std::cout << "[ killed   ] subscribers " << attached.subscribers() << " -> " << after.subscribers()
            << " with " << after.frames_processed() << "/" << kFrames << " frames processed, session "
            << v1::SessionState_Name(during.state()) << "\n";
  EXPECT_EQ(after.subscribers(), static_cast<uint32_t>(kClis + 1 - kVictims));
  EXPECT_EQ(during.state(), v1::SESSION_STATE_RUNNING)
      << "the session ended before the count could be checked; slow the drive down";

  // Survivors: every pose, in order, nothing dropped.
  for (int i = kVictims; i < kClis; ++i) {
    ASSERT_TRUE(clis[static_cast<size_t>(i)]->Wait(60));
    EXPECT_EQ(clis[static_cast<size_t>(i)]->exit_code(), 0) << Slurp(dir / ("sub" + std::to_string(i) + ".err"));
    const auto rows = CsvRows(csv[static_cast<size_t>(i)], "survivor " + std::to_string(i));
    ASSERT_EQ(rows.size(), static_cast<size_t>(kFrames)) << "survivor " << i;
    for (size_t k = 0; k < rows.size(); ++k) {
      EXPECT_EQ(rows[k][2], std::to_string(k));
      EXPECT_EQ(rows[k][27], "0") << "dropped";
    }
  }
  ASSERT_TRUE(reader.WaitDone(60));
  EXPECT_TRUE(reader.status().ok()) << reader.status().error_message();
  const auto poses = reader.poses();
  ASSERT_EQ(poses.size(), static_cast<size_t>(kFrames));
  for (size_t k = 0; k < poses.size(); ++k) {
    EXPECT_EQ(poses[k].sequence(), k);
    EXPECT_EQ(poses[k].dropped_for_subscriber(), 0u);
    EXPECT_TRUE(NonFinitePoseFields(poses[k]).empty()) << "pose " << k;
  }
  // Victims' files are valid up to their last pose too (append + flush).
  for (int i = 0; i < kVictims; ++i) {
    const auto rows = CsvRows(csv[static_cast<size_t>(i)], "victim " + std::to_string(i));
    EXPECT_GE(rows.size(), 5u);
    for (size_t k = 0; k < rows.size(); ++k) EXPECT_EQ(rows[k][2], std::to_string(k));
  }
  // A client sees its stream's end before the server's OnDone drops the
  // subscription: the count reaches 0 soon after, not necessarily at once.
  const v1::SessionStats end = WaitStats(stub.get(), id, 10 * kSanitizerSlowdown,
                                         [](const v1::SessionStats& s) { return s.subscribers() == 0; });
  EXPECT_EQ(end.frames_processed(), static_cast<uint64_t>(kFrames));
  EXPECT_EQ(end.subscribers(), 0u);
  EXPECT_EQ(RunCli(server.port(), {"health"}).out, "SERVING\n");
  ExpectStillRunningThenCleanExit(server);
}

// ------------------------------------- 4. SIGTERM with 100 open streams --

// 100 in-test StreamPoses streams (10 connections) and 2 CLI subscribers on a
// running session; SIGTERM: every stream ends with UNAVAILABLE, both CLIs
// exit with the status, the server exits 0. The target (an exit
// within 2 s) is a benchmark figure: printed here, asserted nowhere (the
// bounded waits only keep a hang from blocking the run).
TEST(FaultTest, SigtermWith100OpenStreamsEndsEveryStreamAndExits) {
  const ScopedTempDir dir("fault_sigterm");
  // Played at 0.1x: 60 s. The test sends SIGTERM as soon as all 102 streams
  // are attached; at 0.5x (12 s) a run beside the soak test on 2 cores saw the
  // session finish before they had all attached.
  constexpr int kFrames = 60;
  std::string error;
  const fs::path drive = RenderSynthDrive(dir / "drive", kFrames, kSynthSeed, kSynthWidth, kSynthHeight, &error);
  ASSERT_FALSE(drive.empty()) << error;
  ServerProcess server(dir / "server");
  ASSERT_GT(server.port(), 0) << "locaid-server did not start: " << server.log();
  auto stub = v1::Localization::NewStub(server.NewChannel());
  const std::string id = StartKitti(stub.get(), drive, 0.1, 1000);
  ASSERT_FALSE(id.empty());

  constexpr int kStreams = 100, kConnections = 10, kClis = 2;
  std::vector<std::shared_ptr<grpc::Channel>> channels;
  for (int c = 0; c < kConnections; ++c) channels.push_back(server.NewChannel(100 + c));
  std::vector<std::unique_ptr<PoseCollector>> streams;
  for (int i = 0; i < kStreams; ++i) {
    streams.push_back(std::make_unique<PoseCollector>(channels[static_cast<size_t>(i % kConnections)], id, true));
  }
  std::vector<std::unique_ptr<ChildProcess>> clis;
  for (int i = 0; i < kClis; ++i) {
    const std::string n = std::to_string(i);
    clis.push_back(std::make_unique<ChildProcess>(
        CliArgv(server.port(), {"subscribe", id, "--format", "csv", "--out", (dir / ("cli" + n + ".csv")).string(),
                                "--stream-timeout-s", "60"}),
        ChildProcess::Options{dir / ("cli" + n + ".out"), dir / ("cli" + n + ".err"), 0}));
  }
  const v1::SessionStats attached = WaitStats(
      stub.get(), id, 30, [&](const v1::SessionStats& s) { return s.subscribers() >= kStreams + kClis; });
  if (attached.subscribers() != static_cast<uint32_t>(kStreams + kClis)) {
    // Say which ones are missing and why (a stream that ended, a CLI that exited).
    std::string why;
    for (size_t i = 0; i < streams.size(); ++i) {
      if (!streams[i]->done()) continue;
      const grpc::Status st = streams[i]->status();
      why += "stream " + std::to_string(i) + " (connection " + std::to_string(i % kConnections) +
             ") ended: " + std::to_string(st.error_code()) + " " + st.error_message() + "\n";
    }
    for (int i = 0; i < kClis; ++i) {
      const std::string n = std::to_string(i);
      why += "cli " + n + (clis[static_cast<size_t>(i)]->Wait(0) ? " exited: " : " running: ") +
             Slurp(dir / ("cli" + n + ".err")) + "\n";
    }
    FAIL() << attached.subscribers() << " of " << kStreams + kClis << " subscribers attached within 30 s\n"
           << why << "server log:\n" << server.log();
  }
  for (auto& s : streams) ASSERT_TRUE(s->WaitPoses(1, 20)) << "a stream saw no pose";
  const v1::Session before = GetSession(stub.get(), id);
  ASSERT_EQ(before.state(), v1::SESSION_STATE_RUNNING) << "the session must still run at SIGTERM";

  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(server.process().Signal(SIGTERM));
  bool all_ended = true;
  for (auto& s : streams) all_ended = s->WaitDone(10) && all_ended;
  const double streams_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const bool exited = server.process().Wait(10);
  const double exit_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::cout << "[ sigterm  ] every in-test stream " << (all_ended ? "ended" : "NOT ended") << " after " << streams_s
            << " s\n";
  std::cout << "[ sigterm  ] " << kStreams << " streams + " << kClis << " CLIs, " << before.stats().frames_processed()
            << "/" << kFrames << " frames: server exited " << (exited ? "after " : "NOT within ") << exit_s
            << " s (issue target 2 s)\n";
  const std::string log = server.log();
  const size_t shutdown_line = log.find("shutdown:");
  if (shutdown_line != std::string::npos) {
    std::cout << "[ sigterm  ] server log: " << log.substr(shutdown_line, log.find('\n', shutdown_line) - shutdown_line)
              << "\n";
  }
  ASSERT_TRUE(exited) << log;
  EXPECT_EQ(server.process().exit_code(), 0) << server.log();
  EXPECT_NE(server.log().find("locaid-server: stopped"), std::string::npos) << server.log();

  size_t unavailable = 0;
  for (size_t i = 0; i < streams.size(); ++i) {
    ASSERT_TRUE(streams[i]->WaitDone(10)) << "stream " << i << " never ended";
    const grpc::Status s = streams[i]->status();
    unavailable += s.error_code() == grpc::UNAVAILABLE ? 1 : 0;
    EXPECT_EQ(s.error_code(), grpc::UNAVAILABLE) << "stream " << i << ": " << s.error_message();
    EXPECT_LT(streams[i]->count(), static_cast<size_t>(kFrames));
  }
  std::cout << "[ sigterm  ] " << unavailable << "/" << kStreams << " streams ended UNAVAILABLE\n";
  for (int i = 0; i < kClis; ++i) {
    const std::string n = std::to_string(i);
    ASSERT_TRUE(clis[static_cast<size_t>(i)]->Wait(10)) << "CLI " << i << " still running after the server exited";
    const std::string err = Slurp(dir / ("cli" + n + ".err"));
    EXPECT_EQ(clis[static_cast<size_t>(i)]->exit_code(), 1) << err;
    EXPECT_NE(err.find("UNAVAILABLE"), std::string::npos) << err;
    CsvRows(dir / ("cli" + n + ".csv"), "cli " + n);  // complete lines only
  }
}

}  // namespace
}  // namespace locaid::server::testing
