#include "server/boot_session.hpp"

#include "connection/host_port.hpp"

#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <utility>


namespace locaid::server {
namespace {

std::string ReadText(const std::string& path, const char* key) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(std::string("live_cameras.") + key + " '" + path + "': " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace

locaid::v1::StartSessionRequest BootCamerasRequest(const BootCameras& boot) {
  locaid::v1::StartSessionRequest req;
  locaid::v1::LiveSource* live = req.mutable_live();
  locaid::v1::CameraSource* c = live->mutable_cameras();
  c->set_left_pipeline(boot.left_pipeline);
  c->set_right_pipeline(boot.right_pipeline);
  c->set_stereo_pipeline(boot.stereo_pipeline);
  c->set_left_camera_info(ReadText(boot.left_camera_info, "left_camera_info"));
  c->set_right_camera_info(ReadText(boot.right_camera_info, "right_camera_info"));
  c->set_pair_tolerance_ms(boot.pair_tolerance_ms);
  c->set_stall_timeout_s(boot.stall_timeout_s);
  live->set_no_imu(boot.no_imu);
  if (!boot.gpsd.empty()) {
    const connection::HostPort gpsd = connection::SplitHostPort(boot.gpsd, "live_cameras.gpsd");
    locaid::v1::GpsdSource* g = live->mutable_gps_source()->mutable_gpsd();
    g->set_host(gpsd.host);
    g->set_port(gpsd.port);
  }
  if (!boot.scenario.empty()) req.mutable_scenario()->set_name(boot.scenario);
  return req;
}

BootSession::BootSession(BootCameras boot, Starter start, std::function<void(const std::string&)> log)
    : boot_(std::move(boot)), start_(std::move(start)), log_(std::move(log)), thread_([this] { Run(); }) {}

BootSession::~BootSession() {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void BootSession::Run() {
  std::string last_reason;
  for (;;) {
    std::string reason;
    try {
      std::string id;
      const grpc::Status s = start_(BootCamerasRequest(boot_), &id);
      if (s.ok()) {
        log_("live camera session " + id + " started (live_cameras)");
        return;
      }
      reason = s.error_message();
    } catch (const std::exception& e) {
      reason = e.what();
    }
    if (reason != last_reason) log_("live_cameras: cannot start yet, retrying every 5 s: " + reason);
    last_reason = reason;
    std::unique_lock lock(mu_);
    if (cv_.wait_for(lock, std::chrono::duration<double>(kRetryS), [this] { return stop_; })) return;
  }
}

}  // namespace locaid::server
