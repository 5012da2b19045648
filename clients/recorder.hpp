// How `locaid subscribe` writes a pose stream to a file (print, CSV, TUM,
// KITTI, GeoJSON, MCAP): each pose goes to the file as it arrives, and a
// failed write leaves the file valid up to the last complete pose.
#pragma once

#include "output/enum_names.hpp"
#include "output/mcap_recording.hpp"
#include "locaid/v1/localization.pb.h"

#include <Eigen/Geometry>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>

#include <fcntl.h>
#include <unistd.h>

namespace locaid::clients {

namespace v1 = locaid::v1;

using output::ModeName;  // every format names the modes as the proto does

// Column list shared with clients/python/locaid_client.py (CSV_COLUMNS).
inline const char* kCsvHeader =
    "t_s,frame_index,sequence,e_m,n_m,u_m,lat_deg,lon_deg,alt_m,qw,qx,qy,qz,ve_mps,vn_mps,vu_mps,"
    "sigma_e_m,sigma_n_m,sigma_u_m,mode,seconds_since_gps,vo_inliers,gps_used,gps_rejected,"
    "gps_outage,processing_latency_ms,delay_ms,dropped,gps_resets,smoothed,vo_health";

// Thrown when the record file cannot be written (disk full, file size
// limit, I/O error). The file has already been cut back to the last complete
// pose and is valid.
class RecordError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Every record is written with write(2) straight to the file (no user-space
// buffer), so a killed client leaves a valid file up to the last pose. When a
// write fails (ENOSPC, EFBIG, EIO ...), the partial record is cut off with
// ftruncate and, for GeoJSON, the closing brackets are put back, so the file
// stays valid up to the last complete pose; then RecordError names the file,
// the errno text and the number of poses kept.
class Recorder {
 public:
  Recorder(const std::string& format, const std::string& path) : format_(format), path_(path) {
    if (format_ == "print") return;
    if (path.empty()) throw std::runtime_error("--out is required for --format " + format_);
    fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd_ < 0) throw std::runtime_error("cannot write '" + path + "': " + std::strerror(errno));
    if (format_ == "csv") Append(std::string(kCsvHeader) + "\n", "the CSV header");
    if (format_ == "geojson") {
      static const std::string kHead = "{\"type\":\"FeatureCollection\",\"features\":[";
      Append(kHead + kGeoJsonTail, "the GeoJSON header");
      committed_ = kHead.size();  // features are written from here on, before the tail
    }
  }
  ~Recorder() {
    if (fd_ >= 0) ::close(fd_);
  }
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  uint64_t poses() const { return poses_; }

  // Closes the file; throws RecordError if the kernel reports a late error.
  void Close() {
    if (fd_ < 0) return;
    const int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0) Throw(errno, "closing the file");
  }

  // A pose's time in seconds to the nanosecond, as its t_ns holds it (12
  // digits of Unix seconds, as written before, kept 10 ms).
  static std::string Seconds(int64_t t_ns) {
    const bool negative = t_ns < 0;
    const uint64_t a = negative ? 0 - static_cast<uint64_t>(t_ns) : static_cast<uint64_t>(t_ns);
    char buf[32];
    std::snprintf(buf, sizeof buf, "%s%llu.%09llu", negative ? "-" : "",
                  static_cast<unsigned long long>(a / 1000000000), static_cast<unsigned long long>(a % 1000000000));
    return buf;
  }

  void Add(const v1::PoseUpdate& p, double delay_ms) {
    const auto& t = p.position_enu_m();
    const auto& q = p.orientation_enu_body();
    const double t_s = static_cast<double>(p.t_ns()) * 1e-9;
    if (format_ == "print") {
      std::cout << std::fixed << std::setprecision(3) << "seq=" << p.sequence() << " t=" << t_s << " enu=("
                << t.x() << "," << t.y() << "," << t.z() << ") lat=" << std::setprecision(7) << p.latitude_deg()
                << " lon=" << p.longitude_deg() << std::setprecision(3) << " mode=" << ModeName(p.mode())
                << " since_gps=" << p.seconds_since_gps() << " inliers=" << p.vo_inliers()
                << " vo_health=" << output::VoHealthName(p.vo_health())
                << " latency_ms=" << p.processing_latency_ms() << " delay_ms=" << delay_ms
                << " dropped=" << p.dropped_for_subscriber() << " smoothed=" << (p.smoothed() ? 1 : 0) << "\n"
                << std::defaultfloat << std::flush;
      if (!std::cout) {
        throw RecordError("writing pose " + std::to_string(poses_ + 1) + " to standard output failed (" +
                          std::strerror(errno) + "); " + std::to_string(poses_) + " poses were printed");
      }
      ++poses_;
      return;
    }
    std::ostringstream out;
    out << std::setprecision(12);
    const Eigen::Quaterniond quat(q.w(), q.x(), q.y(), q.z());
    const Eigen::Matrix3d R = quat.normalized().toRotationMatrix();
    if (format_ == "tum") {
      out << Seconds(p.t_ns()) << " " << t.x() << " " << t.y() << " " << t.z() << " " << q.x() << " " << q.y() << " " << q.z()
          << " " << q.w() << "\n";
    } else if (format_ == "kitti") {
      for (int r = 0; r < 3; ++r) {
        out << (r ? " " : "") << R(r, 0) << " " << R(r, 1) << " " << R(r, 2) << " "
            << (r == 0 ? t.x() : r == 1 ? t.y() : t.z());
      }
      out << "\n";
    } else if (format_ == "csv") {
      auto sigma = [&](int i) {
        return p.covariance_size() == 36 ? std::sqrt(std::max(0.0, p.covariance(i * 6 + i))) : NAN;
      };
      out << Seconds(p.t_ns()) << "," << p.frame_index() << "," << p.sequence() << "," << t.x() << "," << t.y() << "," << t.z()
          << "," << p.latitude_deg() << "," << p.longitude_deg() << "," << p.altitude_m() << "," << q.w() << ","
          << q.x() << "," << q.y() << "," << q.z() << "," << p.velocity_enu_mps().x() << ","
          << p.velocity_enu_mps().y() << "," << p.velocity_enu_mps().z() << "," << sigma(0) << "," << sigma(1)
          << "," << sigma(2) << "," << ModeName(p.mode()) << "," << p.seconds_since_gps() << ","
          << p.vo_inliers() << "," << p.gps_used() << "," << p.gps_rejected() << ","
          << (p.gps_outage_active() ? 1 : 0) << "," << p.processing_latency_ms() << "," << delay_ms << ","
          << p.dropped_for_subscriber() << "," << p.gps_resets() << "," << (p.smoothed() ? 1 : 0) << ","
          << output::VoHealthName(p.vo_health()) << "\n";
    } else if (format_ == "geojson") {
      // The feature overwrites the closing brackets and brings them back.
      out << (poses_ ? "," : "") << "{\"type\":\"Feature\",\"geometry\":{\"type\":\"Point\",\"coordinates\":["
          << std::setprecision(10) << p.longitude_deg() << "," << p.latitude_deg() << "," << p.altitude_m()
          << "]},\"properties\":{\"t_s\":" << Seconds(p.t_ns()) << ",\"sequence\":" << p.sequence()
          << ",\"mode\":\"" << ModeName(p.mode()) << "\"}}";
      const std::string feature = out.str();
      Append(feature + kGeoJsonTail, "pose " + std::to_string(poses_ + 1));
      committed_ += feature.size();  // the tail stays after it
      ++poses_;
      return;
    }
    Append(out.str(), "pose " + std::to_string(poses_ + 1));
    ++poses_;
  }

 private:
  static constexpr const char* kGeoJsonTail = "]}\n";

  // Writes `bytes` at offset committed_ (the end of the last complete
  // record). Line formats move committed_ past them; GeoJSON moves it itself.
  void Append(const std::string& bytes, const std::string& what) {
    size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::pwrite(fd_, bytes.data() + done, bytes.size() - done,
                                 static_cast<off_t>(committed_ + done));
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        const int err = n < 0 ? errno : EIO;
        Rollback();
        Throw(err, "writing " + what);
      }
      done += static_cast<size_t>(n);
    }
    if (format_ != "geojson") committed_ += bytes.size();
  }

  // Cuts the file back to the last complete record (GeoJSON: and its closing
  // brackets, which were in the file before, so no new space is needed).
  void Rollback() {
    off_t keep = static_cast<off_t>(committed_);
    if (format_ == "geojson" && committed_ > 0) {
      const std::string tail = kGeoJsonTail;
      if (::pwrite(fd_, tail.data(), tail.size(), keep) == static_cast<ssize_t>(tail.size())) {
        keep += static_cast<off_t>(tail.size());
      } else {
        keep = 0;  // cannot close the document: leave an empty file rather than invalid JSON
      }
    }
    if (::ftruncate(fd_, keep) != 0) rollback_error_ = errno;
  }

  [[noreturn]] void Throw(int err, const std::string& what) {
    std::ostringstream msg;
    msg << "recording to '" << path_ << "' failed while " << what << ": " << std::strerror(err) << " ("
        << (err == ENOSPC ? "ENOSPC" : err == EFBIG ? "EFBIG" : err == EIO ? "EIO" : "errno " + std::to_string(err))
        << "); kept " << poses_ << " complete pose" << (poses_ == 1 ? "" : "s");
    if (rollback_error_ != 0) {
      msg << ", but cutting off the partial record failed: " << std::strerror(rollback_error_)
          << " (the last line may be incomplete)";
    } else {
      msg << ", the file ends with the last complete pose";
    }
    throw RecordError(msg.str());
  }

  std::string format_, path_;
  int fd_ = -1;
  uint64_t committed_ = 0;  // bytes of complete records (GeoJSON: before the closing brackets)
  uint64_t poses_ = 0;
  int rollback_error_ = 0;
};

}  // namespace locaid::clients
