// locaid-eval: accuracy of an estimated trajectory against ground truth.
//
//   locaid-eval --gt poses/00.txt --est results/00.txt [--json]
//               [--align se3|none] [--max-dt 0.02]
//
// Both files KITTI (12 numbers a line, matched by line) or both TUM (8 numbers,
// matched by timestamp within --max-dt). Prints the KITTI odometry devkit
// metric (t_rel %, r_rel deg/100 m per segment length and on average), ATE
// RMSE (after SE(3) alignment unless --align none) and per-frame RPE.
// Exit status: 0 ok, 2 bad usage or bad input (message on stderr).
#include "eval/evaluate.hpp"
#include "kitti/types.hpp"

#include <algorithm>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <optional>
#include <string>

namespace {

using locaid::eval::DevkitResult;
using locaid::eval::ErrorStats;
using locaid::eval::EvalReport;

constexpr int kExitOk = 0;
constexpr int kExitBadInput = 2;
constexpr double kPercent = 100.0;
constexpr double kRadPerMToDegPer100m = 180.0 / M_PI * 100.0;

std::optional<double> Scaled(const std::optional<double>& v, double factor) {
  if (!v) return std::nullopt;
  return *v * factor;
}

// PREFIX_rmse_UNIT, PREFIX_mean_UNIT, PREFIX_median_UNIT, PREFIX_max_UNIT.
void PutStats(nlohmann::ordered_json& j, const std::string& prefix, const ErrorStats& s,
              const std::string& unit) {
  j[prefix + "_rmse_" + unit] = s.rmse;
  j[prefix + "_mean_" + unit] = s.mean;
  j[prefix + "_median_" + unit] = s.median;
  j[prefix + "_max_" + unit] = s.max;
}

nlohmann::ordered_json OrNull(const std::optional<double>& v) {
  return v ? nlohmann::ordered_json(*v) : nlohmann::ordered_json(nullptr);
}

std::string NoSegmentsNote(const EvalReport& r, float shortest_m) {
  char buf[200];
  std::snprintf(buf, sizeof(buf),
                "trajectory is %.1f m long, shorter than the shortest KITTI segment (%.0f m): "
                "no devkit segments, t_rel/r_rel undefined",
                r.length_m, static_cast<double>(shortest_m));
  return buf;
}

nlohmann::ordered_json ToJson(const EvalReport& r, const std::string& gt, const std::string& est,
                      const locaid::eval::MatchedPoses& m, const std::string& align,
                      float shortest_m) {
  const DevkitResult& d = r.devkit;
  nlohmann::ordered_json j;
  j["gt"] = gt;
  j["est"] = est;
  j["format"] = m.format == locaid::kitti::PoseFormat::kKitti ? "kitti" : "tum";
  j["gt_poses"] = m.gt_count;
  j["est_poses"] = m.est_count;
  j["frames"] = r.frames;
  j["length_m"] = r.length_m;
  j["segments"] = d.segments.size();
  j["t_err"] = OrNull(d.t_err);
  j["r_err_rad_per_m"] = OrNull(d.r_err_rad_per_m);
  j["t_rel_pct"] = OrNull(Scaled(d.t_err, kPercent));
  j["r_rel_deg_per_100m"] = OrNull(Scaled(d.r_err_rad_per_m, kRadPerMToDegPer100m));
  if (d.segments.empty()) j["note"] = NoSegmentsNote(r, shortest_m);
  nlohmann::ordered_json per_length = nlohmann::ordered_json::array();
  for (const auto& l : d.per_length) {
    per_length.push_back({{"length_m", l.length_m},
                          {"segments", l.segments},
                          {"t_err", OrNull(l.t_err)},
                          {"r_err_rad_per_m", OrNull(l.r_err_rad_per_m)},
                          {"t_rel_pct", OrNull(Scaled(l.t_err, kPercent))},
                          {"r_rel_deg_per_100m",
                           OrNull(Scaled(l.r_err_rad_per_m, kRadPerMToDegPer100m))}});
  }
  j["per_length"] = per_length;
  j["align"] = align;
  PutStats(j, "ate", r.ate.trans_m, "m");
  j["rpe_pairs"] = r.rpe.trans_m.count;
  PutStats(j, "rpe_trans", r.rpe.trans_m, "m");
  PutStats(j, "rpe_rot", r.rpe.rot_deg, "deg");
  return j;
}

std::string Cell(const std::optional<double>& v, const char* fmt) {
  if (!v) return "-";
  char buf[64];
  std::snprintf(buf, sizeof(buf), fmt, *v);
  return buf;
}

void PrintStatsRow(const char* name, const ErrorStats& s, const char* unit) {
  std::printf("  %-16s rmse %10.6f  mean %10.6f  median %10.6f  max %10.6f %s\n", name, s.rmse,
              s.mean, s.median, s.max, unit);
}

void PrintTable(const EvalReport& r, const std::string& gt, const std::string& est,
                const locaid::eval::MatchedPoses& m, const std::string& align,
                float shortest_m) {
  const DevkitResult& d = r.devkit;
  std::printf("gt:  %s (%zu poses)\nest: %s (%zu poses)\n", gt.c_str(), m.gt_count, est.c_str(),
              m.est_count);
  std::printf("frames %zu, length %.3f m, devkit segments %zu\n\n", r.frames, r.length_m,
              d.segments.size());
  std::printf("KITTI devkit metric (step 10 frames)\n");
  std::printf("  %9s %9s %12s %20s\n", "length_m", "segments", "t_rel_%", "r_rel_deg/100m");
  for (const auto& l : d.per_length) {
    std::printf("  %9.0f %9d %12s %20s\n", static_cast<double>(l.length_m), l.segments,
                Cell(Scaled(l.t_err, kPercent), "%.4f").c_str(),
                Cell(Scaled(l.r_err_rad_per_m, kRadPerMToDegPer100m), "%.4f").c_str());
  }
  if (d.segments.empty()) {
    std::printf("  average: none (%s)\n", NoSegmentsNote(r, shortest_m).c_str());
  } else {
    std::printf("  %9s %9zu %12s %20s\n", "average", d.segments.size(),
                Cell(Scaled(d.t_err, kPercent), "%.4f").c_str(),
                Cell(Scaled(d.r_err_rad_per_m, kRadPerMToDegPer100m), "%.4f").c_str());
    std::printf("  devkit stats.txt: t_err %.6f  r_err %.6f rad/m\n", *d.t_err, *d.r_err_rad_per_m);
  }
  std::printf("\nATE (alignment %s)\n", align.c_str());
  PrintStatsRow("position", r.ate.trans_m, "m");
  std::printf("\nRPE per frame (%zu pairs)\n", r.rpe.trans_m.count);
  PrintStatsRow("translation", r.rpe.trans_m, "m");
  PrintStatsRow("rotation", r.rpe.rot_deg, "deg");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"locaid-eval: KITTI devkit metric, ATE and RPE of an estimated trajectory"};
  std::string gt_path, est_path, align = "se3";
  bool json = false;
  locaid::eval::EvalConfig config;
  app.add_option("--gt", gt_path, "ground-truth pose file (KITTI or TUM)")->required();
  app.add_option("--est", est_path, "estimated pose file (same format as --gt)")->required();
  app.add_flag("--json", json, "print one JSON object instead of a table");
  app.add_option("--align", align, "ATE alignment: se3 (rigid, no scale) or none")
      ->check(CLI::IsMember({"se3", "none"}));
  app.add_option("--max-dt", config.max_dt_s, "TUM timestamp association tolerance [s]")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--lengths", config.devkit.lengths_m,
                 "segment lengths in metres (devkit: 100 200 ... 800; short drives: 25 50 75 100)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "locaid-eval: " << e.what() << "\nRun with --help for usage.\n";
    return kExitBadInput;
  }
  config.alignment = align == "none" ? locaid::eval::Alignment::kNone
                                     : locaid::eval::Alignment::kSe3;
  const float shortest_m = config.devkit.lengths_m.empty()
                               ? 0.0f
                               : *std::min_element(config.devkit.lengths_m.begin(),
                                                   config.devkit.lengths_m.end());
  try {
    const auto matched =
        locaid::eval::LoadMatchedPoses(gt_path, est_path, config.max_dt_s, config.read);
    const EvalReport report = locaid::eval::Evaluate(matched.gt, matched.est, config);
    if (json) {
      std::cout << ToJson(report, gt_path, est_path, matched, align, shortest_m).dump() << "\n";
    } else {
      PrintTable(report, gt_path, est_path, matched, align, shortest_m);
    }
  } catch (const locaid::kitti::Error& e) {
    std::cerr << "locaid-eval: " << e.what() << "\n";
    return kExitBadInput;
  }
  return kExitOk;
}
