#include "replay/replay_mcap.hpp"

#include "output/pose_message.hpp"

namespace locaid::pipeline {

locaid::v1::PoseUpdate ReplayPoseUpdate(const StepResult& step, uint64_t sequence) {
  locaid::v1::PoseUpdate msg;
  output::FillPoseUpdate(step, step.frame.vo_ms + step.frame.fusion_ms, &msg);
  msg.set_session_id("replay");
  msg.set_sequence(sequence);
  return msg;
}

}  // namespace locaid::pipeline
