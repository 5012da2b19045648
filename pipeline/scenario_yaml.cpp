#include "pipeline/scenario_yaml.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

namespace locaid::pipeline {
namespace {

struct Ctx {
  std::string where;
  [[noreturn]] void Fail(const YAML::Node& node, const std::string& field, const std::string& why) const {
    std::ostringstream os;
    os << where;
    if (node.IsDefined() && node.Mark().line >= 0) os << ":" << node.Mark().line + 1;
    os << ": field '" << field << "': " << why;
    throw ScenarioError(os.str());
  }
  void CheckKeys(const YAML::Node& map, const std::string& prefix,
                 const std::set<std::string>& allowed) const {
    if (!map.IsMap()) Fail(map, prefix.empty() ? "(root)" : prefix, "expected a mapping");
    for (const auto& kv : map) {
      // A mapping or list as a key ("{a: 1}: 2") has no string value.
      if (!kv.first.IsScalar()) Fail(kv.first, prefix.empty() ? "(root)" : prefix, "a key must be a plain name");
      const auto key = kv.first.as<std::string>();
      if (!allowed.count(key)) {
        std::string list;
        for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
        Fail(kv.first, prefix.empty() ? key : prefix + "." + key,
             "unknown key (allowed: " + list + ")");
      }
    }
  }
  double Number(const YAML::Node& n, const std::string& field) const {
    if (!n.IsScalar()) Fail(n, field, "expected a number");
    try {
      return n.as<double>();
    } catch (const YAML::Exception&) {
      Fail(n, field, "expected a number, got '" + n.Scalar() + "'");
    }
  }
  double NonNegative(const YAML::Node& n, const std::string& field) const {
    const double v = Number(n, field);
    if (!(v >= 0)) Fail(n, field, "must be >= 0, got " + n.Scalar());
    return v;
  }
  double Positive(const YAML::Node& n, const std::string& field) const {
    const double v = Number(n, field);
    if (!(v > 0)) Fail(n, field, "must be > 0, got " + n.Scalar());
    return v;
  }
  // The length of window `w` (entry `field`, a `what` starting at start_s):
  // its duration_s, or its end_s - start_s.
  double WindowDuration(const YAML::Node& w, const std::string& field, double start_s, const char* what) const {
    if (w["duration_s"] && w["end_s"]) Fail(w, field, "give duration_s or end_s, not both");
    if (w["duration_s"]) return Positive(w["duration_s"], field + ".duration_s");
    if (!w["end_s"]) Fail(w, field + ".duration_s", "missing (give duration_s or end_s)");
    const double end = Number(w["end_s"], field + ".end_s");
    if (!(end > start_s))
      Fail(w["end_s"], field + ".end_s", std::string(what) + " ends (" + w["end_s"].Scalar() +
                                             " s) before or at its start (" + std::to_string(start_s) + " s)");
    return end - start_s;
  }
};

// The `camera:` list: [{start_s, duration_s | end_s, fault, parameters of that fault}].
std::vector<sim::CameraFaultWindow> ParseCameraFaults(const Ctx& c, const YAML::Node& list) {
  using sim::CameraFaultKind;
  if (!list.IsSequence()) c.Fail(list, "camera", "expected a list of {start_s, duration_s | end_s, fault, ...}");
  const std::vector<std::pair<std::string, CameraFaultKind>> kinds = {
      {"dark", CameraFaultKind::kDark},         {"noise", CameraFaultKind::kNoise},
      {"blur", CameraFaultKind::kBlur},         {"frozen", CameraFaultKind::kFrozen},
      {"drop", CameraFaultKind::kDrop},         {"left_only", CameraFaultKind::kLeftOnly},
      {"right_only", CameraFaultKind::kRightOnly}};
  std::vector<sim::CameraFaultWindow> out;
  for (size_t i = 0; i < list.size(); ++i) {
    const std::string f = "camera[" + std::to_string(i) + "]";
    const YAML::Node w = list[i];
    if (!w.IsMap()) c.Fail(w, f, "expected a mapping {start_s, duration_s | end_s, fault, ...}");
    if (!w["fault"]) c.Fail(w, f + ".fault", "missing (dark, noise, blur, frozen, drop, left_only, right_only)");
    const std::string name = w["fault"].IsScalar() ? w["fault"].Scalar() : "";
    const auto kind = std::find_if(kinds.begin(), kinds.end(), [&](const auto& k) { return k.first == name; });
    if (kind == kinds.end())
      c.Fail(w["fault"], f + ".fault",
             "expected dark, noise, blur, frozen, drop, left_only or right_only, got '" + name + "'");
    sim::CameraFaultWindow win;
    win.kind = kind->second;
    // Parameters only for the faults they change.
    const std::vector<std::pair<std::string, std::set<CameraFaultKind>>> parameters = {
        {"gain", {CameraFaultKind::kDark}},
        {"noise_dn", {CameraFaultKind::kDark, CameraFaultKind::kNoise}},
        {"blur_sigma_px", {CameraFaultKind::kBlur}}};
    std::set<std::string> keys = {"start_s", "duration_s", "end_s", "fault"};
    for (const auto& [key, applies] : parameters) {
      if (applies.count(win.kind)) {
        keys.insert(key);
      } else if (w[key]) {
        c.Fail(w[key], f + "." + key, std::string("applies to ") + (key == "noise_dn" ? "dark and noise" :
                                      key == "gain" ? "dark" : "blur") + " faults, not to " + name);
      }
    }
    c.CheckKeys(w, f, keys);
    if (!w["start_s"]) c.Fail(w, f + ".start_s", "missing");
    win.start_s = c.NonNegative(w["start_s"], f + ".start_s");
    win.duration_s = c.WindowDuration(w, f, win.start_s, "fault");
    if (win.kind == CameraFaultKind::kNoise) win.noise_dn = 8;  // default of a noise fault (as the API's)
    if (w["gain"]) win.gain = c.Positive(w["gain"], f + ".gain");
    if (w["noise_dn"]) win.noise_dn = c.NonNegative(w["noise_dn"], f + ".noise_dn");
    if (w["blur_sigma_px"]) win.blur_sigma_px = c.Positive(w["blur_sigma_px"], f + ".blur_sigma_px");
    // Upper bounds (gain <= 1, noise <= 255, blur <= 50) with the line of the value.
    const std::string problem = sim::CameraFaultParameterProblem(win);
    if (!problem.empty()) {
      const std::string key = problem.substr(0, problem.find(':'));
      c.Fail(w[key], f + "." + key, problem.substr(key.size() + 2));
    }
    out.push_back(win);
  }
  return out;
}

// The `speed:` mapping: a simulated vehicle speed sensor.
sim::SpeedSensorSim ParseSpeedSensor(const Ctx& c, const YAML::Node& m) {
  c.CheckKeys(m, "speed", {"rate_hz", "sigma_mps", "scale_error"});
  sim::SpeedSensorSim sensor;
  if (m["rate_hz"]) sensor.rate_hz = c.Positive(m["rate_hz"], "speed.rate_hz");
  if (m["sigma_mps"]) sensor.sigma_mps = c.Positive(m["sigma_mps"], "speed.sigma_mps");
  if (m["scale_error"]) sensor.scale_error = c.Number(m["scale_error"], "speed.scale_error");
  return sensor;
}

}  // namespace

sim::Scenario ParseScenarioYaml(const std::string& text, const std::string& where) {
  const Ctx c{where};
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw ScenarioError(where + ":" + std::to_string(e.mark.line + 1) + ": YAML syntax: " + e.msg);
  }
  if (!root.IsDefined() || root.IsNull()) throw ScenarioError(where + ": empty scenario file");
  c.CheckKeys(root, "", {"name", "base", "gps", "imu", "outages", "camera", "speed", "seed"});
  sim::Scenario s;
  if (root["base"]) {
    if (!root["base"].IsScalar()) c.Fail(root["base"], "base", "expected a built-in scenario name");
    try {
      s = sim::BuiltinScenario(root["base"].Scalar());
    } catch (const std::invalid_argument& e) {
      c.Fail(root["base"], "base", e.what());
    }
  }
  s.name = std::filesystem::path(where).stem().string();
  if (root["name"]) {
    if (!root["name"].IsScalar()) c.Fail(root["name"], "name", "expected a string");
    s.name = root["name"].Scalar();
  }
  if (const auto g = root["gps"]) {
    c.CheckKeys(g, "gps", {"rate_hz", "sigma_h_m", "sigma_v_m", "bias_sigma_m", "bias_tau_s",
                           "jump_probability", "jump_size_m", "jump_duration_s", "antenna_body_m", "measured",
                           "stated_sigma_scale"});
    if (g["measured"]) {
      const std::string m = g["measured"].IsScalar() ? g["measured"].Scalar() : "";
      if (m == "as-recorded") s.degrade_measured_gps = false;
      else if (m == "degraded") s.degrade_measured_gps = true;
      else c.Fail(g["measured"], "gps.measured", "expected 'as-recorded' or 'degraded', got '" + m + "'");
    }
    if (g["antenna_body_m"]) {
      const auto a = g["antenna_body_m"];
      if (!a.IsSequence() || a.size() != 3) c.Fail(a, "gps.antenna_body_m", "expected [x, y, z] in metres (body frame)");
      for (int i = 0; i < 3; ++i) s.gps_antenna_body_m[i] = c.Number(a[i], "gps.antenna_body_m");
    }
    if (g["rate_hz"]) s.gps_rate_hz = c.Positive(g["rate_hz"], "gps.rate_hz");
    if (g["sigma_h_m"]) s.gps_sigma_h_m = c.NonNegative(g["sigma_h_m"], "gps.sigma_h_m");
    if (g["sigma_v_m"]) s.gps_sigma_v_m = c.NonNegative(g["sigma_v_m"], "gps.sigma_v_m");
    if (g["bias_sigma_m"]) s.gps_bias_sigma_m = c.NonNegative(g["bias_sigma_m"], "gps.bias_sigma_m");
    if (g["bias_tau_s"]) s.gps_bias_tau_s = c.Positive(g["bias_tau_s"], "gps.bias_tau_s");
    if (g["stated_sigma_scale"]) s.gps_stated_sigma_scale = c.Positive(g["stated_sigma_scale"], "gps.stated_sigma_scale");
    if (g["jump_probability"]) {
      s.jump_probability = c.NonNegative(g["jump_probability"], "gps.jump_probability");
      if (s.jump_probability > 1)
        c.Fail(g["jump_probability"], "gps.jump_probability", "must be in [0, 1], got " + g["jump_probability"].Scalar());
    }
    if (g["jump_size_m"]) s.jump_size_m = c.NonNegative(g["jump_size_m"], "gps.jump_size_m");
    if (g["jump_duration_s"]) s.jump_duration_s = c.NonNegative(g["jump_duration_s"], "gps.jump_duration_s");
  }
  if (const auto m = root["imu"]) {
    c.CheckKeys(m, "imu", {"grade", "accel_bias_sigma_mps2", "gyro_bias_sigma_radps",
                           "accel_noise_mps2_sqrt_hz", "gyro_noise_radps_sqrt_hz"});
    if (m["grade"]) {
      const std::string g = m["grade"].IsScalar() ? m["grade"].Scalar() : "";
      if (g == "as-recorded") s.imu_grade = sim::ImuGrade::kAsRecorded;
      else if (g == "mems") s.imu_grade = sim::ImuGrade::kMems;
      else c.Fail(m["grade"], "imu.grade", "expected 'as-recorded' or 'mems', got '" + g + "'");
    }
    if (m["accel_bias_sigma_mps2"]) s.imu_accel_bias_sigma_mps2 = c.NonNegative(m["accel_bias_sigma_mps2"], "imu.accel_bias_sigma_mps2");
    if (m["gyro_bias_sigma_radps"]) s.imu_gyro_bias_sigma_radps = c.NonNegative(m["gyro_bias_sigma_radps"], "imu.gyro_bias_sigma_radps");
    if (m["accel_noise_mps2_sqrt_hz"]) s.imu_accel_noise_mps2_sqrt_hz = c.NonNegative(m["accel_noise_mps2_sqrt_hz"], "imu.accel_noise_mps2_sqrt_hz");
    if (m["gyro_noise_radps_sqrt_hz"]) s.imu_gyro_noise_radps_sqrt_hz = c.NonNegative(m["gyro_noise_radps_sqrt_hz"], "imu.gyro_noise_radps_sqrt_hz");
  }
  if (const auto o = root["outages"]) {
    if (!o.IsSequence()) c.Fail(o, "outages", "expected a list of {start_s, duration_s | end_s}");
    s.outages.clear();
    for (size_t i = 0; i < o.size(); ++i) {
      const std::string f = "outages[" + std::to_string(i) + "]";
      const auto w = o[i];
      c.CheckKeys(w, f, {"start_s", "duration_s", "end_s", "centered"});
      sim::OutageWindow win;
      if (!w["start_s"] && !w["centered"]) c.Fail(w, f + ".start_s", "missing");
      if (w["start_s"]) win.start_s = c.NonNegative(w["start_s"], f + ".start_s");
      if (w["centered"]) {
        try { win.centered = w["centered"].as<bool>(); }
        catch (const YAML::Exception&) { c.Fail(w["centered"], f + ".centered", "expected true or false"); }
      }
      win.duration_s = c.WindowDuration(w, f, win.start_s, "outage");
      s.outages.push_back(win);
    }
  }
  if (root["camera"]) s.camera_faults = ParseCameraFaults(c, root["camera"]);
  if (root["speed"]) s.speed = ParseSpeedSensor(c, root["speed"]);
  if (root["seed"]) {
    const auto n = root["seed"];
    try {
      const long long v = n.as<long long>();
      if (v < 0) c.Fail(n, "seed", "must be >= 0, got " + n.Scalar());
      s.seed = static_cast<uint64_t>(v);
    } catch (const YAML::Exception&) {
      c.Fail(n, "seed", "expected a non-negative integer, got '" + n.Scalar() + "'");
    }
  }
  try {
    sim::ValidateScenario(s);
  } catch (const std::invalid_argument& e) {
    throw ScenarioError(where + ": " + e.what());
  }
  return s;
}

sim::Scenario LoadScenario(const std::string& name_or_path) {
  for (const auto& n : sim::BuiltinScenarioNames())
    if (n == name_or_path) return sim::BuiltinScenario(n);
  const std::filesystem::path path(name_or_path);
  if (!std::filesystem::exists(path)) {
    std::string known;
    for (const auto& n : sim::BuiltinScenarioNames()) known += (known.empty() ? "" : ", ") + n;
    throw ScenarioError("scenario '" + name_or_path + "': neither a built-in (" + known +
                        ") nor an existing file");
  }
  std::ifstream in(path);
  if (!in) throw ScenarioError(path.string() + ": cannot open");
  std::stringstream ss;
  ss << in.rdbuf();
  return ParseScenarioYaml(ss.str(), path.string());
}

}  // namespace locaid::pipeline
