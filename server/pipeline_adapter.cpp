// The server's only contact with locaid_pipeline / locaid_fusion.
#include "server/source_pipeline.hpp"

#include "server/pose_message.hpp"

#include "pipeline/localizer.hpp"
#include "pipeline/scenario_yaml.hpp"

#include <stdexcept>

namespace locaid::server {

namespace {

class LocalizerEstimator : public FrameEstimator {
 public:
  explicit LocalizerEstimator(const EstimatorSetup& setup)
      : localizer_(setup.camera, setup.T_cam0_imu, setup.scenario, Options(setup)) {}

  static pipeline::LocalizerOptions Options(const EstimatorSetup& setup) {
    pipeline::LocalizerOptions options;
    options.vo_method = setup.vo_method;
    options.ekf.gps_lever_arm_body_m = setup.gps_antenna_body_m;
    return options;
  }

  Estimate Process(const vo::StereoFrame& frame, std::span<const kitti::OxtsSample> oxts) override {
    const pipeline::FrameResult r = localizer_.Process(frame, oxts);
    Estimate e;
    e.gps_fixes = FixesSeen(r);
    e.pose = r.pose;
    e.vo_inliers = r.vo.inliers;
    e.vo_status = r.vo.status;
    e.in_outage = r.in_outage;
    return e;
  }
  std::vector<FixSeen> FuseSensors(const pipeline::SensorBatch& batch) override {
    return FixesSeen(localizer_.FuseSensors(batch));
  }

  void ScheduleOutage(int64_t start_ns, int64_t end_ns) override { localizer_.ScheduleOutage(start_ns, end_ns); }
  void StartOutageNow() override { localizer_.StartOutageNow(); }
  void StopOutageNow() override { localizer_.StopOutageNow(); }
  void SetScenario(const fusion::Scenario& scenario) override { localizer_.SetScenario(scenario); }
  bool origin(double* lat_deg, double* lon_deg, double* alt_m) const override {
    if (!localizer_.has_enu_origin()) return false;
    const auto& enu = localizer_.ekf().enu();
    *lat_deg = enu.origin_lat_deg();
    *lon_deg = enu.origin_lon_deg();
    *alt_m = enu.origin_alt_m();
    return true;
  }

 private:
  pipeline::Localizer localizer_;
};

}  // namespace

std::unique_ptr<FrameEstimator> MakeLocalizerEstimator(const EstimatorSetup& setup) {
  return std::make_unique<LocalizerEstimator>(setup);
}

fusion::Scenario ScenarioFromName(const std::string& name) {
  fusion::Scenario s = fusion::BuiltinScenario(name);
  fusion::ValidateScenario(s);
  return s;
}

fusion::Scenario ScenarioFromYaml(const std::string& yaml) {
  try {
    // "yaml" names it (errors read "yaml:LINE: ...") unless it has a name: key.
    fusion::Scenario s = pipeline::ParseScenarioYaml(yaml, "yaml");
    fusion::ValidateScenario(s);
    return s;
  } catch (const pipeline::ScenarioError& e) {
    throw std::invalid_argument(e.what());
  }
}

fusion::Scenario PlaceScenarioOutages(fusion::Scenario scenario, double drive_duration_s) {
  return fusion::PlaceOutagesForDrive(std::move(scenario), drive_duration_s);
}


}  // namespace locaid::server
