// A camera through GStreamer: one pipeline description (anything
// gst-launch-1.0 takes: v4l2src, aravissrc, rtspsrc, a vendor's plugin, a
// recorded file) whose frames end in an appsink, pulled as 8-bit gray images
// with the time of each buffer on the pipeline's clock. Free of gRPC, starts
// no thread of its own (GStreamer runs its streaming threads inside the
// pipeline); the caller polls Pull(), from one thread.
//
// Two ways to name the frames:
//  - a camera's description without an appsink: locaid appends
//    "! videoconvert ! appsink name=locaid" with GRAY8 caps;
//  - a description with the appsinks named (a stereo pipeline's `left` and
//    `right`): each named appsink gets GRAY8 caps, so the description
//    converts before it (videoconvert).
//
// Time: a buffer's PTS mapped to running time by its segment, plus the
// pipeline's base time, is the clock time it was captured at (for a live
// source) or is due to be shown (a file played with sync). All pipelines of
// one process use GStreamer's system clock (monotonic), so the stamps of two
// camera pipelines compare directly; the caller maps them to its own clock
// once (ClockNowNs()).
#pragma once

#include <opencv2/core.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace locaid::sensors {

struct CameraFrame {
  cv::Mat gray;           // CV_8UC1, the caps' width x height (a copy: the buffer is released)
  int64_t clock_ns = 0;   // the buffer's time on GStreamer's system clock (monotonic)
  uint64_t sequence = 0;  // frames pulled from this sink since the capture was created
};

enum class PullResult {
  kFrame,    // `frame` holds the next frame
  kTimeout,  // none within the timeout (the pipeline may be stalled: the caller decides)
  kEnded,    // end of stream (a file played out, a camera that stopped)
  kFailed,   // the pipeline posted an error (unplugged, ...): `why` is GStreamer's message
};

// GStreamer's system clock now, ns: the clock of CameraFrame::clock_ns.
int64_t ClockNowNs();

class GstCapture {
 public:
  // `camera`: the name errors start with ("left camera"). `sinks`: the
  // appsink names the description has; empty: one appsink is appended.
  GstCapture(std::string camera, std::string description, std::vector<std::string> sinks = {});
  ~GstCapture();
  GstCapture(const GstCapture&) = delete;
  GstCapture& operator=(const GstCapture&) = delete;

  // Builds the pipeline and sets it playing; waits up to `timeout_ms` for
  // it to get there. "" on success, else "<camera>: <what failed>:
  // <GStreamer's message>" (a bad description, a missing element, an
  // appsink that is not there, a device that cannot be opened). A capture
  // that failed to start may be started again.
  // `base_time_ns` >= 0: the pipeline's running time counts from that clock
  // time instead of from when it starts playing. Captures started one after
  // the other with one base time stamp the frames of one moment alike,
  // whether live (a camera stamps its capture time) or played from files.
  std::string Start(int timeout_ms = 5000, int64_t base_time_ns = -1);
  // Whether the last Start() failed on the description itself (bad syntax,
  // a missing element or appsink), not on playing it: the user's input is
  // wrong, rather than the camera not there.
  bool description_error() const { return description_error_; }
  // Stops and frees the pipeline (Start() builds a new one: a restart).
  void Stop();
  bool running() const;

  // The next frame of sink `index` (the order of `sinks`; 0 for the
  // appended one), waiting up to timeout_ns.
  PullResult Pull(size_t index, int64_t timeout_ns, CameraFrame& frame, std::string& why);

  const std::string& camera() const { return camera_; }
  size_t sink_count() const { return sinks_.empty() ? 1 : sinks_.size(); }

 private:
  struct Pipeline;
  std::string Fail(const std::string& what, const std::string& message, bool in_description = false);
  std::string BusError();  // the first error on the bus, "" if none

  std::string camera_, description_;
  std::vector<std::string> sinks_;
  std::vector<uint64_t> sequence_;
  std::unique_ptr<Pipeline> p_;
  bool description_error_ = false;
};

}  // namespace locaid::sensors
