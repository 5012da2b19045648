#include "sensors/gst_camera.hpp"

#include <gst/app/gstappsink.h>
#include <gst/gst.h>
#include <gst/video/video.h>

#include <algorithm>
#include <mutex>
#include <utility>

namespace locaid::sensors {
namespace {

constexpr char kAppendedSink[] = "locaid";
// Frames an appsink holds for a caller that is behind: beyond, the oldest
// goes (GStreamer drops it), so a slow caller never queues without bound.
constexpr guint kSinkBuffers = 4;

// gst_init_check once per process; "" or why GStreamer cannot start.
const std::string& InitError() {
  static std::once_flag once;
  static std::string error;
  std::call_once(once, [] {
    GError* e = nullptr;
    if (!gst_init_check(nullptr, nullptr, &e)) error = e ? e->message : "gst_init_check failed";
    g_clear_error(&e);
  });
  return error;
}

std::string TakeMessage(GError*& e) {
  std::string text = e ? e->message : "unknown error";
  g_clear_error(&e);
  return text;
}

GstClock* SystemClock() {
  static GstClock* clock = gst_system_clock_obtain();  // one reference, kept for the process
  return clock;
}

struct SampleRef {
  GstSample* s;
  ~SampleRef() { gst_sample_unref(s); }
};

}  // namespace

struct GstCapture::Pipeline {
  GstElement* pipeline = nullptr;
  GstBus* bus = nullptr;
  std::vector<GstAppSink*> sinks;  // each a reference of ours

  ~Pipeline() {
    if (pipeline) gst_element_set_state(pipeline, GST_STATE_NULL);
    for (GstAppSink* s : sinks) gst_object_unref(s);
    if (bus) gst_object_unref(bus);
    if (pipeline) gst_object_unref(pipeline);
  }
};

int64_t ClockNowNs() {
  if (!InitError().empty()) return 0;
  return static_cast<int64_t>(gst_clock_get_time(SystemClock()));
}

GstCapture::GstCapture(std::string camera, std::string description, std::vector<std::string> sinks)
    : camera_(std::move(camera)), description_(std::move(description)), sinks_(std::move(sinks)),
      sequence_(sink_count(), 0) {}

GstCapture::~GstCapture() = default;

bool GstCapture::running() const { return p_ != nullptr; }

void GstCapture::Stop() { p_.reset(); }

std::string GstCapture::Fail(const std::string& what, const std::string& message, bool in_description) {
  Stop();
  description_error_ = in_description;
  return camera_ + ": " + what + ": " + message;
}

std::string GstCapture::BusError() {
  if (!p_ || !p_->bus) return "";
  GstMessage* m = gst_bus_pop_filtered(p_->bus, GST_MESSAGE_ERROR);
  if (!m) return "";
  GError* e = nullptr;
  gst_message_parse_error(m, &e, nullptr);
  std::string text = std::string(GST_OBJECT_NAME(GST_MESSAGE_SRC(m))) + ": " + TakeMessage(e);
  gst_message_unref(m);
  return text;
}

std::string GstCapture::Start(int timeout_ms, int64_t base_time_ns) {
  Stop();
  description_error_ = false;
  if (!InitError().empty()) return camera_ + ": GStreamer cannot start: " + InitError();
  if (description_.find_first_not_of(" \t\r\n") == std::string::npos) {
    description_error_ = true;
    return camera_ + ": empty pipeline description";
  }
  const std::string description =
      sinks_.empty() ? description_ + " ! videoconvert ! appsink name=" + kAppendedSink : description_;
  GError* e = nullptr;
  GstElement* element = gst_parse_launch_full(description.c_str(), nullptr, GST_PARSE_FLAG_FATAL_ERRORS, &e);
  if (!element || e) {
    if (element) gst_object_unref(element);
    return Fail("bad pipeline description", TakeMessage(e), true);
  }
  p_ = std::make_unique<Pipeline>();
  p_->pipeline = element;
  if (!GST_IS_PIPELINE(element)) {
    return Fail("bad pipeline description", "it is a single element, not a pipeline", true);
  }
  gst_pipeline_use_clock(GST_PIPELINE(element), SystemClock());  // stamps of every capture compare
  p_->bus = gst_element_get_bus(element);

  const std::vector<std::string> names = sinks_.empty() ? std::vector<std::string>{kAppendedSink} : sinks_;
  GstCaps* gray = gst_caps_from_string("video/x-raw,format=GRAY8");
  for (const auto& name : names) {
    GstElement* sink = gst_bin_get_by_name(GST_BIN(element), name.c_str());
    if (!sink || !GST_IS_APP_SINK(sink)) {
      if (sink) gst_object_unref(sink);
      gst_caps_unref(gray);
      return Fail("no appsink named '" + name + "'", "the description must end that camera in appsink name=" + name,
                  true);
    }
    gst_app_sink_set_caps(GST_APP_SINK(sink), gray);
    gst_app_sink_set_max_buffers(GST_APP_SINK(sink), kSinkBuffers);
    gst_app_sink_set_drop(GST_APP_SINK(sink), TRUE);
    p_->sinks.push_back(GST_APP_SINK(sink));
  }
  gst_caps_unref(gray);
  if (base_time_ns >= 0) {
    gst_element_set_start_time(element, GST_CLOCK_TIME_NONE);  // keep the base time given
    gst_element_set_base_time(element, static_cast<GstClockTime>(base_time_ns));
  }

  if (gst_element_set_state(element, GST_STATE_PLAYING) == GST_STATE_CHANGE_FAILURE) {
    const std::string why = BusError();
    return Fail("cannot start", why.empty() ? "the pipeline refused to play" : why);
  }
  const GstStateChangeReturn r =
      gst_element_get_state(element, nullptr, nullptr, static_cast<GstClockTime>(timeout_ms) * GST_MSECOND);
  if (r == GST_STATE_CHANGE_FAILURE) {
    const std::string why = BusError();
    return Fail("cannot start", why.empty() ? "the pipeline refused to play" : why);
  }
  if (r == GST_STATE_CHANGE_ASYNC) {
    return Fail("cannot start", "no frame within " + std::to_string(timeout_ms) + " ms");
  }
  if (const std::string why = BusError(); !why.empty()) return Fail("cannot start", why);
  return "";
}

PullResult GstCapture::Pull(size_t index, int64_t timeout_ns, CameraFrame& frame, std::string& why) {
  if (!p_) {
    why = camera_ + ": not running";
    return PullResult::kFailed;
  }
  if (index >= p_->sinks.size()) {
    why = camera_ + ": no sink " + std::to_string(index);
    return PullResult::kFailed;
  }
  GstAppSink* sink = p_->sinks[index];
  GstSample* sample = gst_app_sink_try_pull_sample(sink, static_cast<GstClockTime>(std::max<int64_t>(timeout_ns, 0)));
  if (const std::string error = BusError(); !error.empty()) {
    if (sample) gst_sample_unref(sample);
    why = camera_ + ": " + error;
    return PullResult::kFailed;
  }
  if (!sample) return gst_app_sink_is_eos(sink) ? PullResult::kEnded : PullResult::kTimeout;
  const SampleRef held{sample};

  GstVideoInfo info;
  if (!gst_video_info_from_caps(&info, gst_sample_get_caps(sample)) ||
      GST_VIDEO_INFO_FORMAT(&info) != GST_VIDEO_FORMAT_GRAY8) {
    why = camera_ + ": the appsink did not get GRAY8 video (add videoconvert before it)";
    return PullResult::kFailed;
  }
  GstBuffer* buffer = gst_sample_get_buffer(sample);
  GstMapInfo map;
  if (!buffer || !gst_buffer_map(buffer, &map, GST_MAP_READ)) {
    why = camera_ + ": a buffer could not be read";
    return PullResult::kFailed;
  }
  const int width = GST_VIDEO_INFO_WIDTH(&info), height = GST_VIDEO_INFO_HEIGHT(&info);
  const size_t stride = static_cast<size_t>(GST_VIDEO_INFO_PLANE_STRIDE(&info, 0));
  if (map.size < stride * static_cast<size_t>(height - 1) + static_cast<size_t>(width)) {
    gst_buffer_unmap(buffer, &map);
    why = camera_ + ": a buffer is smaller than its " + std::to_string(width) + "x" + std::to_string(height) + " caps";
    return PullResult::kFailed;
  }
  frame.gray = cv::Mat(height, width, CV_8UC1, map.data, stride).clone();
  gst_buffer_unmap(buffer, &map);

  // Clock time = base time + running time of the PTS; a buffer without a
  // PTS (some sources) is stamped when it is pulled.
  const GstClockTime pts = GST_BUFFER_PTS(buffer);
  const GstClockTime running =
      GST_CLOCK_TIME_IS_VALID(pts) ? gst_segment_to_running_time(gst_sample_get_segment(sample), GST_FORMAT_TIME, pts)
                                   : GST_CLOCK_TIME_NONE;
  frame.clock_ns = GST_CLOCK_TIME_IS_VALID(running)
                       ? static_cast<int64_t>(gst_element_get_base_time(p_->pipeline) + running)
                       : ClockNowNs();
  frame.sequence = ++sequence_[index];
  return PullResult::kFrame;
}

}  // namespace locaid::sensors
