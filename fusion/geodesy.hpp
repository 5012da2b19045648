// Geodetic <-> local ENU (GeographicLib::LocalCartesian), origin at the first fix.
#pragma once

#include <Eigen/Core>

#include <memory>

namespace GeographicLib { class LocalCartesian; }

namespace locaid::fusion {

class EnuFrame {
 public:
  EnuFrame();
  ~EnuFrame();
  EnuFrame(const EnuFrame&);
  EnuFrame& operator=(const EnuFrame&);

  void SetOrigin(double lat_deg, double lon_deg, double alt_m);
  bool has_origin() const { return has_origin_; }
  // Both throw std::logic_error before SetOrigin.
  Eigen::Vector3d ToEnu(double lat_deg, double lon_deg, double alt_m) const;
  void ToGeodetic(const Eigen::Vector3d& p_enu_m, double& lat_deg, double& lon_deg,
                  double& alt_m) const;
  double origin_lat_deg() const { return lat0_; }
  double origin_lon_deg() const { return lon0_; }
  double origin_alt_m() const { return alt0_; }

 private:
  std::unique_ptr<GeographicLib::LocalCartesian> lc_;
  bool has_origin_ = false;
  double lat0_ = 0, lon0_ = 0, alt0_ = 0;
};

}  // namespace locaid::fusion
