#include "eval/evaluate.hpp"

namespace locaid::eval {

EvalReport Evaluate(const std::vector<Eigen::Isometry3d>& gt,
                    const std::vector<Eigen::Isometry3d>& est, const EvalConfig& config) {
  EvalReport report;
  report.devkit = EvaluateDevkit(gt, est, config.devkit);  // checks the sizes
  report.ate = ComputeAte(gt, est, config.alignment);     // checks non-empty
  report.rpe = ComputeRpe(gt, est);
  report.frames = gt.size();
  report.length_m = PathLengthM(gt);
  return report;
}

}  // namespace locaid::eval
