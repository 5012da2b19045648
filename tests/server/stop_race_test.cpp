// Concurrent StopSession (issue 30): two clients stopping (and removing) the
// same session at the same moment, on every source kind, and stops racing a
// SIGTERM, against the real locaid-server process. The server must answer
// every call, stay up, remove a session exactly once and exit 0 on SIGTERM.
#include "test_support.hpp"

#include <atomic>
#include <set>

namespace locaid::server::testing {
namespace {

namespace fs = std::filesystem;

// A generous deadline: a call that takes longer has hung (the stop itself
// takes milliseconds; the bound on its latency is a benchmark's business).
constexpr double kHungS = 20;

enum class Kind { kKitti, kSynthetic, kLive };
enum class Race { kStopStop, kStopRemove, kRemoveRemove };

const char* Name(Kind k) { return k == Kind::kKitti ? "kitti" : k == Kind::kSynthetic ? "synthetic" : "live"; }

class StopRace : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    drive_ = RenderSynthDrive(dir_.path() / "drive", 20, 5, 320, 120, &error);
    ASSERT_FALSE(drive_.empty()) << error;
    server_ = std::make_unique<ServerProcess>(dir_.path() / "server",
                                              std::vector<std::string>{"--max-concurrent-renders", "8"});
    ASSERT_GT(server_->port(), 0) << server_->log();
    stub_ = v1::Localization::NewStub(server_->NewChannel());
  }

  // Starts a session of `kind`; retries while the server says
  // RESOURCE_EXHAUSTED (renders of stopped sessions still ending: each at its
  // next cancellation point, one texture of the set-up, which under a
  // sanitizer with 8 renders on 2 cores takes tens of seconds). Bounded in
  // time, as a hang would be.
  std::string Start(Kind kind) {
    v1::StartSessionRequest req;
    switch (kind) {
      case Kind::kKitti: req.mutable_kitti()->set_path(drive_.string()); break;
      case Kind::kSynthetic:  // small frames: the stop lands while it renders, and 300 renders stay cheap
        req.mutable_synthetic()->set_seed(3);
        req.mutable_synthetic()->set_frames(400);
        req.mutable_synthetic()->set_options_yaml("width: 160\nheight: 64\n");
        break;
      case Kind::kLive: *req.mutable_live() = SmallCamera(); break;
    }
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(180);
    while (std::chrono::steady_clock::now() < give_up) {
      grpc::ClientContext ctx;
      SetDeadline(&ctx, kHungS);
      v1::Session out;
      const grpc::Status s = stub_->StartSession(&ctx, req, &out);
      if (s.ok()) return out.id();
      if (s.error_code() != grpc::StatusCode::RESOURCE_EXHAUSTED) {
        ADD_FAILURE() << Name(kind) << ": StartSession: " << s.error_message();
        return "";
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    ADD_FAILURE() << Name(kind) << ": StartSession kept answering RESOURCE_EXHAUSTED for 180 s";
    return "";
  }

  grpc::Status Stop(v1::Localization::Stub* stub, const std::string& id, bool remove, v1::Session* out) {
    grpc::ClientContext ctx;
    SetDeadline(&ctx, kHungS);
    v1::StopSessionRequest req;
    req.set_session_id(id);
    req.set_remove(remove);
    return stub->StopSession(&ctx, req, out);
  }

  // One race: two threads, each on its own connection, released together.
  void RunRace(Kind kind, Race race, int iteration) {
    const std::string id = Start(kind);
    ASSERT_FALSE(id.empty());
    const bool remove[2] = {race != Race::kStopStop, race == Race::kRemoveRemove};
    std::atomic<int> ready{0};
    grpc::Status status[2];
    v1::Session answer[2];
    std::vector<std::thread> threads;
    for (int t = 0; t < 2; ++t) {
      threads.emplace_back([&, t] {
        auto stub = v1::Localization::NewStub(server_->NewChannel(1 + t));
        ready.fetch_add(1);
        while (ready.load() < 2) std::this_thread::yield();
        status[t] = Stop(stub.get(), id, remove[t], &answer[t]);
      });
    }
    for (auto& th : threads) th.join();
    const std::string what = std::string(Name(kind)) + " race " + std::to_string(static_cast<int>(race)) +
                             " iteration " + std::to_string(iteration) + ": ";
    for (int t = 0; t < 2; ++t) {
      // The later of two removing calls may find the session gone already.
      const bool gone_ok = remove[0] && status[t].error_code() == grpc::StatusCode::NOT_FOUND;
      ASSERT_TRUE(status[t].ok() || gone_ok) << what << "call " << t << ": " << status[t].error_code() << " "
                                             << status[t].error_message() << "\n" << server_->log();
      if (status[t].ok()) {
        EXPECT_TRUE(answer[t].state() == v1::SESSION_STATE_STOPPED || answer[t].state() == v1::SESSION_STATE_FINISHED)
            << what << "state " << answer[t].state();
      }
    }
    v1::Session now;
    const grpc::Status after = FetchSession(stub_.get(), id, &now);
    if (remove[0]) {
      EXPECT_EQ(after.error_code(), grpc::StatusCode::NOT_FOUND) << what << "removed session still answers";
    } else {
      ASSERT_TRUE(after.ok()) << what << after.error_message();
      EXPECT_TRUE(now.state() == v1::SESSION_STATE_STOPPED || now.state() == v1::SESSION_STATE_FINISHED) << what;
      // Its thread ends after the frame in progress (reaper); then remove it.
      v1::Session removed;
      EXPECT_TRUE(Stop(stub_.get(), id, true, &removed).ok()) << what;
    }
  }

  // Every session the server lists, by id.
  std::set<std::string> Listed() {
    grpc::ClientContext ctx;
    SetDeadline(&ctx, kHungS);
    v1::ListSessionsResponse list;
    EXPECT_TRUE(stub_->ListSessions(&ctx, v1::ListSessionsRequest{}, &list).ok());
    std::set<std::string> ids;
    for (const auto& s : list.sessions()) ids.insert(s.id());
    return ids;
  }

  // `iterations` races of each kind; with `rotate`, one race per iteration,
  // the kinds in turn (a synthetic session costs a world set-up, ~0.6 s CPU).
  void Hammer(Kind kind, int iterations, bool rotate = false) {
    const Race races[] = {Race::kStopStop, Race::kStopRemove, Race::kRemoveRemove};
    for (int i = 0; i < iterations && !HasFatalFailure(); ++i) {
      if (rotate) {
        RunRace(kind, races[i % 3], i);
      } else {
        for (Race race : races) RunRace(kind, race, i);
      }
    }
    EXPECT_TRUE(Listed().empty()) << "every session was removed";
    EXPECT_EQ(RunCli(server_->port(), {"health"}).out, "SERVING\n") << server_->log();
    ASSERT_TRUE(server_->process().Signal(SIGTERM));
    ASSERT_TRUE(server_->process().Wait(60)) << "SIGTERM did not end the server\n" << server_->log();
    EXPECT_EQ(server_->process().exit_code(), 0) << "signal " << server_->process().term_signal() << "\n"
                                                 << server_->log();
  }

  locaid::test_support::ScopedTempDir dir_{"stop_race"};
  fs::path drive_;
  std::unique_ptr<ServerProcess> server_;
  std::unique_ptr<v1::Localization::Stub> stub_;
};

TEST_F(StopRace, KittiSessionsStoppedTwiceAtOnce) { Hammer(Kind::kKitti, 100); }
TEST_F(StopRace, SyntheticSessionsStoppedTwiceAtOnce) { Hammer(Kind::kSynthetic, 100, /*rotate=*/true); }
TEST_F(StopRace, LiveSessionsStoppedTwiceAtOnce) { Hammer(Kind::kLive, 100); }

// Stops in flight while the server is told to end: every call is answered
// (OK, or UNAVAILABLE once the server is going), and the process exits 0.
TEST_F(StopRace, StopsDuringSigtermEndCleanly) {
  std::vector<std::string> ids;
  for (Kind kind : {Kind::kKitti, Kind::kSynthetic, Kind::kLive}) {
    for (int i = 0; i < 3; ++i) ids.push_back(Start(kind));
  }
  std::atomic<bool> go{false};
  std::vector<std::thread> threads;
  std::atomic<int> bad{0};
  std::mutex mu;
  std::string bad_text;
  for (size_t t = 0; t < ids.size(); ++t) {
    threads.emplace_back([&, t] {
      auto stub = v1::Localization::NewStub(server_->NewChannel(static_cast<int>(t) + 1));
      while (!go.load()) std::this_thread::yield();
      for (bool remove : {false, true}) {
        v1::Session out;
        const grpc::Status s = Stop(stub.get(), ids[t], remove, &out);
        const auto code = s.error_code();
        if (code != grpc::StatusCode::OK && code != grpc::StatusCode::UNAVAILABLE &&
            code != grpc::StatusCode::NOT_FOUND && code != grpc::StatusCode::CANCELLED) {
          bad.fetch_add(1);
          std::lock_guard lock(mu);
          bad_text += std::to_string(code) + " " + s.error_message() + "\n";
        }
      }
    });
  }
  go = true;
  ASSERT_TRUE(server_->process().Signal(SIGTERM));
  for (auto& th : threads) th.join();
  EXPECT_EQ(bad.load(), 0) << bad_text;
  ASSERT_TRUE(server_->process().Wait(60)) << "SIGTERM did not end the server\n" << server_->log();
  EXPECT_EQ(server_->process().exit_code(), 0) << "signal " << server_->process().term_signal() << "\n"
                                               << server_->log();
}

}  // namespace
}  // namespace locaid::server::testing
