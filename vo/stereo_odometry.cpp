#include "vo/stereo_odometry.hpp"
#include "core/stereo_camera.hpp"

#include "vo/odometry_common.hpp"
#include "vo/stereo_geometry.hpp"

#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cmath>
#include <ctime>
#include <stdexcept>

namespace locaid::vo {

const char* ToString(Status status) {
  switch (status) {
    case Status::kOk: return "OK";
    case Status::kDegraded: return "DEGRADED";
    case Status::kLost: return "LOST";
  }
  return "UNKNOWN";
}

const char* ToString(Health health) {
  switch (health) {
    case Health::kTracking: return "tracking";
    case Health::kDark: return "dark";
    case Health::kFrozen: return "frozen";
    case Health::kLost: return "lost";
    case Health::kNoImages: return "no_images";
  }
  return "unknown";
}

std::string ImageProblem(const cv::Mat& image, const StereoCamera& camera,
                         double min_stddev) {
  if (image.empty()) return "image missing";
  if (image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3))
    return "image type " + std::to_string(image.type()) + ", expected CV_8UC1";
  if (image.cols != camera.width || image.rows != camera.height)
    return "image " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
           ", camera is " + std::to_string(camera.width) + "x" + std::to_string(camera.height);
  // Sparse sample: every 8th pixel of every 8th row.
  double sum = 0, sum_sq = 0;
  int n = 0;
  const int step = 8;
  for (int y = 0; y < image.rows; y += step) {
    const uchar* row = image.ptr<uchar>(y);
    for (int x = 0; x < image.cols; x += step) {
      const double v = row[x * image.channels()];
      sum += v;
      sum_sq += v * v;
      ++n;
    }
  }
  const double mean = sum / n;
  const double stddev = std::sqrt(std::max(0.0, sum_sq / n - mean * mean));
  if (stddev < min_stddev) return "no texture (intensity stddev " + std::to_string(stddev) + ")";
  return {};
}

cv::Mat ToGrey(const cv::Mat& image) {
  if (image.channels() == 1) return image;
  cv::Mat grey;
  cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  return grey;
}

bool FrameUsable(const StereoFrame& frame, const StereoCamera& camera, double min_stddev) {
  return ImageProblem(frame.left, camera, min_stddev).empty() &&
         ImageProblem(frame.right, camera, min_stddev).empty();
}

RelativeMotion NoMotion(int64_t t_ns, Status status) {
  RelativeMotion m;
  m.t_ns = t_ns;
  m.t_prev_ns = t_ns;
  m.status = status;
  m.covariance = LargeCovariance();
  return m;
}

double NowMs(TimingClock clock) {
  if (clock == TimingClock::kThreadCpu) {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
  }
  return std::chrono::duration<double, std::milli>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

double SumTimings(const StageTimings& timings) {
  double total = 0;
  for (const auto& [name, ms] : timings) total += ms;
  return total;
}

std::unique_ptr<StereoOdometry> MakeStereoOdometry(const std::string& method,
                                                   const StereoCamera& camera,
                                                   TimingClock clock) {
  return MakeStereoOdometry(method, camera, clock, DefaultConfig{});
}

std::unique_ptr<StereoOdometry> MakeStereoOdometry(const std::string& method,
                                                   const StereoCamera& camera,
                                                   TimingClock clock,
                                                   const DefaultConfig& default_config) {
  if (method == "default") {
    DefaultConfig config = default_config;
    config.timing_clock = clock;
    return MakeDefaultOdometry(camera, config);
  }
  if (method == "thesis") {
    ThesisConfig config;
    config.timing_clock = clock;
    return MakeThesisOdometry(camera, config);
  }
  throw std::invalid_argument("unknown VO method '" + method + "' (known: default, thesis)");
}

std::vector<std::string> StereoOdometryMethods() { return {"default", "thesis"}; }

}  // namespace locaid::vo
