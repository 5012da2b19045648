#include "pipeline/replay_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <tuple>
#include <utility>

#include "fusion/ekf_models.hpp"

namespace locaid::pipeline {

namespace {

// 99 % bound of the mean of n 3-dof NEES values (Wilson-Hilferty: the
// closed-form CDF does not reach thousands of dof); 0 for n = 0.
double NeesBound99(int n) {
  if (n <= 0) return 0;
  const double k = 3.0 * n, z99 = 2.326347874;
  const double c = 2.0 / (9.0 * k);
  return k * std::pow(1.0 - c + z99 * std::sqrt(c), 3) / n;
}

}  // namespace

ReplayMetrics ComputeReplayMetrics(const std::vector<ReplaySample>& s, double sigma_h) {
  ReplayMetrics m;
  m.frames = static_cast<int>(s.size());
  auto err_h = [&](size_t i) { return (s[i].p_enu_est_m - s[i].p_enu_gt_m).head<2>().norm(); };
  // A frame is scored only with a valid pose AND ground truth.
  auto scored = [&](size_t i) { return s[i].initialized && s[i].has_gt; };
  double sum2 = 0, nees = 0, nees_late = 0;
  int n = 0;
  std::optional<double> t_init;
  for (size_t i = 0; i < s.size(); ++i) {
    if (!scored(i)) continue;
    if (!t_init) t_init = s[i].t_s;
    const Eigen::Vector3d e = s[i].p_enu_est_m - s[i].p_enu_gt_m;
    const double q = e.dot(s[i].P_pos_m2.ldlt().solve(e));
    if (std::isfinite(q)) { nees += q; ++m.nees_frames; }
    if (std::isfinite(q) && s[i].t_s >= *t_init + 30.0) { nees_late += q; ++m.nees_frames_after_30s; }
    m.max_vertical_error_m = std::max(m.max_vertical_error_m, std::abs(e.z()));
    const bool gps_in_use = !s[i].in_outage &&
        (s[i].mode == fusion::Mode::kGpsFused || s[i].mode == fusion::Mode::kGpsDegraded);
    if (gps_in_use) { sum2 += err_h(i) * err_h(i); ++n; }
  }
  m.rmse_gps_m = n ? std::sqrt(sum2 / n) : std::nan("");
  m.nees_mean = m.nees_frames ? nees / m.nees_frames : std::nan("");
  m.nees_bound_99 = NeesBound99(m.nees_frames);
  m.nees_mean_after_30s = m.nees_frames_after_30s ? nees_late / m.nees_frames_after_30s : std::nan("");
  m.nees_bound_99_after_30s = NeesBound99(m.nees_frames_after_30s);

  for (size_t i = 0; i < s.size(); ++i) {
    if (!s[i].in_outage || (i > 0 && s[i - 1].in_outage)) continue;
    size_t j = i;
    while (j + 1 < s.size() && s[j + 1].in_outage) ++j;
    OutageStats o;
    o.start_s = s[i].t_s;
    o.duration_s = (j + 1 < s.size() ? s[j + 1].t_s : s[j].t_s) - s[i].t_s;
    const size_t first = i > 0 ? i - 1 : i;  // last frame with GPS before the outage
    // Path length over the frames with ground truth (a gap is bridged).
    for (size_t k = first, prev = s.size(); k <= j; ++k) {
      if (!s[k].has_gt) continue;
      if (prev < s.size()) o.distance_m += (s[k].p_enu_gt_m - s[prev].p_enu_gt_m).norm();
      prev = k;
    }
    double sum2 = 0;
    int scored_frames = 0;
    for (size_t k = i; k <= j; ++k) {
      if (!scored(k)) continue;
      o.max_error_m = std::max(o.max_error_m, err_h(k));
      sum2 += err_h(k) * err_h(k);
      ++scored_frames;
    }
    o.rmse_m = scored_frames > 0 ? std::sqrt(sum2 / scored_frames) : std::nan("");
    o.end_error_m = scored(j) ? err_h(j) : std::nan("");
    o.end_error_pct = o.distance_m > 0 ? 100.0 * o.end_error_m / o.distance_m : std::nan("");
    // What the outage added: the horizontal error vector at its end minus the
    // one at the last frame with GPS (the error it started with).
    if (scored(first) && scored(j)) {
      o.start_error_m = err_h(first);
      const Eigen::Vector3d e0 = s[first].p_enu_est_m - s[first].p_enu_gt_m;
      const Eigen::Vector3d e1 = s[j].p_enu_est_m - s[j].p_enu_gt_m;
      o.added_error_m = (e1 - e0).head<2>().norm();
      o.added_error_pct = o.distance_m > 0 ? 100.0 * o.added_error_m / o.distance_m : std::nan("");
    }
    for (size_t k = j + 1; k < s.size() && !s[k].in_outage; ++k) {
      if (scored(k) && err_h(k) <= 2 * sigma_h) { o.reconverge_s = s[k].t_s - s[j].t_s; break; }
    }
    for (size_t k = j + 1; k < s.size() && s[k].t_s - s[j].t_s <= 10.0; ++k) {
      if (!scored(k) || !scored(k - 1)) continue;
      const Eigen::Vector3d d_est = s[k].p_enu_est_m - s[k - 1].p_enu_est_m;
      const Eigen::Vector3d d_gt = s[k].p_enu_gt_m - s[k - 1].p_enu_gt_m;
      o.max_jump_m = std::max(o.max_jump_m, (d_est - d_gt).head<2>().norm());
    }
    m.outages.push_back(o);
  }
  return m;
}

std::string DescribeMetrics(const ReplayMetrics& m) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(3) << "frames " << m.frames << ", horizontal RMSE while GPS used: ";
  if (std::isfinite(m.rmse_gps_m)) {
    out << m.rmse_gps_m << " m";
  } else {
    out << "n/a (no frame had GPS in use with the filter initialised)";
  }
  out << ", NEES mean: ";
  if (std::isfinite(m.nees_mean)) {
    out << m.nees_mean << " (99 % bound " << m.nees_bound_99 << ")";
  } else {
    out << "n/a (the filter was never initialised)";
  }
  out << "\n";
  for (const OutageStats& o : m.outages) {
    out << "  outage at " << o.start_s << " s for " << o.duration_s << " s over " << o.distance_m << " m: ";
    if (std::isfinite(o.end_error_m)) {
      out << "end error " << o.end_error_m << " m";
      if (std::isfinite(o.end_error_pct)) out << " (" << o.end_error_pct << " %)";
      out << ", max " << o.max_error_m << " m, ";
    } else {
      out << "no end error (the filter had no pose at the outage's end: it never got a GPS fix to start from), ";
    }
    if (o.reconverge_s >= 0) {
      out << "reconverged after " << o.reconverge_s << " s";
    } else {
      out << "did not reconverge (within 2 GPS sigma) before the drive ended";
    }
    out << "\n";
  }
  return out.str();
}

namespace {

// Mean and median of a list (median reorders it); zeros when empty.
std::pair<double, double> MeanAndMedian(std::vector<double>& v) {
  if (v.empty()) return {0.0, 0.0};
  double sum = 0;
  for (double q : v) sum += q;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return {sum / static_cast<double>(v.size()), v[v.size() / 2]};
}

}  // namespace

VoErrorStats ComputeVoErrorStats(const std::vector<VoErrorPair>& pairs) {
  VoErrorStats st;
  std::vector<double> nees, nees_model, nees_model_outage;
  Eigen::Matrix<double, 6, 1> e2 = Eigen::Matrix<double, 6, 1>::Zero(), s2 = e2, m2 = e2;
  for (const auto& p : pairs) {
    const Eigen::Isometry3d E = p.T_prev_curr_gt.inverse() * p.T_prev_curr_vo;
    Eigen::Matrix<double, 6, 1> d;
    d.head<3>() = E.translation();
    d.tail<3>() = fusion::LogSO3(E.linear());
    if (!d.allFinite() || !p.covariance.allFinite() || !p.model_covariance.allFinite()) continue;
    e2 += d.cwiseProduct(d);
    s2 += p.covariance.diagonal();
    m2 += p.model_covariance.diagonal();
    const double q = d.dot(p.covariance.ldlt().solve(d));
    if (std::isfinite(q)) nees.push_back(q);
    const double qm = d.dot(p.model_covariance.ldlt().solve(d));
    if (std::isfinite(qm)) (p.in_outage ? nees_model_outage : nees_model).push_back(qm);
    ++st.frames;
  }
  if (st.frames == 0) return st;
  st.rms_error = (e2 / st.frames).cwiseSqrt();
  st.rms_sigma = (s2 / st.frames).cwiseSqrt();
  st.rms_model_sigma = (m2 / st.frames).cwiseSqrt();
  std::tie(st.nees_mean, st.nees_median) = MeanAndMedian(nees);
  st.frames_in_outage = static_cast<int>(nees_model_outage.size());
  st.nees_mean_model_in_outage = MeanAndMedian(nees_model_outage).first;
  st.nees_mean_model_gps_good = MeanAndMedian(nees_model).first;
  nees_model.insert(nees_model.end(), nees_model_outage.begin(), nees_model_outage.end());
  std::tie(st.nees_mean_model, st.nees_median_model) = MeanAndMedian(nees_model);
  return st;
}

void WritePlotCsv(const std::string& path, const std::vector<ReplaySample>& samples,
                  const std::vector<PlotExtras>& extras) {
  if (!extras.empty() && extras.size() != samples.size()) {
    throw std::invalid_argument("WritePlotCsv: " + std::to_string(extras.size()) + " extras for " +
                                std::to_string(samples.size()) + " samples");
  }
  std::ofstream csv(path);
  if (!csv) throw std::runtime_error(path + ": cannot write");
  csv << "t_s,gt_e,gt_n,gt_u,est_e,est_n,est_u,gps_e,gps_n,gps_u,gps_rejected,vo_e,vo_n,vo_u,"
         "sigma_e,sigma_n,sigma_u,err_h,mode,in_outage,initialized,gps_gt_e,gps_gt_n,gps_gt_u,vo_health\n";
  csv << std::fixed << std::setprecision(4);
  auto xyz = [&csv](const std::optional<Eigen::Vector3d>& p) {
    if (p) csv << p->x() << ',' << p->y() << ',' << p->z() << ',';
    else csv << ",,,";
  };
  for (size_t k = 0; k < samples.size(); ++k) {
    const auto& s = samples[k];
    const PlotExtras none;
    const PlotExtras& x = extras.empty() ? none : extras[k];
    csv << s.t_s << ',';
    xyz(s.has_gt ? std::optional<Eigen::Vector3d>(s.p_enu_gt_m) : std::nullopt);
    xyz(s.p_enu_est_m);
    xyz(x.p_enu_gps_m);
    csv << int(x.gps_rejected) << ',';
    xyz(x.p_enu_vo_m);
    csv << std::sqrt(s.P_pos_m2(0, 0)) << ',' << std::sqrt(s.P_pos_m2(1, 1)) << ','
        << std::sqrt(s.P_pos_m2(2, 2)) << ',';
    if (s.has_gt) csv << (s.p_enu_est_m - s.p_enu_gt_m).head<2>().norm();
    csv << ',' << fusion::ToString(s.mode) << ',' << int(s.in_outage) << ',' << int(s.initialized) << ',';
    if (x.p_enu_gt_at_gps_m) csv << x.p_enu_gt_at_gps_m->x() << ',' << x.p_enu_gt_at_gps_m->y() << ',' << x.p_enu_gt_at_gps_m->z();
    else csv << ",,";
    csv << ',' << x.vo_health << '\n';
  }
  if (!csv) throw std::runtime_error(path + ": write failed");
}

}  // namespace locaid::pipeline
