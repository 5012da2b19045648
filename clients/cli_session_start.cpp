#include "clients/cli_session_start.hpp"

#include "bag/bag_topics.hpp"
#include "connection/host_port.hpp"

#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace locaid::clients {
namespace {

namespace v1 = locaid::v1;

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read '" + path + "'");
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// --live: the cameras' pipelines and camera_info files (read here, sent as
// text), and the gpsd the server reads GPS from ("HOST:PORT" or "HOST").
void FillLiveCameras(const StartOptions& o, v1::LiveSource* live) {
  v1::CameraSource* c = live->mutable_cameras();
  c->set_left_pipeline(o.camera_left);
  c->set_right_pipeline(o.camera_right);
  c->set_stereo_pipeline(o.camera_stereo);
  if (o.camera_info_left.empty() || o.camera_info_right.empty())
    throw std::invalid_argument("--live needs --camera-info-left FILE and --camera-info-right FILE");
  c->set_left_camera_info(ReadFile(o.camera_info_left));
  c->set_right_camera_info(ReadFile(o.camera_info_right));
  live->set_no_imu(o.no_imu);
  if (o.gpsd.empty()) return;
  const connection::HostPort gpsd = connection::SplitHostPort(o.gpsd, "--gpsd");
  v1::GpsdSource* g = live->mutable_gps_source()->mutable_gpsd();
  g->set_host(gpsd.host);
  g->set_port(gpsd.port);
}

}  // namespace

void AddStartOptions(CLI::App& start, StartOptions& so) {
  auto* o_kitti = start.add_option("--kitti", so.kitti_path,
                                   "KITTI raw drive or odometry sequence folder, opened by the server (a relative "
                                   "path is made absolute from this command's working directory)");
  auto* o_synth = start.add_option("--synthetic", so.synth_seed, "render a synthetic drive with this seed")
                      ->each([&so](const std::string&) { so.synthetic = true; });
  auto* o_bag = start.add_option("--bag", so.bag_path, "ROS 2 bag (.mcap file or rosbag2 directory), opened by the server; "
                                                       "a relative path is made absolute as --kitti's");
  o_bag->excludes(o_kitti)->excludes(o_synth);
  start.add_option("--bag-topics", so.bag_topics_file, "bag: YAML naming its topics (the keys of locaid-replay --bag-topics)")
      ->check(CLI::ExistingFile)->needs(o_bag);
  o_kitti->excludes(o_synth);
  auto* o_live = start.add_flag("--live", so.live, "a live session whose stereo cameras the server reads through "
                                                   "GStreamer (docs/api.md \"Cameras through GStreamer\")");
  o_live->excludes(o_kitti)->excludes(o_synth)->excludes(o_bag);
  start.add_option("--camera-left", so.camera_left, "live: the left camera's GStreamer pipeline (gst-launch syntax)");
  start.add_option("--camera-right", so.camera_right, "live: the right camera's GStreamer pipeline");
  start.add_option("--camera-stereo", so.camera_stereo,
                    "live: one pipeline with two appsinks named left and right (instead of --camera-left/-right)");
  start.add_option("--camera-info-left", so.camera_info_left, "live: the left camera's ROS camera_info YAML")
      ->check(CLI::ExistingFile);
  start.add_option("--camera-info-right", so.camera_info_right, "live: the right camera's ROS camera_info YAML")
      ->check(CLI::ExistingFile);
  start.add_option("--gpsd", so.gpsd, "live: GPS from the gpsd at HOST:PORT, read by the server");
  start.add_flag("--no-imu", so.no_imu, "live: the car has no IMU; the filter runs on VO + GPS alone")->needs(o_live);
  start.add_option("--frames", so.synth_frames, "synthetic: number of frames");
  start.add_option("--first", so.first_frame, "kitti: first frame");
  start.add_option("--last", so.last_frame, "kitti: last frame (default: to the end)");
  start.add_option("--scenario", so.scenario_name, "built-in GPS scenario, or a scenario YAML file (.yaml/.yml)");
  start.add_option("--scenario-file", so.scenario_file, "scenario YAML file (sent as text)");
  start.add_option("--vo", so.vo_method, "VO method");
  start.add_option("--rate", so.rate, "playback: 0 = as fast as possible, 1 = real time, N = N x")->capture_default_str();
  start.add_option("--history", so.history, "poses kept for --from-start subscribers");
  start.add_flag("--fixed-vo-noise", so.fixed_vo_noise, "the fixed VO noise model, not learnt (docs/api.md)");
  start.add_flag("--fixed-gps-noise", so.fixed_gps_noise, "the fixes' stated sigmas as they are, not learnt");
}

v1::StartSessionRequest StartSessionRequest(const StartOptions& o) {
  v1::StartSessionRequest req;
  if (!o.kitti_path.empty()) {
    // The server opens the path; a relative one means the caller's folder.
    req.mutable_kitti()->set_path(std::filesystem::absolute(o.kitti_path).lexically_normal().string());
    req.mutable_kitti()->set_first_frame(o.first_frame);
    req.mutable_kitti()->set_last_frame(o.last_frame);
  } else if (!o.bag_path.empty()) {
    req.mutable_bag()->set_path(std::filesystem::absolute(o.bag_path).lexically_normal().string());
    const auto t = o.bag_topics_file.empty() ? bag::BagTopics{} : bag::LoadBagTopics(o.bag_topics_file);
    v1::BagTopics* topics = req.mutable_bag()->mutable_topics();
    topics->set_left_image(t.left_image); topics->set_left_info(t.left_info); topics->set_imu(t.imu);
    topics->set_right_image(t.right_image); topics->set_right_info(t.right_info); topics->set_gps(t.gps);
    topics->set_speed(t.speed);
  } else if (o.synthetic) {
    req.mutable_synthetic()->set_seed(o.synth_seed);
    req.mutable_synthetic()->set_frames(o.synth_frames);
  } else if (o.live) {
    FillLiveCameras(o, req.mutable_live());
  } else {
    throw std::invalid_argument("session start needs --kitti PATH, --bag PATH, --synthetic SEED or --live");
  }
  FillScenario(o.scenario_name, o.scenario_file, req.mutable_scenario());
  req.set_vo_method(o.vo_method);
  req.set_playback_rate(o.rate);
  req.set_history_size(o.history);
  req.mutable_noise()->set_fixed_vo_noise(o.fixed_vo_noise);
  req.mutable_noise()->set_fixed_gps_noise(o.fixed_gps_noise);
  return req;
}

void FillScenario(const std::string& name, const std::string& file, v1::Scenario* out) {
  auto ends_with = [&name](const char* tail) {
    const std::string t(tail);
    return name.size() >= t.size() && name.compare(name.size() - t.size(), t.size(), t) == 0;
  };
  if (!file.empty()) {
    out->set_yaml(ReadFile(file));
  } else if (ends_with(".yaml") || ends_with(".yml") || name.find('/') != std::string::npos) {
    out->set_yaml(ReadFile(name));
  } else if (!name.empty()) {
    out->set_name(name);
  }
}

}  // namespace locaid::clients
