// libFuzzer target: the messages of a PushSensorData stream (locaid.v1.PushRequest
// with start, frame, oxts, imu, gps or speed), as the server turns them into
// pipeline input: a first 'start' carrying a LiveSource through
// server/live_source_request.hpp LiveSourceFromProto, the typed messages
// through server/push_requests.hpp ImuItemFromProto / GpsItemFromProto,
// then the session's pipeline::LiveFrameSource (ordering, OXTS line parsing,
// frame decoding).
//
// Input: the stream as protobuf's length-delimited sequence (varint size,
// then a serialized PushRequest, repeated; what
// google::protobuf::util::SerializeDelimitedToOstream writes), up to
// kMaxMessages. Parsing stops at the first malformed message; the ones
// before it are used. A first 'start' with a live source is checked as the
// server checks it: refused, the stream ends there; accepted, the session
// takes its extrinsic and GPS delay bound. The session camera's image is a
// fixed 16x16 stereo pair (the smallest LiveSource allows), so raw GRAY8
// frames are 256 bytes.
//
// Every message is handled as stream_reactors.cpp's PushReactor does (its
// gRPC reactor is not reachable without a server): a frame with another
// encoding is refused, a PNG declaring another size ends the stream, an
// IMU/GPS message is converted or refused with a reason.
//
// Contract:
//  - an accepted live source has finite intrinsics (fx, fy, baseline > 0), a
//    size in [16, 8192], a finite T_cam0_imu whose rotation is orthonormal to
//    1e-6 with determinant > 0, a GPS delay bound in (0, 10] s, a lever arm
//    within 10 m per axis, speed sensor sigmas in [0, 10] m/s and [0, 0.5],
//    a gpsd host without blanks or '/' of at most 253 bytes and a port > 0;
//  - a refused IMU/GPS message (or live source) has a non-empty reason;
//  - an accepted one carries finite values inside the documented ranges
//    (docs/api.md "Typed sensor input"): |a| <= 2000 m/s^2, |w| <= 100 rad/s,
//    noise densities >= 0; latitude/longitude in range, altitude in
//    [-1000, 100000] m (0 for a 2-D fix), sigmas > 0, a covariance symmetric
//    (entry by entry) and positive definite (Cholesky), |v| <= 200 m/s;
//  - what LiveFrameSource hands the pipeline is ordered and finite: frames
//    strictly increasing in time with CV_8UC1 16x16 images, IMU samples and
//    fixes strictly increasing in time (fixes of a frame not after it), OXTS
//    samples strictly increasing with finite fields, every pushed IMU/GPS
//    item counted once.
#include "fuzz/fuzz_support.hpp"
#include "pipeline/frame_source.hpp"
#include "pipeline/live_frame_source.hpp"
#include "server/live_source_request.hpp"
#include "server/push_requests.hpp"

#include "locaid/v1/localization.pb.h"

#include <google/protobuf/io/zero_copy_stream_impl_lite.h>
#include <google/protobuf/stubs/logging.h>
#include <google/protobuf/util/delimited_message_util.h>

#include <Eigen/Cholesky>

#include <climits>
#include <cmath>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace {

namespace v1 = locaid::v1;
namespace pipeline = locaid::pipeline;

constexpr int kMaxMessages = 64;
constexpr int kCameraSize = 16;
// Next() of a closed source returns kEnd once its queue is empty; this bounds
// the loop should it not.
constexpr int kMaxNextCalls = 4 * kMaxMessages + 8;

bool Finite3(const Eigen::Vector3d& v) { return v.allFinite(); }

void CheckImuItem(const pipeline::LiveItem& item) {
  const locaid::fusion::ImuSample& s = item.imu;
  LOCAID_FUZZ_CHECK(item.kind == pipeline::LiveItem::Kind::kImu, "IMU item of another kind");
  LOCAID_FUZZ_CHECK(s.t_ns == item.t_ns, "IMU sample time differs from the item's");
  LOCAID_FUZZ_CHECK(Finite3(s.accel_mps2) && Finite3(s.gyro_radps), "non-finite IMU sample accepted");
  LOCAID_FUZZ_CHECK(s.accel_mps2.norm() <= 2000, "|a| > 2000 m/s^2 accepted");
  LOCAID_FUZZ_CHECK(s.gyro_radps.norm() <= 100, "|w| > 100 rad/s accepted");
  LOCAID_FUZZ_CHECK(std::isfinite(s.accel_noise_mps2_sqrt_hz) && s.accel_noise_mps2_sqrt_hz >= 0,
                    "bad accel noise density accepted");
  LOCAID_FUZZ_CHECK(std::isfinite(s.gyro_noise_radps_sqrt_hz) && s.gyro_noise_radps_sqrt_hz >= 0,
                    "bad gyro noise density accepted");
}

void CheckCovariance(const Eigen::Matrix3d& C) {
  LOCAID_FUZZ_CHECK(C.allFinite(), "non-finite covariance accepted");
  // Symmetry entry by entry against the largest entry (cannot under- or
  // overflow, unlike a norm of the difference).
  const double scale = C.cwiseAbs().maxCoeff();
  const double asym = (0.5 * C - 0.5 * C.transpose()).cwiseAbs().maxCoeff();
  LOCAID_FUZZ_CHECK(asym <= 1e-9 * scale, "asymmetric covariance accepted");
  // Positive definite: the Cholesky factorisation exists (every pivot > 0).
  LOCAID_FUZZ_CHECK(Eigen::LLT<Eigen::Matrix3d>(C).info() == Eigen::Success,
                    "covariance that is not positive definite accepted");
  LOCAID_FUZZ_CHECK((C.diagonal().array() > 0).all(), "covariance with a variance <= 0 accepted");
}

void CheckGpsItem(const pipeline::LiveItem& item) {
  const locaid::fusion::GpsFix& f = item.gps;
  LOCAID_FUZZ_CHECK(item.kind == pipeline::LiveItem::Kind::kGps, "GPS item of another kind");
  LOCAID_FUZZ_CHECK(f.t_ns == item.t_ns, "fix time differs from the item's");
  if (item.gps_no_fix) return;  // position fields are ignored
  LOCAID_FUZZ_CHECK(std::isfinite(f.lat_deg) && f.lat_deg >= -90 && f.lat_deg <= 90, "bad latitude accepted");
  LOCAID_FUZZ_CHECK(std::isfinite(f.lon_deg) && f.lon_deg >= -180 && f.lon_deg <= 180, "bad longitude accepted");
  LOCAID_FUZZ_CHECK(std::isfinite(f.alt_m) && f.alt_m >= -1000 && f.alt_m <= 100000, "bad altitude accepted");
  LOCAID_FUZZ_CHECK(f.has_altitude || f.alt_m == 0, "2-D fix with an altitude");
  LOCAID_FUZZ_CHECK(std::isfinite(f.sigma_h_m) && f.sigma_h_m > 0, "bad horizontal sigma accepted");
  LOCAID_FUZZ_CHECK(std::isfinite(f.sigma_v_m) && f.sigma_v_m > 0, "bad vertical sigma accepted");
  if (f.cov_enu_m2) CheckCovariance(*f.cov_enu_m2);
  LOCAID_FUZZ_CHECK(std::isfinite(f.horizontal_sigma_m()) && f.horizontal_sigma_m() > 0 &&
                        std::isfinite(f.vertical_sigma_m()) && f.vertical_sigma_m() > 0,
                    "fix sigma the filter uses is not finite and > 0");
  if (f.v_enu_mps) {
    LOCAID_FUZZ_CHECK(Finite3(*f.v_enu_mps) && f.v_enu_mps->norm() <= 200, "bad velocity accepted");
    LOCAID_FUZZ_CHECK(std::isfinite(f.sigma_v_enu_mps) && f.sigma_v_enu_mps > 0, "bad velocity sigma accepted");
  }
}

void CheckLiveSource(const locaid::server::LiveSourceSetup& s) {
  const locaid::StereoCamera& c = s.camera.camera;
  LOCAID_FUZZ_CHECK(std::isfinite(c.fx) && c.fx > 0 && std::isfinite(c.fy) && c.fy > 0, "bad focal length accepted");
  LOCAID_FUZZ_CHECK(std::isfinite(c.cx) && std::isfinite(c.cy), "non-finite principal point accepted");
  LOCAID_FUZZ_CHECK(std::isfinite(c.baseline_m) && c.baseline_m > 0, "bad baseline accepted");
  LOCAID_FUZZ_CHECK(c.width >= 16 && c.height >= 16 && c.width <= 8192 && c.height <= 8192, "bad size accepted");
  const Eigen::Matrix4d T = s.camera.T_cam0_imu.matrix();
  LOCAID_FUZZ_CHECK(T.allFinite(), "non-finite T_cam0_imu accepted");
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  const double off = (R * R.transpose() - Eigen::Matrix3d::Identity()).norm();
  LOCAID_FUZZ_CHECK(off <= 1e-6, "T_cam0_imu whose rotation is not orthonormal accepted");
  LOCAID_FUZZ_CHECK(R.determinant() > 0, "T_cam0_imu that is a reflection accepted");
  const double delay = s.camera.max_gps_delay_s;
  LOCAID_FUZZ_CHECK(std::isfinite(delay) && delay > 0 && delay <= locaid::server::kMaxGpsDelayS,
                    "GPS delay bound outside (0, 10] s");
  LOCAID_FUZZ_CHECK(Finite3(s.gps_antenna_body_m) && s.gps_antenna_body_m.cwiseAbs().maxCoeff() <= 10,
                    "lever arm beyond 10 m accepted");
  LOCAID_FUZZ_CHECK(std::isfinite(s.speed_sigma_mps) && s.speed_sigma_mps >= 0 && s.speed_sigma_mps <= 10,
                    "bad speed sigma accepted");
  LOCAID_FUZZ_CHECK(std::isfinite(s.speed_scale_sigma) && s.speed_scale_sigma >= 0 && s.speed_scale_sigma <= 0.5,
                    "bad speed scale sigma accepted");
  if (s.gpsd) {
    LOCAID_FUZZ_CHECK(!s.gpsd->host.empty() && s.gpsd->host.size() <= 253 &&
                          s.gpsd->host.find_first_of(" \t\r\n/") == std::string::npos,
                      "bad gpsd host accepted");
    LOCAID_FUZZ_CHECK(s.gpsd->port > 0, "gpsd port 0 accepted");
  }
}

// The stream after 'start': what PushReactor::OnReadDone does per message.
// Returns the number of IMU and GPS items pushed.
std::pair<uint64_t, uint64_t> PushAll(const std::vector<v1::PushRequest>& messages,
                                      pipeline::LiveFrameSource& source) {
  uint64_t imu = 0, gps = 0;
  auto push = [&source](pipeline::LiveItem item) {
    // The queue holds every message (capacity kMaxMessages): never full.
    LOCAID_FUZZ_CHECK(source.Push(std::move(item), [] {}), "queue full below its capacity");
  };
  for (const v1::PushRequest& req : messages) {
    switch (req.item_case()) {
      case v1::PushRequest::kFrame: {
        const v1::StereoFrame& f = req.frame();
        if (f.encoding() != v1::IMAGE_ENCODING_PNG && f.encoding() != v1::IMAGE_ENCODING_GRAY8) break;
        pipeline::LiveItem item;
        item.kind = pipeline::LiveItem::Kind::kFrame;
        item.t_ns = f.t_ns();
        item.png = f.encoding() == v1::IMAGE_ENCODING_PNG;
        if (item.png && (!pipeline::PngSizeMismatch(f.left(), source.camera(), "left").empty() ||
                         !pipeline::PngSizeMismatch(f.right(), source.camera(), "right").empty())) {
          return {imu, gps};  // the stream ends (INVALID_ARGUMENT)
        }
        item.left = f.left();
        item.right = f.right();
        push(std::move(item));
        break;
      }
      case v1::PushRequest::kOxts: {
        pipeline::LiveItem item;
        item.kind = pipeline::LiveItem::Kind::kOxts;
        item.t_ns = req.oxts().t_ns();
        item.oxts_line = req.oxts().line();
        push(std::move(item));
        break;
      }
      case v1::PushRequest::kImu:
      case v1::PushRequest::kGps: {
        const bool is_imu = req.item_case() == v1::PushRequest::kImu;
        pipeline::LiveItem item;
        const std::string error = is_imu ? locaid::server::ImuItemFromProto(req.imu(), &item)
                                         : locaid::server::GpsItemFromProto(req.gps(), &item);
        if (!error.empty()) break;  // refused with `error` (PushRejected), the stream goes on
        if (is_imu) {
          CheckImuItem(item);
          ++imu;
        } else {
          CheckGpsItem(item);
          ++gps;
        }
        push(std::move(item));
        break;
      }
      case v1::PushRequest::kStart:
      case v1::PushRequest::ITEM_NOT_SET:
        break;  // refused, the stream goes on
    }
  }
  return {imu, gps};
}

// Drains the closed source and checks what the pipeline would get.
void DrainAndCheck(pipeline::LiveFrameSource& source, uint64_t imu_pushed, uint64_t gps_pushed) {
  std::optional<int64_t> last_frame_ns, last_imu_ns, last_gps_ns, last_oxts_ns;
  for (int calls = 0;; ++calls) {
    LOCAID_FUZZ_CHECK(calls < kMaxNextCalls, "closed source never ends");
    const pipeline::SourceItem out = source.Next();
    if (out.kind == pipeline::SourceItem::Kind::kEnd) break;
    if (out.kind == pipeline::SourceItem::Kind::kFrame) {
      LOCAID_FUZZ_CHECK(!last_frame_ns || out.t_ns > *last_frame_ns, "frame not after the previous frame");
      last_frame_ns = out.t_ns;
      for (const cv::Mat* image : {&out.left, &out.right}) {
        LOCAID_FUZZ_CHECK(image->type() == CV_8UC1 && image->cols == kCameraSize && image->rows == kCameraSize,
                          "frame image of the wrong type or size");
      }
    }
    for (const locaid::fusion::TruthSample& s : out.samples.truth_poses) {
      LOCAID_FUZZ_CHECK(!last_oxts_ns || s.t_ns > *last_oxts_ns, "OXTS sample not after the previous one");
      LOCAID_FUZZ_CHECK(s.t_ns <= out.t_ns, "OXTS sample after its frame");
      last_oxts_ns = s.t_ns;
      LOCAID_FUZZ_CHECK(std::isfinite(s.lat_deg) && std::isfinite(s.lon_deg) && std::isfinite(s.alt_m),
                        "non-finite OXTS position handed on");
    }
    LOCAID_FUZZ_CHECK(out.samples.truth_imu.size() == out.samples.truth_poses.size(),
                      "an OXTS record handed on without its IMU part");
    for (const locaid::fusion::ImuSample& s : out.samples.imu) {
      LOCAID_FUZZ_CHECK(!last_imu_ns || s.t_ns > *last_imu_ns, "IMU sample not after the previous one");
      LOCAID_FUZZ_CHECK(s.t_ns <= out.t_ns, "IMU sample after the item's time");
      LOCAID_FUZZ_CHECK(Finite3(s.accel_mps2) && Finite3(s.gyro_radps), "non-finite IMU sample handed on");
      last_imu_ns = s.t_ns;
    }
    for (const pipeline::ArrivedFix& a : out.samples.gps) {
      LOCAID_FUZZ_CHECK(!last_gps_ns || a.fix.t_ns > *last_gps_ns, "fix not after the previous one");
      LOCAID_FUZZ_CHECK(a.fix.t_ns <= out.t_ns, "fix after the item's time");
      LOCAID_FUZZ_CHECK(std::isfinite(a.fix.lat_deg) && std::isfinite(a.fix.lon_deg) && std::isfinite(a.fix.alt_m),
                        "non-finite fix handed on");
      last_gps_ns = a.fix.t_ns;
    }
  }
  const pipeline::LiveInputStats stats = source.input_stats();
  LOCAID_FUZZ_CHECK(stats.imu_samples == imu_pushed, "pushed IMU samples not all counted");
  LOCAID_FUZZ_CHECK(stats.gps_fixes_in == gps_pushed, "pushed fixes not all counted");
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  // Parse errors (invalid UTF-8 in a string field ...) are expected: quiet.
  google::protobuf::SetLogHandler(nullptr);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  google::protobuf::io::ArrayInputStream bytes(data, static_cast<int>(std::min<size_t>(size, INT_MAX)));
  std::vector<v1::PushRequest> messages;
  for (int i = 0; i < kMaxMessages; ++i) {
    v1::PushRequest req;
    bool clean_eof = false;
    if (!google::protobuf::util::ParseDelimitedFromZeroCopyStream(&req, &bytes, &clean_eof)) break;
    messages.push_back(std::move(req));
  }

  pipeline::LiveCameraSetup setup;
  if (!messages.empty() && messages.front().has_start() && messages.front().start().has_live()) {
    locaid::server::LiveSourceSetup live;
    const std::string error =
        locaid::server::LiveSourceFromProto(messages.front().start().live(), Eigen::Isometry3d::Identity(), &live);
    if (!error.empty()) return 0;  // INVALID_ARGUMENT with `error`: the stream ends
    CheckLiveSource(live);
    setup = live.camera;
  }
  setup.camera = locaid::StereoCamera{20.0, 20.0, 7.5, 7.5, 0.5, kCameraSize, kCameraSize};
  pipeline::LiveFrameSource source(setup, kMaxMessages);
  const auto [imu, gps] = PushAll(messages, source);
  source.CloseInput();
  DrainAndCheck(source, imu, gps);
  return 0;
}
