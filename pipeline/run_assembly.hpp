// One assembly of a run, for every caller: a server session (of any source)
// and locaid-replay (whose runs locaid-sweep starts) put a frame loop
// together here and nowhere else, so a replay and a session cannot drift
// apart in how outages are placed or which filter settings a scenario asks.
#pragma once

#include "core/stereo_camera.hpp"
#include "pipeline/frame_loop.hpp"
#include "pipeline/localizer.hpp"
#include "sim/scenario.hpp"

#include <Eigen/Geometry>

#include <functional>
#include <memory>
#include <string>

namespace locaid::pipeline {

// What a caller chose for a run: the scenario (outages relative to the
// drive), the VO method and its own filter settings (IMU, noise models,
// vehicle, lever arm, overrides). The scenario's part of the filter settings
// (EkfConfigForScenario) is added by the assembly, after the caller's.
struct RunOptions {
  sim::Scenario scenario;
  LocalizerOptions localizer;
};

// What an estimator is built from: the source's camera and extrinsic, the
// scenario as placed on the drive, and the filter settings, complete.
struct EstimatorInputs {
  StereoCamera camera;
  Eigen::Isometry3d T_cam0_imu = Eigen::Isometry3d::Identity();
  sim::Scenario scenario;
  LocalizerOptions localizer;
};
// Builds the estimator; throws std::invalid_argument (an unknown VO method).
// Tests and benchmarks pass their own.
using EstimatorMaker = std::function<std::unique_ptr<Estimator>(const EstimatorInputs&)>;
// The production one: a Localizer that computes VO from the images.
std::unique_ptr<Estimator> MakeLocalizer(const EstimatorInputs& inputs);

// The inputs of a run's estimator for a rig, before its drive is known (the
// scenario as given); AssembleRun makes them with the outages placed.
EstimatorInputs EstimatorInputsFor(const StereoCamera& camera, const Eigen::Isometry3d& T_cam0_imu,
                                   const RunOptions& options);

// A run's parts before its frame loop: the scenario with its outages placed
// on the source's drive (on its duration_s() when it knows one, > 0; else
// as given), what they leave the filter without ("" if nothing), and the
// estimator's inputs. AssembleRun puts a frame loop together from them; a
// program that drives the stages itself (bench/pipeline/frame_cost.cpp,
// locaid-nmea) takes them from here too, so it runs what a run runs.
struct PlacedRun {
  sim::Scenario scenario;
  std::string notice;
  EstimatorInputs estimator;
};
PlacedRun PlaceRun(const FrameSource& source, const RunOptions& options);

struct AssembledRun {
  sim::Scenario scenario;  // with its outages placed on the source's drive
  std::string notice;      // what the outages leave the filter without ("" if nothing); also the loop's notice
  std::unique_ptr<FrameLoop> loop;
};

// source -> the scenario's stage -> the estimator `make` builds, as
// PlaceRun places them. Throws what `make` throws.
AssembledRun AssembleRun(std::unique_ptr<FrameSource> source, const RunOptions& options,
                         const EstimatorMaker& make = MakeLocalizer);

}  // namespace locaid::pipeline
