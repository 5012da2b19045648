#include "clients/cli_print.hpp"

#include <iostream>

namespace locaid::clients {

namespace v1 = locaid::v1;

const char* StateName(v1::SessionState s) {
  switch (s) {
    case v1::SESSION_STATE_STARTING: return "STARTING";
    case v1::SESSION_STATE_RUNNING: return "RUNNING";
    case v1::SESSION_STATE_FINISHED: return "FINISHED";
    case v1::SESSION_STATE_STOPPED: return "STOPPED";
    case v1::SESSION_STATE_FAILED: return "FAILED";
    default: return "UNSPECIFIED";
  }
}

void PrintSession(const v1::Session& s) {
  std::cout << s.id() << " " << StateName(s.state()) << " source=" << s.source() << " vo=" << s.vo_method()
            << " scenario=" << s.scenario() << " rate=" << s.playback_rate()
            << " frames=" << s.stats().frames_processed() << "/" << s.total_frames()
            << " subscribers=" << s.stats().subscribers();
  if (!s.error().empty()) std::cout << " error=\"" << s.error() << "\"";
  std::cout << "\n";
}

void PrintStats(const v1::SessionStats& s) {
  std::cout << "frames_in " << s.frames_in() << "\nframes_processed " << s.frames_processed()
            << "\nframes_skipped " << s.frames_skipped() << "\nframes_corrupt " << s.frames_corrupt()
            << "\noxts_bad_lines " << s.oxts_bad_lines() << "\nfps " << s.fps() << "\nlatency_mean_ms "
            << s.latency_mean_ms() << "\nlatency_max_ms " << s.latency_max_ms() << "\nposes_published "
            << s.poses_published() << "\nsubscribers " << s.subscribers() << "\ndropped_total "
            << s.dropped_total() << "\nrealtime_factor " << s.realtime_factor() << "\nbehind_real_time_s "
            << s.behind_real_time_s() << "\nbehind_real_time_max_s " << s.behind_real_time_max_s()
            << "\nfalling_behind " << (s.falling_behind() ? "true" : "false") << "\ncpu_cores " << s.cpu_cores()
            << "\n";
  if (!s.last_input_error().empty()) std::cout << "last_input_error " << s.last_input_error() << "\n";
  if (s.imu_samples() + s.gps_fixes_in() + s.sensor_items_rejected() > 0) {
    std::cout << "imu_samples " << s.imu_samples() << "\ngps_fixes_in " << s.gps_fixes_in() << "\ngps_fixes_late "
              << s.gps_fixes_late() << "\ngps_no_fix " << s.gps_no_fix() << "\nsensor_items_rejected "
              << s.sensor_items_rejected() << "\n";
  }
  if (s.has_gpsd()) {
    const auto& g = s.gpsd();
    std::cout << "gpsd connected=" << (g.connected() ? "true" : "false") << " connects=" << g.connects()
              << " connection_losses=" << g.connection_losses() << " fix_latency_median_ms="
              << g.fix_latency_median_ms() << " fix_latency_max_ms=" << g.fix_latency_max_ms() << "\n";
    if (!g.last_error().empty()) std::cout << "gpsd_last_error " << g.last_error() << "\n";
  }
  if (s.has_camera()) {
    const auto& c = s.camera();
    std::cout << "camera running=" << (c.running() ? "true" : "false") << " pairs=" << c.pairs()
              << " unpaired=" << c.unpaired() << " dropped_late=" << c.dropped_late() << " restarts=" << c.restarts()
              << "\n";
    if (!c.last_error().empty()) std::cout << "camera_last_error " << c.last_error() << "\n";
  }
  if (s.has_noise()) {
    const auto& n = s.noise();
    std::cout << "noise vo_scale=";
    for (int i = 0; i < n.vo_scale_size(); ++i) std::cout << (i ? "," : "") << n.vo_scale(i);
    std::cout << " gps_horizontal_scale=" << n.gps_horizontal_scale()
              << " gps_vertical_scale=" << n.gps_vertical_scale()
              << " vo_learning=" << (n.vo_learning() ? "true" : "false") << "\n";
  }
  for (const auto& sub : s.subscriber()) {
    std::cout << "subscriber " << sub.id() << " peer=" << sub.peer() << " delivered=" << sub.delivered()
              << " dropped=" << sub.dropped() << " queued=" << sub.queued() << "\n";
  }
}

}  // namespace locaid::clients
