// A live session's stereo cameras read by the server itself through
// GStreamer (LiveSource.cameras), on one thread of its own owned by the live
// source it feeds: frames are paired by stamp, rectified from the cameras'
// camera_info as a bag's images are (ros::MakeRectifiedStereo), stamped on
// the session clock and handed on without blocking. A camera that ends,
// fails or stalls makes the session's poses say so (vo_health NO_IMAGES
// ticks, so the filter goes on with IMU, GPS and speed) and is restarted
// with backoff.
//
// Clock: a frame's time is its buffer's PTS on GStreamer's monotonic system
// clock; Open() maps that clock to the session clock (Unix time, ns, the
// clock of gpsd's fixes and of pushed samples) once, so the frames keep the
// spacing their PTS give them.
#pragma once

#include "pipeline/live_frame_source.hpp"
#include "pipeline/stereo_pairer.hpp"
#include "ros/camera_model.hpp"
#include "sensors/gst_camera.hpp"
#include "server/live_source_request.hpp"
#include "server/restart_backoff.hpp"

#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace locaid::server {

class CameraFeeder final : public pipeline::InputFeeder {
 public:
  static constexpr double kFirstFrameTimeoutS = 10.0;
  static constexpr size_t kMaxWaiting = 8;  // frames a side keeps while waiting for its partner

  struct OpenError {
    bool invalid_argument = false;  // else FAILED_PRECONDITION
    std::string message;            // names the camera
  };
  // Starts the pipelines and waits for each camera's first frame, whose size
  // must be its camera_info's; nullptr and `error` when a camera cannot
  // start or does not fit. `sink` must outlive the feeder.
  static std::unique_ptr<CameraFeeder> Open(const CameraSetup& setup, pipeline::LiveFrameSource* sink,
                                            OpenError* error);
  ~CameraFeeder() override;  // stops the thread and the pipelines
  CameraFeeder(const CameraFeeder&) = delete;
  CameraFeeder& operator=(const CameraFeeder&) = delete;

  void AddStats(pipeline::LiveInputStats& stats) const override;

 private:
  struct Side {
    sensors::GstCapture* capture = nullptr;
    size_t sink = 0;
    pipeline::StereoSide side = pipeline::StereoSide::kLeft;
    int64_t last_frame_clock_ns = 0;  // when its newest frame came (GStreamer clock)
  };
  CameraFeeder(const CameraSetup& setup, pipeline::LiveFrameSource* sink);
  std::string StartCaptures();
  void Run();
  bool PullSide(Side& side);  // false: the camera is down (error_ says why)
  void PairAndPush();
  void Push(const sensors::CameraFrame& left, const sensors::CameraFrame& right);
  void PushNoImages(int64_t clock_ns);
  void GoDown(const std::string& why);
  bool WaitFor(double seconds);  // false when stopping

  CameraSetup setup_;
  pipeline::LiveFrameSource* const sink_;
  ros::RectifiedStereo rectified_;
  std::vector<std::unique_ptr<sensors::GstCapture>> captures_;
  Side left_, right_;
  pipeline::StereoPairer<sensors::CameraFrame> pairer_;  // frames by their GStreamer clock stamps
  int64_t clock_to_session_ns_ = 0;  // session time = GStreamer clock + this
  int64_t last_pushed_ns_ = INT64_MIN;
  int64_t frame_period_ns_ = 100'000'000;  // of the no-image ticks: the cameras' own, once seen
  bool down_ = false;
  mutable std::mutex mu_;  // guards the figures below and stop_
  std::condition_variable cv_;
  bool stop_ = false;
  uint64_t pairs_ = 0, unpaired_ = 0, dropped_late_ = 0, restarts_ = 0;
  std::string error_;
  std::thread thread_;
};

}  // namespace locaid::server
