#include "ros2/apps/live_input.hpp"

#include "connection/connection.hpp"

#include <algorithm>
#include <chrono>
#include <thread>

namespace locaid::ros2 {
namespace {

using Clock = std::chrono::steady_clock;

// How the inputs are read: sensor data best effort (it matches reliable and
// best-effort publishers alike), /tf_static as tf2 publishes it.
Qos ReaderQos(const std::string& type) {
  if (type == ros::kTfMessage) return {Reliability::kReliable, Durability::kTransientLocal, 100};
  if (type == ros::kImage || type == ros::kCompressedImage) return SensorDataQos(10);
  if (type == ros::kImu) return SensorDataQos(200);
  return SensorDataQos(20);
}

std::string Describe(const grpc::Status& s) {
  const std::string name = connection::StatusCodeName(s.error_code());
  return s.error_message().empty() ? name : name + ": " + s.error_message();
}

double SecondsSince(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

}  // namespace

LiveInput::LiveInput(Node& node, PosePublisherOptions publishing, LiveInputOptions options)
    : node_(node),
      publishing_(std::move(publishing)),
      options_(std::move(options)),
      stub_(v1::Localization::NewStub(options_.channel)) {}

LiveInput::~LiveInput() = default;

void LiveInput::Stop() {
  stopping_ = true;
  cv_.notify_all();
}

void LiveInput::Prepare(grpc::ClientContext* ctx, double timeout_s) const {
  if (timeout_s > 0) {
    ctx->set_deadline(std::chrono::system_clock::now() +
                      std::chrono::milliseconds(static_cast<int64_t>(timeout_s * 1000)));
  }
  if (!options_.token.empty()) ctx->AddMetadata("authorization", "Bearer " + options_.token);
}

int LiveInput::Run() {
  if (!Setup()) return stopping() ? 0 : 1;
  double wait_s = 0.5;
  while (!stopping()) {
    const auto started = Clock::now();
    const std::string id = StartSession();
    if (!id.empty()) RunSession(id);
    if (stopping()) break;
    if (SecondsSince(started) > 5) wait_s = 0.5;  // it ran: start over from a short wait
    options_.log("starting a new session in " + std::to_string(wait_s).substr(0, 3) + " s");
    const auto until = Clock::now() + std::chrono::duration<double>(wait_s);
    while (!stopping() && Clock::now() < until) Pump(std::chrono::milliseconds(50));  // keeps DDS drained
    wait_s = std::min(wait_s * 2, 5.0);
  }
  return 0;
}

bool LiveInput::Setup() {
  InputSetup setup(options_.topics, options_.setup);
  Participant& p = node_.participant();
  p.WatchPublications();
  const auto t0 = Clock::now();
  auto logged = t0;
  std::optional<InputRig> rig;
  std::vector<Sample> samples;
  while (!stopping() && !rig) {
    p.Wait(std::chrono::milliseconds(100));
    for (const Publication& pub : p.TakePublications()) {
      const std::string topic = RosTopicName(pub.topic), type = RosTypeName(pub.type);
      if (pub.alive && !topic.empty() && !type.empty()) setup.AddPublication(topic, type);
    }
    for (const auto& [topic, type] : setup.WantedTopics()) {
      if (!readers_.count(topic)) readers_[topic] = node_.CreateSubscription(topic, type, ReaderQos(type));
    }
    for (const auto& [topic, reader] : readers_) {
      samples.clear();
      reader->Take(samples);
      for (const Sample& s : samples) setup.AddMessage(topic, s.data);
    }
    std::string missing;
    try {
      rig = setup.TryFinish(SecondsSince(t0), &missing);
    } catch (const std::exception& e) {
      options_.log("inputs: " + std::string(e.what()));
      return false;
    }
    if (!rig && SecondsSince(logged) >= 5) {
      options_.log("waiting for the inputs: " + missing);
      logged = Clock::now();
    }
  }
  if (!rig) return false;
  const InputTopics& topics = setup.topics();
  const auto wanted = setup.WantedTopics();
  for (auto it = readers_.begin(); it != readers_.end();) {
    it = wanted.count(it->first) ? std::next(it) : readers_.erase(it);  // other cameras looked at while choosing
  }
  for (size_t i = 0; i < kInputRoleCount; ++i) {
    const std::string& topic = topics.topic[i];
    if (topic.empty()) continue;
    if (!readers_.count(topic)) readers_[topic] = node_.CreateSubscription(topic, topics.type[i], ReaderQos(topics.type[i]));
    roles_.emplace(topic, static_cast<InputRole>(i));
    options_.log("input " + std::string(InputRoleKey(static_cast<InputRole>(i))) + ": " + topic + " (" +
                 topics.type[i] + ")");
  }
  for (const std::string& note : rig->notes) options_.log(note);
  // The poses out: the rig of these inputs on /tf_static, their health on /diagnostics.
  publishing_.T_body_cam0 = rig->T_cam0_imu.inverse();
  publishing_.extra_status = [this] { return Health(); };
  auto publisher = std::make_unique<PosePublisher>(node_, publishing_);
  std::lock_guard lock(mu_);
  topics_ = topics;
  assembler_ = std::make_unique<InputAssembler>(topics, *rig, options_.assembler, options_.log);
  rig_ = std::move(rig);
  publisher_ = std::move(publisher);
  return true;
}

std::string LiveInput::StartSession() {
  v1::StartSessionRequest req;
  *req.mutable_live() = rig()->live();
  if (options_.scenario.kind_case() != v1::Scenario::KIND_NOT_SET) *req.mutable_scenario() = options_.scenario;
  grpc::ClientContext ctx;
  Prepare(&ctx, 10);
  v1::Session session;
  const grpc::Status s = stub_->StartSession(&ctx, req, &session);
  if (!s.ok()) {
    options_.log("StartSession: " + Describe(s));
    return "";
  }
  options_.log("session " + session.id() + " started (live, fed from DDS)");
  return session.id();
}

void LiveInput::Pump(std::chrono::milliseconds wait) {
  Participant& p = node_.participant();
  p.Wait(wait);
  std::vector<v1::PushRequest> out;
  std::vector<Sample> samples;
  std::lock_guard lock(mu_);
  for (const Publication& pub : p.TakePublications()) {
    const auto role = roles_.find(RosTopicName(pub.topic));
    if (!pub.alive || role == roles_.end() || !assembler_) continue;
    const std::string type = RosTypeName(pub.type);
    if (type == topics_.type_of(role->second) || !wrong_publications_.insert(GuidText(pub.guid)).second) continue;
    assembler_->WrongType(role->second, type.empty() ? pub.type : type);
  }
  const auto now = Clock::now();
  for (const auto& [topic, reader] : readers_) {
    samples.clear();
    reader->Take(samples);
    const InputRole role = roles_.at(topic);
    for (const Sample& s : samples) assembler_->Add(role, s.data, now, out);
  }
  assembler_->Tick(now, out);
  for (v1::PushRequest& item : out) {
    if (!sending_) break;  // no session: what comes meanwhile is not kept
    if (item.has_frame()) {
      if (queued_frames_ >= options_.max_queued_frames) {
        const auto oldest = std::find_if(queue_.begin(), queue_.end(), [](const v1::PushRequest& r) { return r.has_frame(); });
        queue_.erase(oldest);
        --queued_frames_;
        ++counters_.frames_dropped_late;
      }
      ++queued_frames_;
    }
    queue_.push_back(std::move(item));
  }
  cv_.notify_all();
}

void LiveInput::RunSession(const std::string& id) {
  {
    std::lock_guard lock(mu_);
    counters_.session_id = id;
    ++counters_.sessions;
  }
  publisher_->NewSession();
  std::atomic<uint64_t> followed_sequence{0}, pushed_sequence{0};
  connection::FollowerOptions follow;
  follow.channel = options_.channel;
  follow.token = options_.token;
  follow.session = id;
  follow.smoothing_lag_s = options_.smoothing_lag_s;
  follow.log = options_.log;
  connection::SessionFollower follower(follow, [](const std::string&) {}, [&](const v1::PoseUpdate& pose) {
    publisher_->Publish(pose);
    followed_sequence = pose.sequence();
  });
  std::thread follow_thread([&] { follower.Run(); });

  grpc::ClientContext ctx;
  Prepare(&ctx, 0);
  auto stream = stub_->PushSensorData(&ctx);
  v1::PushRequest start;
  start.mutable_start()->set_session_id(id);
  v1::PushResponse first;
  if (!stream->Write(start) || !stream->Read(&first) || !first.has_session()) {
    options_.log("session " + id + ": PushSensorData: " + Describe(stream->Finish()));
    follower.Stop();
    follow_thread.join();
    return;
  }
  {
    std::lock_guard lock(mu_);
    queue_.clear();
    queued_frames_ = 0;
    sending_ = true;
    closing_ = false;
  }
  std::atomic<bool> ended{false};
  std::thread reader([&] {
    v1::PushResponse r;
    while (stream->Read(&r)) {
      std::lock_guard lock(mu_);
      if (r.has_rejected()) {
        ++counters_.server_rejected;
        counters_.server_last_rejection = r.rejected().kind() + " " + std::to_string(r.rejected().index()) + ": " +
                                          r.rejected().reason();
        if (counters_.server_rejected <= 3) options_.log("the session refused " + counters_.server_last_rejection);
      } else if (r.has_pose()) {
        ++counters_.poses_on_push_stream;
        pushed_sequence = r.pose().sequence();
      }
    }
    ended = true;
    cv_.notify_all();
  });
  std::thread writer([&] {
    for (;;) {
      std::unique_lock lock(mu_);
      cv_.wait(lock, [&] { return !queue_.empty() || closing_ || ended; });
      if (ended) break;
      if (queue_.empty()) {  // closing
        lock.unlock();
        stream->WritesDone();
        break;
      }
      v1::PushRequest item = std::move(queue_.front());
      queue_.pop_front();
      if (item.has_frame()) --queued_frames_;
      lock.unlock();
      if (!stream->Write(item)) break;
      lock.lock();
      ++counters_.items_sent;
    }
  });
  while (!ended && !stopping()) Pump(std::chrono::milliseconds(50));
  if (stopping()) {
    // The end of the input: what the merge still holds, then a half-close;
    // the session processes what it got and ends the stream.
    std::vector<v1::PushRequest> rest;
    {
      std::lock_guard lock(mu_);
      assembler_->Flush(rest);
      for (auto& item : rest) queue_.push_back(std::move(item));
    }
  }
  {
    std::lock_guard lock(mu_);
    closing_ = true;
  }
  cv_.notify_all();
  const auto until = Clock::now() + std::chrono::seconds(10);
  while (!ended && Clock::now() < until) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  if (!ended) ctx.TryCancel();
  writer.join();
  reader.join();
  options_.log("session " + id + ": push stream ended: " + Describe(stream->Finish()));
  {
    std::lock_guard lock(mu_);
    sending_ = false;
    queue_.clear();
    queued_frames_ = 0;
  }
  // The follower publishes the session's last poses, then it is done.
  const auto follow_until = Clock::now() + std::chrono::seconds(5);
  while (followed_sequence < pushed_sequence && Clock::now() < follow_until)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  follower.Stop();
  follow_thread.join();
}

std::vector<output::DiagnosticStatus> LiveInput::Health() {
  std::lock_guard lock(mu_);
  if (!assembler_) return {};
  output::DiagnosticStatus h = assembler_->Health(Clock::now());
  h.hardware_id = counters_.session_id;
  h.values.insert(h.values.end(),
                  {{"session_id", counters_.session_id},
                   {"sessions", std::to_string(counters_.sessions)},
                   {"frames_dropped_late", std::to_string(counters_.frames_dropped_late)},
                   {"items_sent", std::to_string(counters_.items_sent)},
                   {"server_rejected", std::to_string(counters_.server_rejected)}});
  if (!counters_.server_last_rejection.empty()) h.values.emplace_back("server_last_rejection", counters_.server_last_rejection);
  return {std::move(h)};
}

LiveInputCounters LiveInput::counters() const {
  std::lock_guard lock(mu_);
  return counters_;
}

std::vector<std::pair<InputRole, TopicStats>> LiveInput::topic_stats() {
  std::lock_guard lock(mu_);
  return assembler_ ? assembler_->stats(Clock::now()) : std::vector<std::pair<InputRole, TopicStats>>{};
}

double LiveInput::image_cpu_s() {
  std::lock_guard lock(mu_);
  return assembler_ ? assembler_->image_cpu_s() : 0.0;
}

PosePublisher* LiveInput::publisher() const {
  std::lock_guard lock(mu_);
  return publisher_.get();
}

std::optional<InputRig> LiveInput::rig() const {
  std::lock_guard lock(mu_);
  return rig_;
}

}  // namespace locaid::ros2
