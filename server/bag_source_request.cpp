#include "server/bag_source_request.hpp"

#include "pipeline/bag_frame_source.hpp"
#include "server/status.hpp"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace locaid::server {

namespace v1 = locaid::v1;
using grpc::Status;
using grpc::StatusCode;

namespace {

// A duration in milliseconds: 0 = `default_s`, else finite and in (0, max_ms].
Status Millis(const char* field, double ms, double max_ms, double default_s, double* out_s) {
  if (!std::isfinite(ms) || ms < 0 || ms > max_ms) {
    std::ostringstream msg;
    msg << "bag." << field << ": must be in [0, " << max_ms << "] ms (0 = " << default_s * 1e3 << " ms), got " << ms;
    return Invalid(msg.str());
  }
  *out_s = ms == 0 ? default_s : ms * 1e-3;
  return Status::OK;
}

// bag.topics: each empty (by type), a ROS name from the root, or "none" for
// the optional sensors.
Status ParseTopics(const v1::BagTopics& t, bag::BagTopics* out) {
  const struct {
    const char* key;
    const std::string& value;
    std::string* to;
    bool optional;
  } fields[] = {{"left_image", t.left_image(), &out->left_image, false},
                {"left_info", t.left_info(), &out->left_info, false},
                {"right_image", t.right_image(), &out->right_image, false},
                {"right_info", t.right_info(), &out->right_info, false},
                {"imu", t.imu(), &out->imu, true},
                {"gps", t.gps(), &out->gps, true},
                {"speed", t.speed(), &out->speed, true}};
  for (const auto& f : fields) {
    const std::string& v = f.value;
    const std::string field = std::string("bag.topics.") + f.key;
    if (v == "none" && !f.optional) return Invalid(field + ": the cameras cannot be \"none\" (only imu, gps, speed)");
    const bool name_ok = v.empty() || v == "none" ||
                         (v.front() == '/' && v.size() <= 1024 &&
                          std::none_of(v.begin(), v.end(), [](unsigned char c) { return c <= ' ' || c == 0x7f; }));
    if (!name_ok) {
      return Invalid(field + " " + Quoted(v) + ": must be empty (picked by type), " +
                     (f.optional ? "\"none\" (off) " : "") + "or a topic name starting with '/' (no spaces)");
    }
    *f.to = v;
  }
  return Status::OK;
}

// A bag whose counters are the session's input stats (SessionStats
// imu_samples, gps_fixes_in, gps_no_fix, speed_samples, sensor_items_rejected
// for messages out of stamp order): copied after every item, since RPC
// threads read them while the session thread reads the bag.
class CountedBagSource : public pipeline::FrameSource {
 public:
  explicit CountedBagSource(std::unique_ptr<pipeline::BagFrameSource> bag) : bag_(std::move(bag)) {}
  pipeline::SourceItem Next() override {
    pipeline::SourceItem item = bag_->Next();
    const pipeline::BagSourceStats& b = bag_->stats();
    std::lock_guard lock(mu_);
    stats_.imu_samples = b.imu;
    stats_.gps_fixes_in = b.fixes + b.no_fix;
    stats_.gps_no_fix = b.no_fix;
    stats_.speed_samples = b.speed;
    stats_.sensor_rejected = b.late;
    return item;
  }
  void Cancel() override { bag_->Cancel(); }
  void Wake() override { bag_->Wake(); }
  int64_t total_frames() const override { return bag_->total_frames(); }
  double duration_s() const override { return bag_->duration_s(); }
  const StereoCamera& camera() const override { return bag_->camera(); }
  Eigen::Isometry3d T_cam0_imu() const override { return bag_->T_cam0_imu(); }
  pipeline::LiveInputStats input_stats() const override {
    std::lock_guard lock(mu_);
    return stats_;
  }

 private:
  std::unique_ptr<pipeline::BagFrameSource> bag_;
  mutable std::mutex mu_;
  pipeline::LiveInputStats stats_;
};

// The bag reader's errors speak of locaid-replay's --bag-topics FILE; a
// session names its topics in bag.topics.
std::string ForRequest(std::string what) {
  const std::string flag = "--bag-topics FILE";
  for (size_t at = what.find(flag); at != std::string::npos; at = what.find(flag, at))
    what.replace(at, flag.size(), "bag.topics");
  return what;
}

}  // namespace

Status OpenBagSource(const v1::BagSource& b, pipeline::RunOptions* run, std::unique_ptr<pipeline::FrameSource>* out,
                     std::string* name) {
  if (Status s = RequireServerPath("bag.path", b.path(), "a .mcap file or a rosbag2 directory on the server"); !s.ok())
    return s;
  pipeline::BagSourceOptions options;
  if (Status s = Millis("stereo_tolerance_ms", b.stereo_tolerance_ms(), 1000, options.stereo_tolerance_s,
                        &options.stereo_tolerance_s);
      !s.ok())
    return s;
  if (Status s = Millis("reorder_window_ms", b.reorder_window_ms(), 60000, options.reorder_window_s,
                        &options.reorder_window_s);
      !s.ok())
    return s;
  if (Status s = ParseTopics(b.topics(), &options.topics); !s.ok()) return s;
  // Outages placed on the drive's middle need its length: scan it all.
  const auto& outages = run->scenario.outages;
  if (std::any_of(outages.begin(), outages.end(), [](const sim::OutageWindow& o) { return o.centered; }))
    options.preview_s = 0;
  try {
    auto bag = std::make_unique<pipeline::BagFrameSource>(b.path(), options);
    run->localizer.ekf.gps.lever_arm_body_m = bag->gps_lever_arm_body_m();
    run->localizer.ekf.imu.enabled = bag->has_imu();
    *out = std::make_unique<CountedBagSource>(std::move(bag));
  } catch (const std::exception& e) {  // bag::McapError, std::runtime_error: the bag's content
    return {StatusCode::FAILED_PRECONDITION, "cannot open bag: " + ForRequest(e.what())};
  }
  *name = "bag:" + b.path();
  return Status::OK;
}

}  // namespace locaid::server
