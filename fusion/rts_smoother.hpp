// The backward pass of a Rauch-Tung-Striebel smoother over the error state,
// on the epochs the forward filter recorded (fusion/epoch_log.hpp), and where
// those epochs wait for it (EpochStore: memory up to a budget, then a
// temporary file).
//
// For epoch k chained to k+1 (Phi = phi of k+1):
//   G_k    = P+_k Phi' (P-_{k+1})^+
//   dx_k   = G_k (dx_{k+1} + c_{k+1})          c: k+1's correction (posterior - prior)
//   Ps_k   = P+_k + G_k (Ps_{k+1} - P-_{k+1}) G_k'
// where dx is the smoothed error about the forward posterior; the last
// epoch of a chain keeps its filtered estimate (dx = 0, Ps = P+). P- may be
// singular (a clone copies the pose): its pseudo-inverse is taken on the
// correlation matrix, so states of very different scales (metres, gyro
// biases) keep their precision. On a linear-Gaussian model this equals the
// batch least-squares solution (tests/fusion/rts_smoother_test.cpp).
//
// Single-threaded. EpochStore does file I/O only past its memory budget.
#pragma once

#include "fusion/epoch_log.hpp"
#include "fusion/types.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace locaid::fusion {

// The smoothed error of one epoch about its forward posterior, and its covariance.
struct SmoothedError {
  Eigen::VectorXd dx;
  Eigen::MatrixXd P;
};

// The last epoch of a chain: the filtered estimate.
SmoothedError ChainEnd(const Epoch& epoch);
// One backward step: epoch k from the smoothed epoch k+1 (next.linked must hold).
SmoothedError RtsStep(const Epoch& k, const Epoch& next, const SmoothedError& next_smoothed);

// The smoothed pose of an epoch: `forward` (the filter's pose at the epoch's
// time, for its mode and counters) with the nominal state corrected by dx,
// the covariance from P, and `smoothed` set.
FusedPose SmoothedPose(const Epoch& epoch, const SmoothedError& s, const ErrorLayout& layout,
                       const FusedPose& forward);

// Bytes an epoch of an n-state model takes in an EpochStore.
size_t EpochBytes(int n);

struct EpochStoreOptions {
  // Epochs kept in memory; beyond it they go to a temporary file in
  // spill_dir (unlinked at once: nothing stays behind, even after a crash).
  size_t memory_budget_bytes = size_t{256} << 20;
  std::filesystem::path spill_dir = std::filesystem::temp_directory_path();
};

// Epochs in the order the filter made them, read back newest first.
class EpochStore {
 public:
  explicit EpochStore(EpochStoreOptions options = {});
  ~EpochStore();
  EpochStore(const EpochStore&) = delete;
  EpochStore& operator=(const EpochStore&) = delete;

  // Throws std::runtime_error when the spill file cannot be written (says
  // the folder and the reason) or the epoch's size differs from the first's.
  void Append(const Epoch& epoch);
  int64_t size() const { return count_; }
  size_t bytes_in_memory() const { return memory_.size() * sizeof(double); }
  size_t bytes_spilled() const { return spilled_ * record_doubles_ * sizeof(double); }

  // Runs the backward pass from the newest epoch to the oldest; `visit` gets
  // each epoch with its smoothed error. Throws std::runtime_error when the
  // spill file cannot be read back.
  void SmoothBackward(const std::function<void(const Epoch&, const SmoothedError&)>& visit) const;

 private:
  void Spill();
  Epoch Decode(const double* record) const;
  void Encode(const Epoch& epoch, double* record) const;

  EpochStoreOptions options_;
  int n_ = -1;
  size_t record_doubles_ = 0;
  int64_t count_ = 0;
  int64_t spilled_ = 0;        // records in the file (the oldest ones)
  std::vector<double> memory_;  // the newest records
  int fd_ = -1;
};

}  // namespace locaid::fusion
