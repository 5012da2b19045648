// The fixture of the GStreamer camera session tests: the real
// locaid-server, the real `locaid session start --live` flags, camera_info
// files written by clients/kitti_camera_info.py from the real excerpt's
// calibration, and multifilesrc playing the excerpt's raw images in place of
// cameras (no hardware). Skips when ../shared's excerpt is absent.
#pragma once

#include "test_support.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace locaid::server::testing {

namespace fs = std::filesystem;

inline const fs::path kDate = fs::path(LOCAID_SHARED_DATA) / "raw/2011_09_26";
inline const fs::path kDrive = kDate / "2011_09_26_drive_unknown_extract";
// Frames 24.. : the excerpt lacks left frame 23 and right frame 22, and
// multifilesrc ends at a missing file.
constexpr int kFirst = 24;

// A camera: the raw images of one side in `images` (default the excerpt's),
// `frames` of them from `first`, at `framerate` frames per second (a
// GStreamer fraction, "N/D").
inline std::string Play(const std::string& side, int frames, const std::string& framerate = "10/1",
                        bool loop = false, const fs::path& images = kDrive, int first = kFirst) {
  return "multifilesrc location=" + (images / side / "data/%010d.png").string() + " index=" +
         std::to_string(first) + " stop-index=" + std::to_string(first + frames - 1) +
         (loop ? " loop=true" : "") + " caps=image/png,framerate=" + framerate + " ! pngdec";
}

class CameraSession : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::exists(kDrive / "image_00")) GTEST_SKIP() << "shared real KITTI excerpt absent: " << kDrive;
    const auto r = RunShell("python3 " + ShellQuote(std::string(LOCAID_SOURCE_DIR) + "/clients/kitti_camera_info.py") +
                            " " + ShellQuote((kDate / "calib_cam_to_cam.txt").string()) + " " +
                            ShellQuote(dir_.path().string()));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    server_ = std::make_unique<ServerProcess>(dir_ / "server");
    ASSERT_GT(server_->port(), 0) << server_->log();
  }

  // `locaid session start --live ...`: the session id, or "" with `error`.
  std::string Start(const std::vector<std::string>& camera_flags, std::string* error = nullptr,
                    const std::string& left_info = "", const std::string& right_info = "") {
    std::vector<std::string> args = {"session", "start", "--live"};
    args.insert(args.end(), camera_flags.begin(), camera_flags.end());
    args.insert(args.end(), {"--camera-info-left", left_info.empty() ? (dir_ / "left.yaml").string() : left_info,
                             "--camera-info-right", right_info.empty() ? (dir_ / "right.yaml").string() : right_info});
    const CliResult r = RunCli(server_->port(), args);
    if (error) *error = r.err;
    if (r.exit_code != 0) return "";
    std::string id = r.out;
    id.erase(std::remove(id.begin(), id.end(), '\n'), id.end());
    return id;
  }

  std::unique_ptr<v1::Localization::Stub> Stub() { return v1::Localization::NewStub(server_->NewChannel()); }

  ScopedTempDir dir_{"camera_session"};
  std::unique_ptr<ServerProcess> server_;
};

}  // namespace locaid::server::testing
