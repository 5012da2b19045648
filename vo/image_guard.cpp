#include "vo/image_guard.hpp"

#include "vo/odometry_common.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

namespace locaid::vo {

ImageSample SampleImage(const cv::Mat& grey, int step_px) {
  ImageSample s;
  if (grey.empty() || grey.type() != CV_8UC1) return s;
  s.rows = grey.rows;
  s.cols = grey.cols;
  s.px.reserve(static_cast<size_t>((grey.rows + step_px - 1) / step_px) * ((grey.cols + step_px - 1) / step_px));
  std::array<int, 256> histogram{};
  double sum = 0, sum_sq = 0;
  for (int y = 0; y < grey.rows; y += step_px) {
    const uchar* row = grey.ptr<uchar>(y);
    for (int x = 0; x < grey.cols; x += step_px) {
      const uchar v = row[x];
      s.px.push_back(v);
      ++histogram[v];
      sum += v;
      sum_sq += static_cast<double>(v) * v;
    }
  }
  const double n = static_cast<double>(s.px.size());
  const double mean = sum / n;
  s.stddev = std::sqrt(std::max(0.0, sum_sq / n - mean * mean));
  const auto percentile = [&](double q) {
    const double target = q * n;
    double seen = 0;
    for (int v = 0; v < 256; ++v) {
      seen += histogram[static_cast<size_t>(v)];
      if (seen > target) return v;
    }
    return 255;
  };
  s.p_low = percentile(0.01);
  s.p_high = percentile(0.99);
  return s;
}

double MeanAbsDifference(const ImageSample& a, const ImageSample& b) {
  if (a.px.empty() || a.rows != b.rows || a.cols != b.cols || a.px.size() != b.px.size())
    return std::numeric_limits<double>::infinity();
  int64_t sum = 0;
  for (size_t i = 0; i < a.px.size(); ++i) sum += std::abs(static_cast<int>(a.px[i]) - static_cast<int>(b.px[i]));
  return static_cast<double>(sum) / static_cast<double>(a.px.size());
}

double EstimateNoiseDn(const cv::Mat& grey) {
  if (grey.rows < 3 || grey.cols < 3) return 0;
  cv::Mat f, laplacian;
  grey.convertTo(f, CV_32F);
  const cv::Mat kernel = (cv::Mat_<float>(3, 3) << 1, -2, 1, -2, 4, -2, 1, -2, 1);
  cv::filter2D(f, laplacian, CV_32F, kernel);
  const cv::Rect inner(1, 1, grey.cols - 2, grey.rows - 2);
  const double sum_abs = cv::norm(laplacian(inner), cv::NORM_L1);
  return std::sqrt(M_PI / 2) * sum_abs / (6.0 * inner.area());
}

double SignalToNoise(const ImageSample& sample, double noise_dn) {
  const double signal = std::sqrt(std::max(0.0, sample.stddev * sample.stddev - noise_dn * noise_dn));
  return signal / std::max(noise_dn, 0.1);
}

StereoFrame StretchDark(const StereoFrame& frame, const ImageSample& left, double noise_dn,
                        const ImageGuardConfig& cfg) {
  const double range = std::max(1, left.p_high - left.p_low);
  const double gain = 255.0 / range;
  // Smoothing so the stretched white noise stays near stretch_noise_dn: a
  // Gaussian of sigma s divides it by 2 sqrt(pi) s.
  const double noise = noise_dn * gain;
  const double sigma = std::min(cfg.max_smoothing_px, noise / (2 * std::sqrt(M_PI) * cfg.stretch_noise_dn));
  StereoFrame out;
  out.t_ns = frame.t_ns;
  const auto stretch = [&](const cv::Mat& image) {
    if (image.empty()) return cv::Mat();
    cv::Mat f, stretched;
    ToGrey(image).convertTo(f, CV_32F);
    if (sigma >= 0.5) cv::GaussianBlur(f, f, cv::Size(0, 0), sigma);
    f.convertTo(stretched, CV_8U, gain, -gain * left.p_low);  // rounded, saturated to 0..255
    return stretched;
  };
  out.left = stretch(frame.left);
  out.right = stretch(frame.right);
  return out;
}

GuardedOdometry::GuardedOdometry(std::unique_ptr<StereoOdometry> method, const ImageGuardConfig& config)
    : method_(std::move(method)), cfg_(config) {}

void GuardedOdometry::Reset() {
  method_->Reset();
  prev_left_ = {};
  prev_right_ = {};
}

RelativeMotion GuardedOdometry::Track(const StereoFrame& frame) {
  ImageSample left = SampleImage(frame.left.empty() ? cv::Mat() : ToGrey(frame.left), cfg_.sample_step_px);
  ImageSample right = SampleImage(frame.right.empty() ? cv::Mat() : ToGrey(frame.right), cfg_.sample_step_px);
  const bool textured = !left.px.empty() && left.stddev >= cfg_.min_image_stddev;
  const bool frozen = textured && MeanAbsDifference(left, prev_left_) <= cfg_.frozen_max_mad_dn &&
                      (right.px.empty() || MeanAbsDifference(right, prev_right_) <= cfg_.frozen_max_mad_dn);
  const bool dark = !left.px.empty() && (!textured || left.p_high - left.p_low < cfg_.dark_range_dn);
  RelativeMotion m;
  if (frozen) {
    m = NoMotion(frame.t_ns, Status::kLost);  // not shown to the method: its reference stays the last good frame
  } else if (dark && textured) {
    const double noise_dn = EstimateNoiseDn(ToGrey(frame.left));
    m = SignalToNoise(left, noise_dn) < cfg_.min_dark_snr ? NoMotion(frame.t_ns, Status::kLost)
                                                          : method_->Track(StretchDark(frame, left, noise_dn, cfg_));
  } else {
    m = method_->Track(frame);
  }
  if (m.status != Status::kLost) m.health = Health::kTracking;
  else m.health = frozen ? Health::kFrozen : dark ? Health::kDark : Health::kLost;
  // A missing image keeps the previous sample: the same content after a gap is still frozen.
  if (!left.px.empty()) prev_left_ = std::move(left);
  if (!right.px.empty()) prev_right_ = std::move(right);
  return m;
}

}  // namespace locaid::vo
