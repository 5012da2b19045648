#include "kitti/oxts.hpp"

#include "kitti/parse_number.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <vector>

namespace locaid::kitti {
namespace {

// Pointers to the 25 double fields of a record, in file order.
std::array<double*, 25> DoubleFields(OxtsRecord& r) {
  return {&r.lat_deg,  &r.lon_deg,   &r.alt_m,   &r.roll_rad, &r.pitch_rad,
          &r.yaw_rad,  &r.vn_mps,    &r.ve_mps,  &r.vf_mps,   &r.vl_mps,
          &r.vu_mps,   &r.ax_mps2,   &r.ay_mps2, &r.az_mps2,  &r.af_mps2,
          &r.al_mps2,  &r.au_mps2,   &r.wx_radps, &r.wy_radps, &r.wz_radps,
          &r.wf_radps, &r.wl_radps,  &r.wu_radps, &r.pos_accuracy_m,
          &r.vel_accuracy_mps};
}
std::array<int*, 5> IntFields(OxtsRecord& r) {
  return {&r.navstat, &r.numsats, &r.posmode, &r.velmode, &r.orimode};
}

std::vector<std::string_view> SplitWs(std::string_view s) {
  std::vector<std::string_view> out;
  size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t' || s[i] == '\r' || s[i] == '\n')) ++i;
    size_t j = i;
    while (j < s.size() && !(s[j] == ' ' || s[j] == '\t' || s[j] == '\r' || s[j] == '\n')) ++j;
    if (j > i) out.push_back(s.substr(i, j - i));
    i = j;
  }
  return out;
}

std::string FieldLabel(int i) {
  return "field " + std::to_string(i + 1) + " (" + std::string(OxtsFieldNames()[i]) + ")";
}

}  // namespace

const std::array<std::string_view, kOxtsFieldCount>& OxtsFieldNames() {
  static const std::array<std::string_view, kOxtsFieldCount> names = {
      "lat", "lon", "alt", "roll", "pitch", "yaw", "vn", "ve", "vf", "vl",
      "vu", "ax", "ay", "az", "af", "al", "au", "wx", "wy", "wz",
      "wf", "wl", "wu", "pos_accuracy", "vel_accuracy", "navstat", "numsats",
      "posmode", "velmode", "orimode"};
  return names;
}

OxtsRecord ParseOxtsLine(std::string_view line, const std::string& where) {
  const auto tokens = SplitWs(line);
  if (static_cast<int>(tokens.size()) != kOxtsFieldCount) {
    throw Error(where + ": " + std::to_string(tokens.size()) + " fields, expected " +
                std::to_string(kOxtsFieldCount));
  }
  std::array<double, kOxtsFieldCount> v{};
  for (int i = 0; i < kOxtsFieldCount; ++i) {
    std::string why;
    if (!ParseFiniteDouble(tokens[i], v[i], why)) {
      throw Error(where + ": " + FieldLabel(i) + " " + why + ": '" + std::string(tokens[i]) + "'");
    }
  }
  if (v[0] < -90.0 || v[0] > 90.0) {
    throw Error(where + ": " + FieldLabel(0) + " = " + std::string(tokens[0]) +
                " outside [-90, 90] deg");
  }
  if (v[1] < -180.0 || v[1] > 180.0) {
    throw Error(where + ": " + FieldLabel(1) + " = " + std::string(tokens[1]) +
                " outside [-180, 180] deg");
  }
  OxtsRecord r;
  auto doubles = DoubleFields(r);
  for (size_t i = 0; i < doubles.size(); ++i) *doubles[i] = v[i];
  auto ints = IntFields(r);
  for (size_t k = 0; k < ints.size(); ++k) {
    const int i = static_cast<int>(doubles.size() + k);
    if (v[i] != std::floor(v[i]) || std::fabs(v[i]) > 1e9) {
      throw Error(where + ": " + FieldLabel(i) + " must be an integer: '" +
                  std::string(tokens[i]) + "'");
    }
    *ints[k] = static_cast<int>(v[i]);
  }
  return r;
}

OxtsRecord ReadOxtsFile(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw Error(path.string() + ": cannot open OXTS file");
  std::string line, data_line;
  int line_no = 0, data_line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (SplitWs(line).empty()) continue;
    if (data_line_no != 0) {
      throw Error(path.string() + ":" + std::to_string(line_no) +
                  ": more than one record line in an OXTS file");
    }
    data_line = line;
    data_line_no = line_no;
  }
  if (data_line_no == 0) throw Error(path.string() + ":1: empty OXTS file");
  return ParseOxtsLine(data_line, path.string() + ":" + std::to_string(data_line_no));
}

std::string WriteOxtsLine(const OxtsRecord& r_in) {
  OxtsRecord r = r_in;
  std::string out;
  char buf[64];
  for (double* d : DoubleFields(r)) {
    std::snprintf(buf, sizeof buf, "%.17g", *d);
    if (!out.empty()) out += ' ';
    out += buf;
  }
  for (int* i : IntFields(r)) {
    out += ' ';
    out += std::to_string(*i);
  }
  return out;
}

}  // namespace locaid::kitti
