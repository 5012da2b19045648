#include "pipeline/apps/replay_mcap.hpp"

#include "server/pose_message.hpp"

namespace locaid::pipeline {

void ReplayMcap::Add(int64_t frame_index, const FrameResult& r, const std::optional<Eigen::Isometry3d>& truth_enu,
                     double truth_lat, double truth_lon, double truth_alt) {
  server::StepResult step;
  step.kind = server::StepResult::Kind::kPose;
  step.frame_index = frame_index;
  step.t_ns = r.pose.t_ns;
  step.pose = r.pose;
  step.vo_inliers = r.vo.inliers;
  step.vo_status = r.vo.status;
  step.gps_outage_active = r.in_outage;
  step.gps_fixes = server::FixesSeen(r);
  if (truth_enu) step.truth = server::TruthPose{truth_lat, truth_lon, truth_alt, truth_enu};
  locaid::v1::PoseUpdate msg;
  server::FillPoseUpdate(step, r.vo_ms + r.fusion_ms, &msg);
  msg.set_session_id("replay");
  msg.set_sequence(sequence_++);
  recording_.Add(msg);
}

}  // namespace locaid::pipeline
