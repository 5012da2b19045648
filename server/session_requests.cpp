// Request translation for starting sessions: every field of a
// StartSessionRequest (and a PushSensorData start) is checked here, before
// the RPC answers OK, and turned into a session's pipeline.
#include "core/stereo_camera.hpp"
#include "server/service.hpp"

#include "kitti/dataset.hpp"
#include "kitti/raw_drive.hpp"
#include "pipeline/live_frame_source.hpp"
#include "server/bag_source_request.hpp"
#include "server/camera_feeder.hpp"
#include "server/gpsd_feeder.hpp"
#include "server/live_source_request.hpp"
#include "server/status.hpp"
#include "server/synthetic_drive.hpp"
#include "server/deferred_run_loop.hpp"
#include "pipeline/frame_source.hpp"
#include "pipeline/run_assembly.hpp"
#include "pipeline/scenario_yaml.hpp"

#include <algorithm>
#include <atomic>
#include <climits>
#include <cmath>
#include <filesystem>
#include <optional>
#include <sstream>
#include <string>
#include <utility>

namespace locaid::server {
namespace {

namespace v1 = locaid::v1;
using grpc::Status;
using grpc::StatusCode;

bool Finite(double x) { return std::isfinite(x); }

// VehicleOptions: constraints on or off, and the IMU's mounting in the car.
Status ParseVehicleOptions(const v1::VehicleOptions& v, pipeline::RunOptions* run) {
  fusion::EkfConfig::Vehicle& vehicle = run->localizer.ekf.vehicle;
  vehicle.constraints = !v.constraints_off();
  vehicle.constraints_need_speed = !v.constraints_without_speed();
  if (v.r_vehicle_body_size() == 0) return Status::OK;
  if (v.r_vehicle_body_size() != 9)
    return Invalid("vehicle.R_vehicle_body: expected 0 or 9 values (row-major 3x3), got " +
                   std::to_string(v.r_vehicle_body_size()));
  Eigen::Matrix3d R;
  for (int i = 0; i < 9; ++i) {
    if (!Finite(v.r_vehicle_body(i))) return Invalid("vehicle.R_vehicle_body: values must be finite");
    R(i / 3, i % 3) = v.r_vehicle_body(i);
  }
  if (!(R.transpose() * R).isApprox(Eigen::Matrix3d::Identity(), 1e-6) || R.determinant() < 0)
    return Invalid("vehicle.R_vehicle_body: not a rotation (R^T R must be I to 1e-6, det +1)");
  vehicle.R_vehicle_body = R;
  return Status::OK;
}

// The frame loop of a session reading `source`, assembled as locaid-replay
// assembles its runs: an outage that leaves the filter nothing to start from
// is said with the first pose (Session.error). Throws what the factory throws.
std::unique_ptr<pipeline::FrameLoop> MakeFrameLoop(const pipeline::EstimatorMaker& make, const pipeline::RunOptions& run,
                                                   std::unique_ptr<pipeline::FrameSource> source) {
  return pipeline::AssembleRun(std::move(source), run, make).loop;
}

// A KITTI drive on the server: opened and checked (frames in range, at least
// one stereo pair), or the status that says why not.
Status OpenKittiSource(const v1::KittiSource& k, std::unique_ptr<pipeline::FrameSource>* out, std::string* name) {
  if (Status s = RequireServerPath("kitti.path", k.path(), "a drive or sequence folder on the server"); !s.ok())
    return s;
  std::error_code ec;
  if (!std::filesystem::is_directory(k.path(), ec)) {
    return Invalid("kitti.path " + Quoted(k.path()) + ": not a directory");
  }
  if (k.first_frame() < 0) return Invalid("kitti.first_frame: must be >= 0");
  if (k.last_frame() > 0 && k.last_frame() < k.first_frame()) {
    return Invalid("kitti.last_frame " + std::to_string(k.last_frame()) + ": before first_frame " +
                   std::to_string(k.first_frame()) + " (last_frame <= 0 plays to the end)");
  }
  // A bad OXTS file mid-drive is skipped and counted (pipeline::DatasetFrameSource
  // reports it as bad OXTS lines), not a refused drive.
  kitti::RawDriveOptions open_options;
  open_options.skip_bad_oxts = true;
  auto dataset = kitti::OpenDataset(k.path(), open_options);
  if (dataset->size() == 0) return {StatusCode::FAILED_PRECONDITION, "kitti.path " + Quoted(k.path()) + ": no frames"};
  if (static_cast<size_t>(k.first_frame()) >= dataset->size()) {
    return Invalid("kitti.first_frame " + std::to_string(k.first_frame()) + ": the drive has " +
                   std::to_string(dataset->size()) + " frames");
  }
  // A drive without stereo pairs (no image_01/, say) would "finish"
  // with no poses: refuse it now.
  const size_t last = k.last_frame() <= 0 ? dataset->size() - 1
                                          : std::min(dataset->size() - 1, static_cast<size_t>(k.last_frame()));
  bool any_stereo = false;
  for (size_t i = static_cast<size_t>(k.first_frame()); i <= last && !any_stereo; ++i)
    any_stereo = dataset->has_stereo(i);
  if (!any_stereo) {
    return {StatusCode::FAILED_PRECONDITION, "kitti.path " + Quoted(k.path()) + ": no frame in [" +
                                                 std::to_string(k.first_frame()) + ", " + std::to_string(last) +
                                                 "] has both a left and a right image (image_00/, image_01/)"};
  }
  *name = "kitti:" + k.path();
  *out = std::make_unique<pipeline::DatasetFrameSource>(std::move(dataset), k.first_frame(),
                                                k.last_frame() <= 0 ? -1 : k.last_frame());
  return Status::OK;
}

// A live source: camera, antenna lever arm, speed sensor and an optional gpsd
// receiver (live_source_request.cpp checks them).
Status OpenLiveSource(const v1::LiveSource& l, pipeline::RunOptions* run, std::unique_ptr<pipeline::LiveFrameSource>* out,
                      std::optional<GpsdEndpoint>* gpsd, std::optional<CameraSetup>* cameras, std::string* name) {
  LiveSourceSetup live;
  if (const std::string error = LiveSourceFromProto(l, KittiRigTcam0Imu(), &live); !error.empty()) {
    return Invalid(error);
  }
  fusion::EkfConfig& ekf = run->localizer.ekf;
  ekf.gps.lever_arm_body_m = live.gps_antenna_body_m;
  // LiveSource.speed_sensor: 0 keeps the filter's defaults.
  if (live.speed_sigma_mps > 0) ekf.vehicle.speed_sigma_mps = live.speed_sigma_mps;
  if (live.speed_scale_sigma > 0) ekf.vehicle.speed_scale_sigma = live.speed_scale_sigma;
  ekf.imu.enabled = live.camera.expects_imu;
  *gpsd = live.gpsd;
  *cameras = live.cameras;
  *out = std::make_unique<pipeline::LiveFrameSource>(live.camera);
  *name = std::string("live") + (*cameras ? "+cameras" : "") +
          (*gpsd ? "+gpsd:" + (*gpsd)->host + ":" + std::to_string((*gpsd)->port) : "");
  return Status::OK;
}

}  // namespace

Status LocalizationService::ResolveScenario(const v1::Scenario& s, sim::Scenario* out, std::string* name) const {
  try {
    switch (s.kind_case()) {
      case v1::Scenario::kYaml:
        // "yaml" names it (errors read "yaml:LINE: ...") unless it has a name: key.
        *out = pipeline::ParseScenarioYaml(s.yaml(), "yaml");
        *name = out->name.empty() ? "yaml" : out->name;
        break;
      case v1::Scenario::kName:
        *out = sim::BuiltinScenario(s.name());
        *name = s.name();
        break;
      case v1::Scenario::KIND_NOT_SET:
        *out = sim::BuiltinScenario(config_.default_scenario);
        *name = config_.default_scenario;
        break;
    }
    sim::ValidateScenario(*out);
  } catch (const std::exception& e) {
    return Invalid(std::string("scenario: ") + e.what());
  }
  return Status::OK;
}

// The options every source shares: pacing, VO method, history, scenario.
Status LocalizationService::SessionOptionsFromRequest(const v1::StartSessionRequest& req, SessionOptions* options,
                                                      pipeline::RunOptions* run) const {
  // Pacing divides the sensor time by the rate: outside [1e-3, 1e3] it
  // overflows or is meaningless (1e-300 played at full speed).
  const double rate = req.playback_rate();
  if (!Finite(rate) || (rate != 0 && (rate < kMinPlaybackRate || rate > kMaxPlaybackRate))) {
    std::ostringstream got;
    got << rate;
    return Invalid("playback_rate: must be 0 (as fast as possible) or in [0.001, 1000], got " + got.str());
  }
  options->playback_rate = req.playback_rate();
  options->vo_method = req.vo_method().empty() ? config_.default_vo_method : req.vo_method();
  options->history_size = req.history_size() == 0 ? config_.history_size
                                                   : std::min<size_t>(req.history_size(), config_.max_history_size);
  run->localizer.vo_method = options->vo_method;
  if (Status s = ParseVehicleOptions(req.vehicle(), run); !s.ok()) return s;
  run->localizer.ekf.vo.learn_noise = !req.noise().fixed_vo_noise();
  run->localizer.ekf.gps.learn_noise = !req.noise().fixed_gps_noise();
  return ResolveScenario(req.scenario(), &run->scenario, &options->scenario);
}

Status LocalizationService::DoStart(const v1::StartSessionRequest& req, std::string* id) {
  SessionOptions options;
  pipeline::RunOptions run;
  if (Status s = SessionOptionsFromRequest(req, &options, &run); !s.ok()) return s;
  std::unique_ptr<pipeline::FrameSource> source;
  pipeline::LiveFrameSource* live = nullptr;
  std::optional<GpsdEndpoint> gpsd;
  std::optional<CameraSetup> cameras;
  try {
    switch (req.source_case()) {
      case v1::StartSessionRequest::kKitti:
        if (Status s = OpenKittiSource(req.kitti(), &source, &options.source); !s.ok()) return s;
        break;
      case v1::StartSessionRequest::kBag:
        if (Status s = OpenBagSource(req.bag(), &run, &source, &options.source); !s.ok()) return s;
        break;
      case v1::StartSessionRequest::kSynthetic:
        return StartSynthetic(req.synthetic(), std::move(options), std::move(run), id);
      case v1::StartSessionRequest::kLive: {
        std::unique_ptr<pipeline::LiveFrameSource> src;
        if (Status s = OpenLiveSource(req.live(), &run, &src, &gpsd, &cameras, &options.source); !s.ok()) return s;
        live = src.get();
        source = std::move(src);
        break;
      }
      case v1::StartSessionRequest::SOURCE_NOT_SET:
        return Invalid("source: one of kitti, bag, synthetic or live is required");
    }
  } catch (const kitti::Error& e) {
    return {StatusCode::FAILED_PRECONDITION, std::string("cannot open input: ") + e.what()};
  } catch (const SyntheticError& e) {
    return {StatusCode::FAILED_PRECONDITION, std::string("synthetic drive: ") + e.what()};
  } catch (const std::invalid_argument& e) {
    return Invalid(e.what());
  }
  std::unique_ptr<pipeline::FrameLoop> loop;
  options.estimator = std::make_shared<EstimatorHandle>();
  try {
    loop = MakeFrameLoop(RecordEstimator(make_estimator_, options.estimator), run, std::move(source));
  } catch (const std::exception& e) {
    return Invalid(std::string("vo_method/scenario: ") + e.what());
  }
  if (cameras) {  // started last: frames flow from here on
    CameraFeeder::OpenError error;
    auto feeder = CameraFeeder::Open(*cameras, live, &error);
    if (!feeder) {
      return {error.invalid_argument ? StatusCode::INVALID_ARGUMENT : StatusCode::FAILED_PRECONDITION,
              "live.cameras: " + error.message};
    }
    live->AttachFeeder(std::move(feeder));
  }
  if (gpsd) live->AttachFeeder(std::make_unique<GpsdFeeder>(*gpsd, live));
  return sessions_.Add(std::move(options), std::move(loop), live, id);
}

Status LocalizationService::StartSynthetic(const v1::SyntheticSource& s, SessionOptions options,
                                          pipeline::RunOptions run, std::string* id) {
  const size_t frames = s.frames() == 0 ? config_.synthetic_default_frames : s.frames();
  if (frames < 2 || frames > config_.max_synthetic_frames) {
    return Invalid("synthetic.frames: must be in [2, max_synthetic_frames=" +
                   std::to_string(config_.max_synthetic_frames) + "], got " + std::to_string(frames));
  }
  SyntheticRig rig;
  try {
    rig = ValidateSyntheticRequest(s.seed(), frames, s.options_yaml(), config_.max_synthetic_frames);
  } catch (const SyntheticError& e) {
    return Invalid(e.what());
  }
  // The estimator is built after the render; building one now with the
  // drive's rig checks vo_method and the scenario before the RPC answers.
  try {
    make_estimator_(pipeline::EstimatorInputsFor(rig.camera, rig.T_cam0_imu, run));
  } catch (const std::exception& e) {
    return Invalid(std::string("vo_method/scenario: ") + e.what());
  }
  options.source = "synthetic:seed=" + std::to_string(s.seed()) + ",frames=" + std::to_string(frames);
  // Rendered on the session thread (can take seconds); failures fail the session.
  // Each session renders its own folder and deletes it when its
  // pipeline ends, so rendered drives never outlive their sessions.
  const std::filesystem::path drive_dir = SyntheticRoot(config_.work_dir) / RandomSessionId();
  options.estimator = std::make_shared<EstimatorHandle>();  // set on the session thread, after the render
  auto factory = [drive_dir, seed = s.seed(), frames, yaml = s.options_yaml(), run,
                  make = RecordEstimator(make_estimator_, options.estimator)](
                     const std::atomic<bool>& cancel) mutable -> std::unique_ptr<pipeline::RunLoop> {
    auto src = std::make_unique<pipeline::DatasetFrameSource>(
        MakeSyntheticDrive(drive_dir, seed, frames, yaml, &cancel), 0, -1);
    return MakeFrameLoop(make, run, std::move(src));
  };
  auto remove_drive = [drive_dir] {
    std::error_code ec;
    std::filesystem::remove_all(drive_dir, ec);
  };
  return sessions_.Add(std::move(options),
                       std::make_unique<DeferredRunLoop>(std::move(factory), static_cast<int64_t>(frames),
                                                          std::move(remove_drive)),
                       nullptr, id);
}

Status LocalizationService::StartLive(const v1::PushStart& start, std::shared_ptr<Session>* session,
                                      pipeline::LiveFrameSource** live) {
  if (!start.session_id().empty()) return sessions_.AttachPush(start.session_id(), true, session, live);
  v1::StartSessionRequest req;
  *req.mutable_live() = start.live();
  *req.mutable_scenario() = start.scenario();
  *req.mutable_vehicle() = start.vehicle();
  *req.mutable_noise() = start.noise();
  req.set_vo_method(start.vo_method());
  req.set_history_size(start.history_size());
  std::string id;
  if (Status s = DoStart(req, &id); !s.ok()) return s;
  return sessions_.AttachPush(id, false, session, live);
}

}  // namespace locaid::server
