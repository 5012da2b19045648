#include "pipeline/run_assembly.hpp"

#include <utility>

namespace locaid::pipeline {

std::unique_ptr<Estimator> MakeLocalizer(const EstimatorInputs& inputs) {
  return std::make_unique<Localizer>(inputs.camera, inputs.T_cam0_imu, inputs.localizer);
}

EstimatorInputs EstimatorInputsFor(const StereoCamera& camera, const Eigen::Isometry3d& T_cam0_imu,
                                   const RunOptions& options) {
  EstimatorInputs inputs{camera, T_cam0_imu, options.scenario, options.localizer};
  inputs.localizer.ekf = EkfConfigForScenario(inputs.localizer.ekf, inputs.scenario);
  return inputs;
}

PlacedRun PlaceRun(const FrameSource& source, const RunOptions& options) {
  RunOptions placed = options;
  const double duration_s = source.duration_s();
  if (duration_s > 0) placed.scenario = sim::PlaceOutagesForDrive(placed.scenario, duration_s);
  PlacedRun run;
  run.estimator = EstimatorInputsFor(source.camera(), source.T_cam0_imu(), placed);
  run.scenario = run.estimator.scenario;
  run.notice = sim::OutageCoverageWarning(run.scenario, duration_s);
  return run;
}

AssembledRun AssembleRun(std::unique_ptr<FrameSource> source, const RunOptions& options,
                         const EstimatorMaker& make) {
  PlacedRun placed = PlaceRun(*source, options);
  AssembledRun run;
  run.scenario = std::move(placed.scenario);
  run.notice = std::move(placed.notice);
  run.loop = std::make_unique<FrameLoop>(std::move(source), ScenarioStage(run.scenario), make(placed.estimator));
  run.loop->set_notice(run.notice);
  return run;
}

}  // namespace locaid::pipeline
