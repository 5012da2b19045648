// libFuzzer target: OXTS record lines and files (kitti/oxts.hpp).
// Contract: ParseOxtsLine / ReadOxtsFile return a record or throw kitti::Error;
// a parsed record survives WriteOxtsLine -> ParseOxtsLine bit for bit.
#include "fuzz/fuzz_support.hpp"
#include "kitti/oxts.hpp"

#include <cmath>
#include <cstring>

namespace {

using locaid::kitti::OxtsRecord;

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

void CheckRoundTrip(const OxtsRecord& r) {
  const std::string line = locaid::kitti::WriteOxtsLine(r);
  OxtsRecord back;
  try {
    back = locaid::kitti::ParseOxtsLine(line, "round-trip");
  } catch (const locaid::kitti::Error& e) {
    locaid::fuzz::Fail(std::string("written line does not parse: ") + e.what() + " | " + line);
  }
  const double a[] = {r.lat_deg, r.lon_deg, r.alt_m, r.roll_rad, r.pitch_rad, r.yaw_rad,
                      r.vn_mps, r.ve_mps, r.vf_mps, r.vl_mps, r.vu_mps, r.ax_mps2, r.ay_mps2,
                      r.az_mps2, r.af_mps2, r.al_mps2, r.au_mps2, r.wx_radps, r.wy_radps,
                      r.wz_radps, r.wf_radps, r.wl_radps, r.wu_radps, r.pos_accuracy_m,
                      r.vel_accuracy_mps};
  const double b[] = {back.lat_deg, back.lon_deg, back.alt_m, back.roll_rad, back.pitch_rad,
                      back.yaw_rad, back.vn_mps, back.ve_mps, back.vf_mps, back.vl_mps,
                      back.vu_mps, back.ax_mps2, back.ay_mps2, back.az_mps2, back.af_mps2,
                      back.al_mps2, back.au_mps2, back.wx_radps, back.wy_radps, back.wz_radps,
                      back.wf_radps, back.wl_radps, back.wu_radps, back.pos_accuracy_m,
                      back.vel_accuracy_mps};
  for (size_t i = 0; i < sizeof a / sizeof a[0]; ++i) {
    LOCAID_FUZZ_CHECK(std::isfinite(a[i]), "parsed field " + std::to_string(i) + " not finite");
    LOCAID_FUZZ_CHECK(SameBits(a[i], b[i]), "field " + std::to_string(i) + " changed: " + line);
  }
  LOCAID_FUZZ_CHECK(r.lat_deg >= -90 && r.lat_deg <= 90, "lat out of range");
  LOCAID_FUZZ_CHECK(r.lon_deg >= -180 && r.lon_deg <= 180, "lon out of range");
  LOCAID_FUZZ_CHECK(r.navstat == back.navstat && r.numsats == back.numsats &&
                        r.posmode == back.posmode && r.velmode == back.velmode &&
                        r.orimode == back.orimode,
                    "integer field changed: " + line);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static locaid::fuzz::MemFile file;
  const std::string_view text = locaid::fuzz::AsText(data, size);
  try {
    CheckRoundTrip(locaid::kitti::ParseOxtsLine(text, "fuzz"));
  } catch (const locaid::kitti::Error&) {
  }
  try {
    CheckRoundTrip(locaid::kitti::ReadOxtsFile(file.Write(text)));
  } catch (const locaid::kitti::Error&) {
  }
  return 0;
}
