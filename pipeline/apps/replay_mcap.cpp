#include "pipeline/apps/replay_mcap.hpp"

#include "output/pose_message.hpp"

namespace locaid::pipeline {

void ReplayMcap::Add(const StepResult& step) {
  locaid::v1::PoseUpdate msg;
  output::FillPoseUpdate(step, step.frame.vo_ms + step.frame.fusion_ms, &msg);
  msg.set_session_id("replay");
  msg.set_sequence(sequence_++);
  recording_.Add(msg);
}

}  // namespace locaid::pipeline
