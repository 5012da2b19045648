// The whole recorded drive smoothed once it has been filtered: attach log()
// to the filter (Ekf::set_epoch_log), keep each pose with its epoch
// (Ekf::MarkEpoch), then Smooth. Epochs wait in an EpochStore (memory up to
// its budget, then a temporary file), so a drive of any length is smoothed
// without the kernel killing it; EpochBytes says what one epoch costs.
//
// Single-threaded, like the filter it records.
#pragma once

#include "fusion/epoch_log.hpp"
#include "fusion/rts_smoother.hpp"
#include "fusion/types.hpp"

#include <cstdint>
#include <vector>

namespace locaid::fusion {

class OfflineSmoother {
 public:
  explicit OfflineSmoother(EpochStoreOptions options = {})
      : store_(std::move(options)), log_([this](Epoch&& e) { store_.Append(e); }) {}

  EpochLog& log() { return log_; }
  const EpochStore& store() const { return store_; }

  // The smoothed pose of each forward pose: forward[i] with its epoch
  // epochs[i] (-1: the filter had not started; the pose is returned as it
  // is). Closes the log. Throws std::runtime_error when the store cannot
  // read back what it spilled.
  std::vector<FusedPose> Smooth(const std::vector<FusedPose>& forward, const std::vector<int64_t>& epochs,
                                const ErrorLayout& layout);

 private:
  EpochStore store_;
  EpochLog log_;
};

}  // namespace locaid::fusion
