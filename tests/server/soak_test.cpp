// Soak / load test of the real locaid-server process (issue 7), loopback only,
// bounded in count and time.
//
// Live sessions start and stop over time (created by StartSession, fed small
// 32x24 GRAY8 frames + OXTS lines through PushSensorData at ~20 fps, then
// half-closed and removed). A pool of subscriber workers connects and
// disconnects at random (seeded): each subscriber opens its OWN connection
// (local subchannel pool), picks a running session, streams for a random
// time, then its deadline disconnects it (or the session ends first).
//   keepers (large queue, read promptly): must lose no pose (sequence and
//     frame_index +1 each, dropped_for_subscriber == 0); a from-start keeper
//     per session must see every pose the session published.
//   slow ones (queue of kSlowQueue, sleep between reads): the gaps they see
//     must equal the growth of dropped_for_subscriber (drops are counted
//     exactly), and their server-side queue stays bounded.
// Stats must add up: frames pushed == frames_in == frames_processed ==
// poses_published == poses back on the push stream == poses of the
// from-start keeper; per subscriber delivered + dropped + queued <=
// published; dropped_total >= the drops the clients saw.
// Memory: VmRSS of the server after a warm-up phase (same load, shorter) and
// after the main phase, both measured idle (all sessions removed, all
// subscribers gone); the second must be within kMaxRssGrowth of the first
// (printed, not checked, in an AddressSanitizer build: its quarantine keeps
// freed memory).
// Coverage: the main phase goes on (another round of the same length) until
// it has exercised every path: sessions that ended while others started, a
// slow subscriber that lost poses, streams ended by their session and by
// their deadline. How much load a machine carries per second is no assertion
// (bench/ measures it); only a phase that never gets there fails.
//
// Duration of a round of the main phase: LOCAID_SOAK_SECONDS (default 45). A
// few minutes: `LOCAID_SOAK_SECONDS=300 ctest -R Soak --output-on-failure`.
#include "test_support.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <fstream>
#include <map>
#include <mutex>
#include <random>
#include <sys/types.h>
#include <thread>
#include <unistd.h>

namespace locaid::server::testing {
namespace {

using Clock = std::chrono::steady_clock;

constexpr double kDefaultSoakSeconds = 45;
constexpr double kMaxSoakSeconds = 600;          // all rounds; + warm-up and drain stays under the CTest TIMEOUT (900 s)
constexpr int kMaxRounds = 3;                    // main-phase rounds until every path was exercised
constexpr double kMaxRssGrowth = 0.10;           // end RSS <= warm RSS * (1 + this)
constexpr int kSubscriberWorkers = 100;          // max concurrent subscribers
constexpr int kConcurrentSessions = 3;
constexpr int64_t kFramePeriodNs = 50'000'000;   // 20 fps, sensor clock and wall pacing
constexpr uint32_t kKeeperQueue = 5000;          // > frames of any session: never full
constexpr uint32_t kSlowQueue = 8;
constexpr uint32_t kHistory = 5000;              // from-start subscribers get everything
constexpr double kKeeperFraction = 0.7;
constexpr uint64_t kSeed = 20261122;

double SoakSeconds() {
  const char* env = std::getenv("LOCAID_SOAK_SECONDS");
  double s = kDefaultSoakSeconds;
  if (env && *env) s = std::strtod(env, nullptr);
  if (!(s >= 5)) s = 5;
  return std::min(s, kMaxSoakSeconds);
}

// The real server binary on 127.0.0.1, port picked by the OS; its port
// file and work_dir in a folder of its own.
class ServerProcess {
 public:
  ServerProcess() {
    const auto port_file = dir_ / "port";
    const std::string bin = std::string(LOCAID_BIN_DIR) + "/locaid-server";
    const std::string pf = port_file.string(), work = (dir_ / "work").string();
    pid_ = fork();
    if (pid_ == 0) {
      execl(bin.c_str(), bin.c_str(), "--listen", "127.0.0.1:0", "--port-file", pf.c_str(), "--work-dir",
            work.c_str(), "--shutdown-grace-s", "1", "--max-sessions", "8", static_cast<char*>(nullptr));
      _exit(127);
    }
    for (int i = 0; i < 1000 && port_ == 0 && alive(); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      std::ifstream in(port_file);
      in >> port_;
    }
  }
  ~ServerProcess() {
    if (pid_ > 0 && alive()) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
  }
  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  bool alive() {
    if (exited_) return false;
    int status = 0;
    const pid_t r = waitpid(pid_, &status, WNOHANG);
    if (r == pid_) {
      exited_ = true;
      status_ = status;
    }
    return !exited_;
  }
  // SIGTERM, bounded wait; returns the exit status or -1.
  int Terminate() {
    if (!alive()) return WIFEXITED(status_) ? WEXITSTATUS(status_) : -1;
    kill(pid_, SIGTERM);
    for (int i = 0; i < 1500 && alive(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    if (alive()) return -1;
    return WIFEXITED(status_) ? WEXITSTATUS(status_) : -1;
  }
  std::string Describe() const {
    if (!exited_) return "running";
    if (WIFSIGNALED(status_)) return "killed by signal " + std::to_string(WTERMSIG(status_));
    return "exited " + std::to_string(WEXITSTATUS(status_));
  }

 private:
  const ScopedTempDir dir_{"soak"};
  pid_t pid_ = -1;
  int port_ = 0;
  bool exited_ = false;
  int status_ = 0;
};

// small_window: a 1 KiB HTTP/2 window, so a slow reader's poses wait in the
// server's queue (where drops happen) instead of the transport buffers.
std::unique_ptr<v1::Localization::Stub> OwnConnection(int port, bool small_window = false) {
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);  // a new TCP connection per subscriber
  if (small_window) {
    args.SetInt(GRPC_ARG_HTTP2_STREAM_LOOKAHEAD_BYTES, 1024);
    args.SetInt(GRPC_ARG_HTTP2_BDP_PROBE, 0);
  }
  return v1::Localization::NewStub(
      grpc::CreateCustomChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials(), args));
}

// Per-session client-side accounting (filled by subscribers, read at the end).
struct SessionLedger {
  std::mutex mu;
  uint64_t published = 0;       // poses_published when the input ended
  uint64_t dropped_total = 0;   // server's dropped_total after the input ended
  uint64_t client_seen_drops = 0;
};

// Everything the phase counts; printed at the end.
struct Figures {
  std::atomic<int> sessions{0}, subscribers{0}, keepers{0}, slow{0}, from_start{0};
  std::atomic<int> ended_ok{0}, disconnected{0}, raced_removal{0}, max_concurrent{0}, concurrent{0};
  std::atomic<uint64_t> frames_pushed{0}, poses_to_keepers{0}, poses_to_slow{0}, drops_seen{0};
  std::mutex mu;
  std::vector<std::string> failures;
  void Fail(const std::string& what) {
    std::lock_guard lock(mu);
    if (failures.size() < 50) failures.push_back(what);
  }
};

class Load {
 public:
  Load(int port, uint64_t seed, Figures* fig) : port_(port), seed_(seed), fig_(fig), control_(MakeStub(port)) {}

  // Runs sessions and subscribers for `seconds`, then waits for every thread
  // and removes every session.
  void Run(double seconds) {
    deadline_ = Clock::now() + std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000));
    std::vector<std::thread> session_threads;
    for (int s = 0; s < kConcurrentSessions; ++s) {
      session_threads.emplace_back([this, s] {
        std::mt19937_64 rng(seed_ * 31 + static_cast<uint64_t>(s));
        // Staggered starts so sessions begin and end at different times.
        std::this_thread::sleep_for(std::chrono::milliseconds(700 * s));
        while (Clock::now() < deadline_) RunOneSession(rng);
      });
    }
    std::vector<std::thread> workers;
    for (int w = 0; w < kSubscriberWorkers; ++w) {
      workers.emplace_back([this, w] {
        std::mt19937_64 rng(seed_ * 1000003 + static_cast<uint64_t>(w));
        std::uniform_int_distribution<int> idle_ms(0, 2000);
        while (Clock::now() < deadline_) {
          std::this_thread::sleep_for(std::chrono::milliseconds(idle_ms(rng)));
          if (Clock::now() >= deadline_) break;
          RunOneSubscriber(rng);
        }
      });
    }
    for (auto& t : workers) t.join();
    for (auto& t : session_threads) t.join();
    // Cross-check drops per session now that every subscriber has ended.
    std::lock_guard lock(ledgers_mu_);
    for (auto& [id, ledger] : ledgers_) {
      std::lock_guard l2(ledger->mu);
      if (ledger->client_seen_drops > ledger->dropped_total) {
        fig_->Fail(id + ": clients saw " + std::to_string(ledger->client_seen_drops) +
                   " drops but dropped_total is " + std::to_string(ledger->dropped_total));
      }
    }
  }

 private:
  v1::SessionStats Stats(const std::string& id) {
    v1::SessionStats stats;
    const grpc::Status s = FetchStats(control_.get(), id, &stats);
    if (!s.ok()) fig_->Fail("GetStats " + id + ": " + s.error_message());
    return stats;
  }

  std::pair<std::string, std::shared_ptr<SessionLedger>> PickSession(std::mt19937_64& rng) {
    std::lock_guard lock(running_mu_);
    if (running_.empty()) return {};
    std::uniform_int_distribution<size_t> pick(0, running_.size() - 1);
    auto it = running_.begin();
    std::advance(it, static_cast<std::ptrdiff_t>(pick(rng)));
    return *it;
  }

  // One subscriber: its own connection, a random session, keeper or slow,
  // disconnected by its deadline unless the session ends first.
  void RunOneSubscriber(std::mt19937_64& rng) {
    auto [id, ledger] = PickSession(rng);
    if (id.empty()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      return;
    }
    const bool keeper = std::uniform_real_distribution<double>(0, 1)(rng) < kKeeperFraction;
    const bool from_start = keeper && (rng() % 2 == 0);
    const double lifetime_s = std::uniform_real_distribution<double>(1.0, 20.0)(rng);
    const int slow_sleep_ms = std::uniform_int_distribution<int>(60, 150)(rng);
    ++fig_->subscribers;
    ++(keeper ? fig_->keepers : fig_->slow);
    if (from_start) ++fig_->from_start;
    const int now = ++fig_->concurrent;
    for (int m = fig_->max_concurrent.load(); now > m && !fig_->max_concurrent.compare_exchange_weak(m, now);) {
    }
    auto stub = OwnConnection(port_, !keeper);
    grpc::ClientContext ctx;
    SetDeadline(&ctx, lifetime_s);
    v1::StreamPosesRequest req;
    req.set_session_id(id);
    req.set_from_start(from_start);
    req.set_queue_size(keeper ? kKeeperQueue : kSlowQueue);
    auto reader = stub->StreamPoses(&ctx, req);
    v1::PoseUpdate p, prev;
    uint64_t n = 0, last_dropped = 0;
    bool first = true;
    const std::string who = id + (keeper ? " keeper" : " slow") + (from_start ? "/from-start" : "");
    while (reader->Read(&p)) {
      ++n;
      if (p.session_id() != id) fig_->Fail(who + ": pose of session " + p.session_id());
      if (keeper) {
        if (p.dropped_for_subscriber() != 0) fig_->Fail(who + ": dropped_for_subscriber " + std::to_string(p.dropped_for_subscriber()));
        if (first && from_start && p.sequence() != 0) fig_->Fail(who + ": first sequence " + std::to_string(p.sequence()));
        if (!first && (p.sequence() != prev.sequence() + 1 || p.frame_index() != prev.frame_index() + 1)) {
          fig_->Fail(who + ": sequence " + std::to_string(prev.sequence()) + " -> " + std::to_string(p.sequence()) +
                     ", frame_index " + std::to_string(prev.frame_index()) + " -> " + std::to_string(p.frame_index()));
        }
      } else {
        if (!first) {
          const uint64_t gap = p.sequence() - prev.sequence() - 1;
          const uint64_t counted = p.dropped_for_subscriber() - prev.dropped_for_subscriber();
          if (p.sequence() <= prev.sequence() || gap != counted) {
            fig_->Fail(who + ": sequence " + std::to_string(prev.sequence()) + " -> " + std::to_string(p.sequence()) +
                       " but dropped_for_subscriber grew by " + std::to_string(counted));
          }
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(slow_sleep_ms));
      }
      last_dropped = p.dropped_for_subscriber();
      prev = p;
      first = false;
    }
    const grpc::Status s = reader->Finish();
    --fig_->concurrent;
    (keeper ? fig_->poses_to_keepers : fig_->poses_to_slow) += n;
    fig_->drops_seen += last_dropped;
    {
      std::lock_guard lock(ledger->mu);
      ledger->client_seen_drops += last_dropped;
    }
    if (s.ok()) {
      ++fig_->ended_ok;
    } else if (s.error_code() == grpc::DEADLINE_EXCEEDED) {
      ++fig_->disconnected;
    } else if (s.error_code() == grpc::NOT_FOUND && n == 0) {
      ++fig_->raced_removal;  // picked just before the session was removed
    } else {
      fig_->Fail(who + ": stream ended with " + std::to_string(s.error_code()) + " " + s.error_message());
    }
  }

  // One live session from start to removal.
  void RunOneSession(std::mt19937_64& rng) {
    const double remaining_s =
        std::chrono::duration<double>(deadline_ - Clock::now()).count();
    if (remaining_s < 1.5) {
      std::this_thread::sleep_for(std::chrono::milliseconds(static_cast<int64_t>(std::max(0.0, remaining_s) * 1000)));
      return;
    }
    const double life_s = std::min(remaining_s, std::uniform_real_distribution<double>(4.0, 12.0)(rng));
    const int frames = std::max(10, static_cast<int>(life_s * 1e9 / kFramePeriodNs));
    std::string id;
    {
      v1::StartSessionRequest req;
      *req.mutable_live() = SmallCamera();
      req.set_history_size(kHistory);
      grpc::ClientContext ctx;
      SetDeadline(&ctx, 10);
      v1::Session resp;
      const grpc::Status s = control_->StartSession(&ctx, req, &resp);
      if (!s.ok()) {
        fig_->Fail("StartSession: " + s.error_message());
        std::this_thread::sleep_for(std::chrono::milliseconds(500));
        return;
      }
      id = resp.id();
    }
    ++fig_->sessions;
    auto ledger = std::make_shared<SessionLedger>();
    {
      std::lock_guard lock(ledgers_mu_);
      ledgers_[id] = ledger;
    }
    // The from-start keeper that must see every pose.
    std::vector<v1::PoseUpdate> all;
    grpc::Status all_status;
    auto all_stub = OwnConnection(port_);
    grpc::ClientContext all_ctx;
    SetDeadline(&all_ctx, life_s + 120);
    std::thread all_reader([&] {
      v1::StreamPosesRequest req;
      req.set_session_id(id);
      req.set_from_start(true);
      req.set_queue_size(kKeeperQueue);
      auto reader = all_stub->StreamPoses(&all_ctx, req);
      v1::PoseUpdate p;
      while (reader->Read(&p)) all.push_back(p);
      all_status = reader->Finish();
    });
    {
      std::lock_guard lock(running_mu_);
      running_[id] = ledger;
    }
    // Push stream attached to the session; a reader collects its poses.
    grpc::ClientContext push_ctx;
    SetDeadline(&push_ctx, life_s + 120);
    auto push = control_->PushSensorData(&push_ctx);
    v1::PushRequest start;
    start.mutable_start()->set_session_id(id);
    *start.mutable_start()->mutable_live() = SmallCamera();
    v1::PushResponse first;
    if (!push->Write(start) || !push->Read(&first) || !first.has_session()) {
      fig_->Fail(id + ": push stream did not start");
    }
    std::atomic<uint64_t> push_poses{0};
    std::atomic<uint64_t> push_rejected{0};
    std::thread push_reader([&] {
      v1::PushResponse r;
      while (push->Read(&r)) {
        if (r.has_pose()) ++push_poses;
        if (r.has_rejected()) ++push_rejected;
      }
    });
    const auto t0 = Clock::now();
    for (int i = 0; i < frames; ++i) {
      const int64_t t = (i + 1) * kFramePeriodNs;
      std::this_thread::sleep_until(t0 + std::chrono::nanoseconds(i * kFramePeriodNs));
      if (!push->Write(Oxts(t - kFramePeriodNs / 2, OxtsLine(49.0 + 1e-6 * i, 8.4))) || !push->Write(Gray8Frame(t))) {
        fig_->Fail(id + ": push write failed at frame " + std::to_string(i));
        break;
      }
      ++fig_->frames_pushed;
    }
    // Every frame back as a pose on the push stream, then the books.
    for (int i = 0; i < 3000 && push_poses.load() < static_cast<uint64_t>(frames); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    const v1::SessionStats st = Stats(id);
    const uint64_t n = static_cast<uint64_t>(frames);
    if (push_poses.load() != n || st.frames_in() != n || st.frames_processed() != n || st.poses_published() != n ||
        push_rejected.load() != 0) {
      fig_->Fail(id + ": pushed " + std::to_string(n) + " frames, push stream got " + std::to_string(push_poses.load()) +
                 " poses (" + std::to_string(push_rejected.load()) + " rejected), stats frames_in " +
                 std::to_string(st.frames_in()) + " frames_processed " + std::to_string(st.frames_processed()) +
                 " poses_published " + std::to_string(st.poses_published()));
    }
    for (const auto& sub : st.subscriber()) {
      if (sub.delivered() + sub.dropped() + sub.queued() > st.poses_published()) {
        fig_->Fail(id + ": subscriber " + std::to_string(sub.id()) + " delivered " + std::to_string(sub.delivered()) +
                   " + dropped " + std::to_string(sub.dropped()) + " + queued " + std::to_string(sub.queued()) +
                   " > published " + std::to_string(st.poses_published()));
      }
      if (sub.dropped() > 0 && sub.queued() > kSlowQueue) {
        fig_->Fail(id + ": a dropping subscriber has " + std::to_string(sub.queued()) + " queued (> " +
                   std::to_string(kSlowQueue) + ")");
      }
    }
    {
      std::lock_guard lock(running_mu_);
      running_.erase(id);
    }
    push->WritesDone();
    push_reader.join();
    const grpc::Status ps = push->Finish();
    if (!ps.ok()) fig_->Fail(id + ": push stream ended with " + ps.error_message());
    all_reader.join();  // the session finished: the from-start keeper's stream ends
    if (!all_status.ok()) fig_->Fail(id + ": from-start keeper ended with " + all_status.error_message());
    if (all.size() != n) {
      fig_->Fail(id + ": from-start keeper got " + std::to_string(all.size()) + " of " + std::to_string(n) + " poses");
    }
    for (size_t i = 0; i < all.size(); ++i) {
      if (all[i].sequence() != i || all[i].frame_index() != static_cast<int64_t>(i) ||
          all[i].dropped_for_subscriber() != 0) {
        fig_->Fail(id + ": from-start keeper pose " + std::to_string(i) + " has sequence " +
                   std::to_string(all[i].sequence()) + " frame_index " + std::to_string(all[i].frame_index()) +
                   " dropped " + std::to_string(all[i].dropped_for_subscriber()));
        break;
      }
    }
    fig_->poses_to_keepers += all.size();
    // Input over: no more publishes, so dropped_total is final.
    const v1::SessionStats end = Stats(id);
    {
      std::lock_guard lock(ledger->mu);
      ledger->published = end.poses_published();
      ledger->dropped_total = end.dropped_total();
    }
    grpc::ClientContext stop_ctx;
    SetDeadline(&stop_ctx, 10);
    v1::StopSessionRequest stop;
    stop.set_session_id(id);
    stop.set_remove(true);
    v1::Session stopped;
    const grpc::Status ss = control_->StopSession(&stop_ctx, stop, &stopped);
    if (!ss.ok()) fig_->Fail(id + ": StopSession(remove): " + ss.error_message());
  }

  const int port_;
  const uint64_t seed_;
  Figures* fig_;
  std::unique_ptr<v1::Localization::Stub> control_;
  Clock::time_point deadline_;
  std::mutex running_mu_;
  std::map<std::string, std::shared_ptr<SessionLedger>> running_;
  std::mutex ledgers_mu_;
  std::map<std::string, std::shared_ptr<SessionLedger>> ledgers_;
};

int ListedSessions(int port) {
  auto stub = MakeStub(port);
  grpc::ClientContext ctx;
  SetDeadline(&ctx, 10);
  v1::ListSessionsResponse resp;
  if (!stub->ListSessions(&ctx, v1::ListSessionsRequest{}, &resp).ok()) return -1;
  return resp.sessions_size();
}

void PrintFigures(const char* phase, double seconds, const Figures& f) {
  std::printf(
      "[soak] %s %.0f s: sessions %d, frames pushed %llu, subscribers %d (keepers %d, from-start %d, slow %d), "
      "max concurrent %d, ended with the session %d, disconnected by deadline %d, raced removal %d, "
      "poses to keepers %llu, poses to slow %llu, drops seen by slow %llu\n",
      phase, seconds, f.sessions.load(), static_cast<unsigned long long>(f.frames_pushed.load()),
      f.subscribers.load(), f.keepers.load(), f.from_start.load(), f.slow.load(), f.max_concurrent.load(),
      f.ended_ok.load(), f.disconnected.load(), f.raced_removal.load(),
      static_cast<unsigned long long>(f.poses_to_keepers.load()),
      static_cast<unsigned long long>(f.poses_to_slow.load()), static_cast<unsigned long long>(f.drops_seen.load()));
  std::fflush(stdout);
}

// The paths a main phase must have exercised; "" when it has.
std::string NotExercised(const Figures& f) {
  std::string missing;
  if (f.sessions.load() <= kConcurrentSessions) missing += " sessions that ended while others started;";
  if (f.drops_seen.load() == 0) missing += " a slow subscriber that lost poses (drop accounting);";
  if (f.ended_ok.load() == 0) missing += " a stream ended by its session;";
  if (f.disconnected.load() == 0) missing += " a stream ended by its deadline;";
  return missing;
}

void ExpectNoFailures(const Figures& f, const char* phase) {
  EXPECT_TRUE(f.failures.empty()) << phase << ": " << f.failures.size() << " failure(s), first: "
                                  << (f.failures.empty() ? "" : f.failures.front());
  for (size_t i = 1; i < f.failures.size() && i < 10; ++i) ADD_FAILURE() << phase << ": " << f.failures[i];
}

TEST(Soak, ChurningSubscribersWhileSessionsStartAndStop) {
  const double soak_s = SoakSeconds();
  const double warm_s = std::clamp(soak_s / 4, 8.0, 30.0);
  constexpr double kSettleS = 2.0;  // idle time before reading RSS
  ServerProcess server;
  ASSERT_GT(server.port(), 0) << "locaid-server did not write its port (" << server.Describe() << ")";

  Figures warm;
  Load(server.port(), kSeed, &warm).Run(warm_s);
  PrintFigures("warm-up", warm_s, warm);
  ASSERT_TRUE(server.alive()) << "server died during warm-up: " << server.Describe();
  ExpectNoFailures(warm, "warm-up");
  EXPECT_EQ(ListedSessions(server.port()), 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(static_cast<int64_t>(kSettleS * 1000)));
  const long rss_warm_kb = VmRssKb(server.pid());

  Figures main;
  int rounds = 0;
  do {
    Load(server.port(), kSeed + 1 + static_cast<uint64_t>(rounds), &main).Run(soak_s);
    ++rounds;
    PrintFigures("load", soak_s * rounds, main);
    ASSERT_TRUE(server.alive()) << "server died under load: " << server.Describe();
  } while (!NotExercised(main).empty() && rounds < kMaxRounds && soak_s * (rounds + 1) <= kMaxSoakSeconds);
  ExpectNoFailures(main, "load");
  EXPECT_EQ(NotExercised(main), "") << "not exercised in " << rounds << " rounds of " << soak_s << " s";
  EXPECT_EQ(ListedSessions(server.port()), 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(static_cast<int64_t>(kSettleS * 1000)));
  const long rss_end_kb = VmRssKb(server.pid());

  const double growth = static_cast<double>(rss_end_kb - rss_warm_kb) / static_cast<double>(rss_warm_kb);
  std::printf("[soak] server VmRSS after warm-up %ld kB, after load %ld kB (%+.1f %%, limit +%.0f %%)\n", rss_warm_kb,
              rss_end_kb, 100 * growth, 100 * kMaxRssGrowth);
  ASSERT_GT(rss_warm_kb, 0);
  if (kUnderAddressSanitizer) {
    // ASan holds freed blocks in its quarantine (256 MB by default) and pads
    // every allocation, so RSS grows with the load whatever the server keeps;
    // the load itself still runs under ASan's checks.
    std::printf("[soak] RSS growth not checked: the server is built with AddressSanitizer\n");
  } else {
    EXPECT_LE(growth, kMaxRssGrowth) << "server memory grew from " << rss_warm_kb << " kB to " << rss_end_kb << " kB";
  }
  EXPECT_EQ(server.Terminate(), 0) << server.Describe();
}

}  // namespace
}  // namespace locaid::server::testing
