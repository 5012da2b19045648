#include "fusion/geodesy.hpp"

#include <GeographicLib/LocalCartesian.hpp>

#include <stdexcept>

namespace locaid::fusion {

EnuFrame::EnuFrame() : lc_(std::make_unique<GeographicLib::LocalCartesian>()) {}
EnuFrame::~EnuFrame() = default;
EnuFrame::EnuFrame(const EnuFrame& o)
    : lc_(std::make_unique<GeographicLib::LocalCartesian>(*o.lc_)),
      has_origin_(o.has_origin_), lat0_(o.lat0_), lon0_(o.lon0_), alt0_(o.alt0_) {}
EnuFrame& EnuFrame::operator=(const EnuFrame& o) {
  if (this != &o) {
    *lc_ = *o.lc_;
    has_origin_ = o.has_origin_;
    lat0_ = o.lat0_; lon0_ = o.lon0_; alt0_ = o.alt0_;
  }
  return *this;
}

void EnuFrame::SetOrigin(double lat_deg, double lon_deg, double alt_m) {
  lc_->Reset(lat_deg, lon_deg, alt_m);
  lat0_ = lat_deg; lon0_ = lon_deg; alt0_ = alt_m;
  has_origin_ = true;
}

Eigen::Vector3d EnuFrame::ToEnu(double lat_deg, double lon_deg, double alt_m) const {
  if (!has_origin_) throw std::logic_error("EnuFrame::ToEnu: no origin set");
  Eigen::Vector3d p;
  lc_->Forward(lat_deg, lon_deg, alt_m, p.x(), p.y(), p.z());
  return p;
}

void EnuFrame::ToGeodetic(const Eigen::Vector3d& p, double& lat_deg, double& lon_deg,
                          double& alt_m) const {
  if (!has_origin_) throw std::logic_error("EnuFrame::ToGeodetic: no origin set");
  lc_->Reverse(p.x(), p.y(), p.z(), lat_deg, lon_deg, alt_m);
}

}  // namespace locaid::fusion
