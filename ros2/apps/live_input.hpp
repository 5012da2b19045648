// locaid-ros2 --inputs: the car's ROS 2 topics feed a live session.
//
// Run() on the caller's thread: reads DDS (discovery and the input topics)
// until InputSetup has the topics and the rig, then starts a live session
// (StartSession{live}, so the poses can be followed from its first one) and
// feeds it through PushSensorData from the InputAssembler, while a
// SessionFollower on the session's id hands its poses to the PosePublisher.
// A session whose stream breaks (server restart) is followed by a new one
// after a backoff (0.5 s doubling to 5 s); the topics and rig are kept.
//
// Real time: the push stream takes items as the session consumes them (gRPC
// flow control). Frames waiting to be sent are at most `max_queued_frames`;
// a newer one drops the oldest waiting (counted, as the server's cameras do);
// typed items are never dropped.
//
// Threads, all joined before Run() returns: per session, the push writer,
// the push reader and the follower.
#pragma once

#include "connection/session_follower.hpp"
#include "locaid/v1/localization.grpc.pb.h"
#include "ros2/graph.hpp"
#include "ros2/input_assembler.hpp"
#include "ros2/input_setup.hpp"
#include "ros2/pose_publisher.hpp"

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <set>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace locaid::ros2 {

struct LiveInputOptions {
  std::shared_ptr<grpc::Channel> channel;
  std::string token;
  bag::BagTopics topics;            // from --inputs FILE
  InputSetupOptions setup;
  AssemblerOptions assembler;
  v1::Scenario scenario;            // empty: the server's default
  double smoothing_lag_s = 0;       // the followed stream's lag
  size_t max_queued_frames = 2;
  std::function<void(const std::string&)> log = [](const std::string&) {};
};

// What the adapter counted besides each topic's figures.
struct LiveInputCounters {
  uint64_t sessions = 0, frames_dropped_late = 0, items_sent = 0, poses_on_push_stream = 0;
  uint64_t server_rejected = 0;
  std::string server_last_rejection, session_id;
};

class LiveInput {
 public:
  // `publishing`: how the session's poses go out (its /tf_static rig and
  // extra statuses are set from the inputs).
  LiveInput(Node& node, PosePublisherOptions publishing, LiveInputOptions options);
  ~LiveInput();

  // 0 after Stop(); 1 when the inputs cannot be set up (the reason logged).
  int Run();
  void Stop();  // any thread

  // The inputs' health and the adapter's counters (any thread); empty
  // before the session's inputs are set up.
  std::vector<output::DiagnosticStatus> Health();
  LiveInputCounters counters() const;
  // Each topic's figures (any thread).
  std::vector<std::pair<InputRole, TopicStats>> topic_stats();
  double image_cpu_s();
  // The rig once set up (T_body_cam0 for /tf_static is its inverse).
  std::optional<InputRig> rig() const;
  // The poses' publisher, made once the inputs are set up (else nullptr).
  PosePublisher* publisher() const;

 private:
  bool Setup();                         // false: stopping or failed (logged)
  void RunSession(const std::string& id);
  std::string StartSession();           // "" when the server refused (logged)
  void Pump(std::chrono::milliseconds wait);  // DDS -> assembler -> outgoing queue
  void Enqueue(std::vector<v1::PushRequest>& items);
  bool stopping() const { return stopping_.load(); }
  void Prepare(grpc::ClientContext* ctx, double timeout_s) const;

  Node& node_;
  PosePublisherOptions publishing_;
  LiveInputOptions options_;
  std::unique_ptr<v1::Localization::Stub> stub_;
  std::atomic<bool> stopping_{false};

  // Input thread only.
  std::map<std::string, std::unique_ptr<Reader>> readers_;  // ROS topic -> reader
  std::map<std::string, InputRole> roles_;                  // ROS topic -> role once set up
  std::set<std::string> wrong_publications_;                // GUID text of publications already reported

  mutable std::mutex mu_;  // what other threads read
  std::condition_variable cv_;
  std::unique_ptr<InputAssembler> assembler_;
  std::unique_ptr<PosePublisher> publisher_;
  std::optional<InputRig> rig_;
  InputTopics topics_;
  std::deque<v1::PushRequest> queue_;  // outgoing, for the session's writer
  size_t queued_frames_ = 0;
  bool sending_ = false;               // a session's writer takes from queue_
  bool closing_ = false;               // the writer half-closes once the queue is empty
  LiveInputCounters counters_;
};

}  // namespace locaid::ros2
