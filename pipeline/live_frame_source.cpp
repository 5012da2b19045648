#include "pipeline/live_frame_source.hpp"

#include "kitti/oxts.hpp"
#include "pipeline/oxts_adapter.hpp"

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <stdexcept>
#include <utility>

namespace locaid::pipeline {

std::optional<PngSize> ReadPngSize(const std::string& bytes) {
  static constexpr unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (bytes.size() < 24) return std::nullopt;
  const auto* b = reinterpret_cast<const unsigned char*>(bytes.data());
  if (!std::equal(kSignature, kSignature + 8, b)) return std::nullopt;
  auto be32 = [b](size_t at) {
    return (uint32_t{b[at]} << 24) | (uint32_t{b[at + 1]} << 16) | (uint32_t{b[at + 2]} << 8) | uint32_t{b[at + 3]};
  };
  if (be32(8) != 13 || bytes.compare(12, 4, "IHDR") != 0) return std::nullopt;
  return PngSize{be32(16), be32(20)};
}

std::string PngSizeMismatch(const std::string& bytes, const StereoCamera& camera, const char* which) {
  const auto size = ReadPngSize(bytes);
  if (!size) return "";
  if (size->width == static_cast<uint32_t>(camera.width) && size->height == static_cast<uint32_t>(camera.height)) {
    return "";
  }
  return std::string(which) + " image: PNG declares " + std::to_string(size->width) + "x" +
         std::to_string(size->height) + " px, session camera is " + std::to_string(camera.width) + "x" +
         std::to_string(camera.height) + " px";
}

// An image the server's cameras already rectified: checked, not copied.
static cv::Mat CheckedLiveImage(const cv::Mat& image, const StereoCamera& camera, const char* which) {
  if (image.type() != CV_8UC1 || image.cols != camera.width || image.rows != camera.height) {
    throw std::invalid_argument(std::string(which) + " image: " + std::to_string(image.cols) + "x" +
                                std::to_string(image.rows) + " type " + std::to_string(image.type()) + ", expected " +
                                std::to_string(camera.width) + "x" + std::to_string(camera.height) + " CV_8UC1");
  }
  return image;
}

cv::Mat DecodeLiveImage(const std::string& bytes, bool png, const StereoCamera& camera,
                        const char* which) {
  const std::string prefix = std::string(which) + " image: ";
  if (bytes.empty()) throw std::invalid_argument(prefix + "empty");
  cv::Mat image;
  if (png) {
    if (!ReadPngSize(bytes)) {
      throw std::invalid_argument(prefix + "not a PNG (no signature + IHDR header in the first 24 of " +
                                  std::to_string(bytes.size()) + " bytes)");
    }
    const std::string mismatch = PngSizeMismatch(bytes, camera, which);
    if (!mismatch.empty()) throw std::invalid_argument(mismatch);
    const cv::Mat raw(1, static_cast<int>(bytes.size()), CV_8UC1,
                      const_cast<char*>(bytes.data()));
    image = cv::imdecode(raw, cv::IMREAD_GRAYSCALE);
    if (image.empty()) throw std::invalid_argument(prefix + "cannot decode " + std::to_string(bytes.size()) + " bytes");
  } else {
    const size_t expected = static_cast<size_t>(camera.width) * static_cast<size_t>(camera.height);
    if (bytes.size() != expected) {
      throw std::invalid_argument(prefix + "GRAY8 has " + std::to_string(bytes.size()) +
                                  " bytes, expected " + std::to_string(expected) + " (" +
                                  std::to_string(camera.width) + "x" + std::to_string(camera.height) + ")");
    }
    image = cv::Mat(camera.height, camera.width, CV_8UC1, const_cast<char*>(bytes.data())).clone();
  }
  if (image.cols != camera.width || image.rows != camera.height) {
    throw std::invalid_argument(prefix + "size " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                                ", expected " + std::to_string(camera.width) + "x" + std::to_string(camera.height));
  }
  return image;
}

LiveFrameSource::LiveFrameSource(LiveCameraSetup setup, size_t capacity)
    : setup_(std::move(setup)), capacity_(std::max<size_t>(capacity, 1)) {}

bool LiveFrameSource::Push(LiveItem item, std::function<void()> resume) {
  std::lock_guard lock(mu_);
  if (closed_ || cancelled_) return true;  // dropped: the session has ended
  if (queue_.size() < capacity_) {
    queue_.push_back(std::move(item));
    cv_.notify_one();
    return true;
  }
  pending_ = std::move(item);
  resume_ = std::move(resume);
  return false;
}

bool LiveFrameSource::TryPush(LiveItem item) {
  std::lock_guard lock(mu_);
  if (closed_ || cancelled_) return true;  // dropped: the session has ended
  if (queue_.size() >= capacity_ || pending_) return false;
  queue_.push_back(std::move(item));
  cv_.notify_one();
  return true;
}

void LiveFrameSource::PushAsyncFix(LiveItem fix) {
  std::lock_guard lock(mu_);
  if (closed_ || cancelled_) return;
  if (async_fixes_.size() >= kMaxAsyncFixes) {
    async_fixes_.pop_front();
    std::lock_guard s(stats_mu_);
    ++stats_.gps_fixes_late;
  }
  async_fixes_.push_back(std::move(fix));
  cv_.notify_one();
}

LiveInputStats LiveFrameSource::input_stats() const {
  LiveInputStats stats;
  {
    std::lock_guard lock(stats_mu_);
    stats = stats_;
  }
  for (const auto& feeder : feeders_) feeder->AddStats(stats);
  return stats;
}

void LiveFrameSource::TakeImu(const LiveItem& item) {
  std::lock_guard s(stats_mu_);
  ++stats_.imu_samples;
  if (last_imu_ns_ && item.t_ns <= *last_imu_ns_) {
    ++stats_.sensor_rejected;
    stats_.last_error = "pushed imu sample: t_ns " + std::to_string(item.t_ns) + " not after the previous sample (" +
                        std::to_string(*last_imu_ns_) + ")";
    return;
  }
  last_imu_ns_ = item.t_ns;
  imu_.push_back(item.imu);
  sensor_time_ns_ = std::max(sensor_time_ns_, item.t_ns);
}

void LiveFrameSource::TakeSpeed(const LiveItem& item) {
  std::lock_guard s(stats_mu_);
  ++stats_.speed_samples;
  if (last_speed_ns_ && item.t_ns <= *last_speed_ns_) {
    ++stats_.sensor_rejected;
    stats_.last_error = "pushed speed sample: t_ns " + std::to_string(item.t_ns) +
                        " not after the previous sample (" + std::to_string(*last_speed_ns_) + ")";
    return;
  }
  last_speed_ns_ = item.t_ns;
  speed_.push_back(item.speed);
  sensor_time_ns_ = std::max(sensor_time_ns_, item.t_ns);
}

void LiveFrameSource::TakeGps(LiveItem item) {
  std::lock_guard s(stats_mu_);
  ++stats_.gps_fixes_in;
  if (item.gps_no_fix) {
    ++stats_.gps_no_fix;
    receiver_has_fix_ = false;
    return;
  }
  const auto max_delay_ns = static_cast<int64_t>(setup_.max_gps_delay_s * 1e9);
  // Fused out of order a fix would pull the state back in time: too old
  // against the newest frame, or not after the previous fix, it is dropped.
  // Saturated: a frame at t_ns near INT64_MIN overflowed the subtraction
  // (undefined behaviour, found by fuzz_push_requests).
  const int64_t oldest_ns = last_frame_ns_ < INT64_MIN + max_delay_ns ? INT64_MIN : last_frame_ns_ - max_delay_ns;
  const bool stale = last_frame_ns_ != INT64_MIN && item.t_ns < oldest_ns;
  const bool repeated = last_gps_ns_ && item.t_ns <= *last_gps_ns_;
  if (stale || repeated) {
    ++stats_.gps_fixes_late;
    stats_.last_error = "gps fix at t_ns " + std::to_string(item.t_ns) +
                        (stale ? " older than the newest frame (" + std::to_string(last_frame_ns_) +
                                     ") by more than max_gps_delay_s"
                               : " not after the previous fix (" + std::to_string(*last_gps_ns_) + ")");
    return;
  }
  last_gps_ns_ = item.t_ns;
  receiver_has_fix_ = true;
  if (held_gps_.size() >= kMaxAsyncFixes) {
    held_gps_.pop_front();
    ++stats_.gps_fixes_late;
  }
  held_gps_.push_back({item.gps, item.arrival_steady_ns});
}

bool LiveFrameSource::HasReleasable() const {
  return !imu_.empty() || !speed_.empty() || receiver_has_fix_.has_value() ||
         (!held_gps_.empty() && held_gps_.front().fix.t_ns <= sensor_time_ns_);
}

void LiveFrameSource::Release(int64_t t_ns, SourceItem& out) {
  auto imu_end = std::find_if(imu_.begin(), imu_.end(), [&](const fusion::ImuSample& s) { return s.t_ns > t_ns; });
  out.samples.imu.assign(imu_.begin(), imu_end);
  imu_.erase(imu_.begin(), imu_end);
  auto speed_end =
      std::find_if(speed_.begin(), speed_.end(), [&](const fusion::SpeedSample& s) { return s.t_ns > t_ns; });
  out.samples.speed.assign(speed_.begin(), speed_end);
  speed_.erase(speed_.begin(), speed_end);
  while (!held_gps_.empty() && held_gps_.front().fix.t_ns <= t_ns) {
    out.samples.gps.push_back(held_gps_.front());
    held_gps_.pop_front();
  }
  out.samples.receiver_has_fix = std::exchange(receiver_has_fix_, std::nullopt);
}

void LiveFrameSource::CloseInput() {
  std::lock_guard lock(mu_);
  closed_ = true;
  cv_.notify_all();
}

void LiveFrameSource::Cancel() {
  std::function<void()> resume;
  {
    std::lock_guard lock(mu_);
    cancelled_ = true;
    pending_.reset();
    resume.swap(resume_);
    cv_.notify_all();
  }
  if (resume) resume();
}

void LiveFrameSource::Wake() {
  std::lock_guard lock(mu_);
  woken_ = true;
  cv_.notify_all();
}

SourceItem LiveFrameSource::Next() {
  for (;;) {
    SourceItem out;
    std::optional<LiveItem> item = Dequeue(out);
    if (!item) return out;
    switch (item->kind) {
      case LiveItem::Kind::kImu:
        TakeImu(*item);
        continue;
      case LiveItem::Kind::kGps:
        TakeGps(std::move(*item));
        continue;
      case LiveItem::Kind::kSpeed:
        TakeSpeed(*item);
        continue;
      case LiveItem::Kind::kOxts:
        TakeOxts(*item);
        continue;
      case LiveItem::Kind::kFrame:
        return Frame(std::move(*item));
    }
  }
}

std::optional<LiveItem> LiveFrameSource::Dequeue(SourceItem& out) {
  LiveItem item;
  std::function<void()> resume;
  {
    std::unique_lock lock(mu_);
    if (queue_.empty() && async_fixes_.empty() && !closed_ && !cancelled_ && !woken_ && !HasReleasable()) {
      cv_.wait_for(lock, std::chrono::milliseconds(50));
    }
    while (!async_fixes_.empty()) {
      TakeGps(std::move(async_fixes_.front()));
      async_fixes_.pop_front();
    }
    if (std::exchange(woken_, false)) {
      out.kind = SourceItem::Kind::kIdle;
      return std::nullopt;
    }
    if (cancelled_ || (queue_.empty() && closed_)) {
      out.kind = SourceItem::Kind::kEnd;
      return std::nullopt;
    }
    if (queue_.empty() && HasReleasable()) {
      // Typed data between frames is fused now, not at the next frame.
      out.kind = SourceItem::Kind::kSamples;
      out.t_ns = sensor_time_ns_;
      Release(sensor_time_ns_, out);
      return std::nullopt;
    }
    if (queue_.empty()) {
      out.kind = SourceItem::Kind::kIdle;
      out.oxts_bad_lines = std::exchange(bad_lines_, 0);
      if (out.oxts_bad_lines > 0) out.error = last_error_;
      return std::nullopt;
    }
    item = std::move(queue_.front());
    queue_.pop_front();
    if (pending_) {
      queue_.push_back(std::move(*pending_));
      pending_.reset();
      resume.swap(resume_);
    }
  }
  if (resume) resume();
  return item;
}

void LiveFrameSource::TakeOxts(const LiveItem& item) {
  const int64_t n = oxts_count_++;
  try {
    kitti::OxtsSample s;
    s.t_ns = item.t_ns;
    s.index = static_cast<int>(n);
    s.record = kitti::ParseOxtsLine(item.oxts_line, "pushed oxts record " + std::to_string(n));
    // Against the last accepted record, not the buffer: the buffer is
    // handed to the pipeline at every frame and may be empty.
    if (last_oxts_t_ns_ && s.t_ns <= *last_oxts_t_ns_) {
      throw std::invalid_argument("pushed oxts record " + std::to_string(n) + ": t_ns " + std::to_string(s.t_ns) +
                                  " not after the previous record (" + std::to_string(*last_oxts_t_ns_) + ")");
    }
    last_oxts_t_ns_ = s.t_ns;
    AppendOxts(s, truth_);
  } catch (const std::exception& e) {
    ++bad_lines_;
    last_error_ = e.what();
  }
}

SourceItem LiveFrameSource::Frame(LiveItem item) {
  SourceItem out;
  out.index = frames_++;
  if (setup_.expects_imu && frames_ == kFramesBeforeNoImuNotice && !last_imu_ns_) {
    std::lock_guard s(stats_mu_);
    stats_.last_error = std::to_string(kFramesBeforeNoImuNotice) +
                        " frames and no IMU sample: the filter is IMU-driven and drifts fast without one; a car "
                        "without IMU starts its session with live.no_imu";
  }
  out.t_ns = item.t_ns;
  out.oxts_bad_lines = std::exchange(bad_lines_, 0);
  if (out.oxts_bad_lines > 0) out.error = last_error_;
  // Hand over the truth samples up to the frame time; later ones wait.
  truth_.MoveUpTo(item.t_ns, out.samples);
  if (item.t_ns > last_frame_ns_) sensor_time_ns_ = std::max(sensor_time_ns_, item.t_ns);
  Release(item.t_ns, out);
  if (item.t_ns <= last_frame_ns_) {
    out.kind = SourceItem::Kind::kCorrupt;
    out.error = "pushed frame " + std::to_string(out.index) + ": t_ns " + std::to_string(item.t_ns) +
                " not after the previous frame (" + std::to_string(last_frame_ns_) + ")";
    return out;
  }
  try {
    if (item.no_images) {
      out.no_images = true;  // a pose without VO: out.left / out.right stay empty
    } else if (!item.left_image.empty() || !item.right_image.empty()) {
      out.left = CheckedLiveImage(item.left_image, setup_.camera, "left");
      out.right = CheckedLiveImage(item.right_image, setup_.camera, "right");
    } else {
      pair_runner().Run([&] { out.left = DecodeLiveImage(item.left, item.png, setup_.camera, "left"); },
                        [&] { out.right = DecodeLiveImage(item.right, item.png, setup_.camera, "right"); });
    }
    out.kind = SourceItem::Kind::kFrame;
    last_frame_ns_ = item.t_ns;
  } catch (const std::exception& e) {
    out.kind = SourceItem::Kind::kCorrupt;
    out.error = "pushed frame " + std::to_string(out.index) + ": " + e.what();
  }
  return out;
}

}  // namespace locaid::pipeline
