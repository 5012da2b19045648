#include "server/camera_feeder.hpp"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <utility>

namespace locaid::server {
namespace {

constexpr int64_t kPullTimeoutNs = 20'000'000;  // one side's wait per turn of the loop
constexpr int64_t kNsPerS = 1'000'000'000;

int64_t ToNs(double seconds) { return static_cast<int64_t>(seconds * 1e9); }

int64_t UnixNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::string SizeText(int w, int h) { return std::to_string(w) + "x" + std::to_string(h) + " px"; }

}  // namespace

CameraFeeder::CameraFeeder(const CameraSetup& setup, pipeline::LiveFrameSource* sink)
    : setup_(setup),
      sink_(sink),
      rectified_(ros::MakeRectifiedStereo(setup.left_info, setup.right_info)),
      pairer_(ToNs(setup.pair_tolerance_s), kMaxWaiting) {
  if (!setup_.stereo_pipeline.empty()) {
    captures_.push_back(
        std::make_unique<sensors::GstCapture>("stereo camera", setup_.stereo_pipeline, std::vector<std::string>{"left", "right"}));
    left_ = {captures_[0].get(), 0, pipeline::StereoSide::kLeft, 0};
    right_ = {captures_[0].get(), 1, pipeline::StereoSide::kRight, 0};
  } else {
    captures_.push_back(std::make_unique<sensors::GstCapture>("left camera", setup_.left_pipeline));
    captures_.push_back(std::make_unique<sensors::GstCapture>("right camera", setup_.right_pipeline));
    left_ = {captures_[0].get(), 0, pipeline::StereoSide::kLeft, 0};
    right_ = {captures_[1].get(), 0, pipeline::StereoSide::kRight, 0};
  }
}

std::unique_ptr<CameraFeeder> CameraFeeder::Open(const CameraSetup& setup, pipeline::LiveFrameSource* sink,
                                                 OpenError* error) {
  std::unique_ptr<CameraFeeder> f(new CameraFeeder(setup, sink));
  if (std::string why = f->StartCaptures(); !why.empty()) {
    error->invalid_argument = std::any_of(f->captures_.begin(), f->captures_.end(),
                                          [](const auto& c) { return c->description_error(); });
    error->message = std::move(why);
    return nullptr;
  }
  // Each camera's first frame: it must come, and fit its camera_info.
  const std::pair<Side*, const ros::CameraInfo*> sides[] = {{&f->left_, &setup.left_info},
                                                                   {&f->right_, &setup.right_info}};
  for (const auto& [side, info] : sides) {
    const std::string name = side == &f->left_ ? "left camera" : "right camera";
    sensors::CameraFrame frame;
    std::string why;
    const sensors::PullResult r = side->capture->Pull(side->sink, ToNs(kFirstFrameTimeoutS), frame, why);
    if (r != sensors::PullResult::kFrame) {
      error->message = r == sensors::PullResult::kFailed ? why
                       : r == sensors::PullResult::kEnded
                           ? name + ": the stream ended before its first frame"
                           : name + ": no frame within " + std::to_string(static_cast<int>(kFirstFrameTimeoutS)) + " s";
      return nullptr;
    }
    if (frame.gray.cols != static_cast<int>(info->width) || frame.gray.rows != static_cast<int>(info->height)) {
      error->invalid_argument = true;
      error->message = name + ": frames are " + SizeText(frame.gray.cols, frame.gray.rows) +
                       ", its camera_info says " + SizeText(static_cast<int>(info->width), static_cast<int>(info->height));
      return nullptr;
    }
    side->last_frame_clock_ns = frame.clock_ns;
    f->pairer_.Add(side->side, frame.clock_ns, std::move(frame));
  }
  f->clock_to_session_ns_ = UnixNowNs() - sensors::ClockNowNs();
  f->thread_ = std::thread([p = f.get()] { p->Run(); });
  return f;
}

CameraFeeder::~CameraFeeder() {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void CameraFeeder::AddStats(pipeline::LiveInputStats& stats) const {
  std::lock_guard lock(mu_);
  stats.has_camera = true;
  stats.camera_running = !down_;
  stats.camera_pairs = pairs_;
  stats.camera_unpaired = unpaired_;
  stats.camera_dropped_late = dropped_late_;
  stats.camera_restarts = restarts_;
  stats.camera_error = error_;
}

std::string CameraFeeder::StartCaptures() {
  // One base time for both cameras: the frames of one moment get one stamp
  // (two file players started one after the other would otherwise differ by
  // the time between their starts).
  const int64_t base_time = sensors::ClockNowNs();
  for (auto& c : captures_) {
    if (std::string why = c->Start(5000, base_time); !why.empty()) {
      for (auto& other : captures_) other->Stop();
      return why;
    }
  }
  return "";
}

bool CameraFeeder::WaitFor(double seconds) {
  std::unique_lock lock(mu_);
  cv_.wait_for(lock, std::chrono::duration<double>(std::max(seconds, 0.0)), [&] { return stop_; });
  return !stop_;
}

void CameraFeeder::Run() {
  RestartBackoff backoff;
  int64_t next_tick = 0, next_restart = 0;
  for (;;) {
    {
      std::lock_guard lock(mu_);
      if (stop_) return;
    }
    if (!down_) {
      const uint64_t pairs_before = pairs_;
      if (PullSide(left_) && PullSide(right_)) PairAndPush();
      if (pairs_ > pairs_before) backoff.Delivered();  // back to the first wait once frames flow
      if (down_) {
        next_tick = sensors::ClockNowNs();
        next_restart = next_tick + ToNs(backoff.wait_s());
      }
      continue;
    }
    const int64_t now = sensors::ClockNowNs();
    if (now >= next_tick) {
      PushNoImages(now);
      next_tick = now + frame_period_ns_;
    }
    if (now >= next_restart) {
      std::string why = StartCaptures();
      std::lock_guard lock(mu_);
      ++restarts_;
      if (why.empty()) {
        down_ = false;
        pairer_.Clear();
        left_.last_frame_clock_ns = right_.last_frame_clock_ns = sensors::ClockNowNs();
        continue;
      }
      error_ = std::move(why);
      backoff.Failed();
      next_restart = now + ToNs(backoff.wait_s());
    }
    if (!WaitFor(static_cast<double>(std::min(next_tick, next_restart) - sensors::ClockNowNs()) * 1e-9)) return;
  }
}

bool CameraFeeder::PullSide(Side& side) {
  const char* name = &side == &left_ ? "left camera" : "right camera";
  sensors::CameraFrame frame;
  std::string why;
  switch (side.capture->Pull(side.sink, kPullTimeoutNs, frame, why)) {
    case sensors::PullResult::kFrame:
      side.last_frame_clock_ns = frame.clock_ns;
      if (pairer_.Add(side.side, frame.clock_ns, std::move(frame))) {  // its oldest frame pushed out
        std::lock_guard lock(mu_);
        ++unpaired_;
      }
      return true;
    case sensors::PullResult::kTimeout:
      if (sensors::ClockNowNs() - side.last_frame_clock_ns > ToNs(setup_.stall_timeout_s)) {
        GoDown(std::string(name) + ": no frame for " + std::to_string(setup_.stall_timeout_s) + " s (stalled)");
        return false;
      }
      return true;
    case sensors::PullResult::kEnded:
      GoDown(std::string(name) + ": end of stream");
      return false;
    case sensors::PullResult::kFailed:
      GoDown(why);
      return false;
  }
  return false;
}

void CameraFeeder::PairAndPush() {
  pairer_.Pair([this](const sensors::CameraFrame& left, const sensors::CameraFrame& right) { Push(left, right); },
               [this](pipeline::StereoSide, const sensors::CameraFrame&) {
                 std::lock_guard lock(mu_);
                 ++unpaired_;  // the older frame has no partner
               });
}

void CameraFeeder::Push(const sensors::CameraFrame& left, const sensors::CameraFrame& right) {
  const int64_t t_ns = left.clock_ns + clock_to_session_ns_;
  if (t_ns <= last_pushed_ns_) {  // older than a tick sent while the camera was down
    std::lock_guard lock(mu_);
    ++dropped_late_;
    return;
  }
  pipeline::LiveItem item;
  item.kind = pipeline::LiveItem::Kind::kFrame;
  item.t_ns = t_ns;
  try {
    item.left_image = rectified_.left.Rectify(left.gray);
    item.right_image = rectified_.right.Rectify(right.gray);
  } catch (const std::exception& e) {
    GoDown(std::string("rectification: ") + e.what());  // a camera whose frame size changed
    return;
  }
  const bool taken = sink_->TryPush(std::move(item));
  std::lock_guard lock(mu_);
  if (!taken) {
    ++dropped_late_;  // the session is still busy with earlier frames
    return;
  }
  if (last_pushed_ns_ != INT64_MIN) frame_period_ns_ = std::clamp(t_ns - last_pushed_ns_, kNsPerS / 100, kNsPerS);
  last_pushed_ns_ = t_ns;
  ++pairs_;
}

void CameraFeeder::PushNoImages(int64_t clock_ns) {
  const int64_t t_ns = clock_ns + clock_to_session_ns_;
  if (t_ns <= last_pushed_ns_) return;
  pipeline::LiveItem item;
  item.kind = pipeline::LiveItem::Kind::kFrame;
  item.t_ns = t_ns;
  item.no_images = true;
  if (sink_->TryPush(std::move(item))) last_pushed_ns_ = t_ns;
}

void CameraFeeder::GoDown(const std::string& why) {
  for (auto& c : captures_) c->Stop();
  std::lock_guard lock(mu_);
  down_ = true;
  error_ = why;
}

}  // namespace locaid::server
