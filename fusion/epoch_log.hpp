// What a Rauch-Tung-Striebel smoother needs of the forward filter, recorded
// as it runs: one Epoch per time the filter took measurements (or gave a
// pose). The filter and its process models call the hooks through
// FilterState::log; with no log attached nothing is recorded and nothing is
// paid. fusion/rts_smoother.hpp runs the backward pass over the epochs.
//
// Epoch k+1 is chained to epoch k by the error-state transition Phi between
// k's posterior and k+1's prior (IMU propagation steps and clones composed,
// so epochs come at the update rate, not the IMU rate). A chain breaks where
// the filter is not a linear-Gaussian step away from its past: the start-up
// fit and a position reset to GPS start a new chain. Rejected fixes are not
// measurements: they leave no trace.
//
// Threading: the thread that runs the filter. No I/O.
#pragma once

#include "fusion/ekf_models.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <functional>

namespace locaid::fusion {

struct FilterState;

struct Epoch {
  int64_t seq = 0;     // 0, 1, 2, ... in the order the filter made them
  int64_t t_ns = 0;    // the filter's time at the epoch
  bool linked = false; // chained to epoch seq - 1 by phi (false: a chain starts here)
  Eigen::MatrixXd phi;      // n x n: error-state transition from epoch seq - 1's posterior to this prior
  Eigen::MatrixXd P_prior;  // n x n: error covariance before this epoch's updates
  Eigen::MatrixXd P_post;   // n x n: after them
  Eigen::VectorXd correction;  // n: posterior minus prior nominal state (the updates' dx, summed)
  NominalState x_post;         // nominal state after the updates
};

// Where the shown states sit in a model's error-state layout (position at 0).
struct ErrorLayout {
  int size = 0;
  int attitude = 0;
  int velocity = -1;  // -1: velocity is not a state (no-IMU model)
};

class EpochLog {
 public:
  using Sink = std::function<void(Epoch&&)>;
  // `sink` takes each epoch once it is complete, in order.
  explicit EpochLog(Sink sink) : sink_(std::move(sink)) {}

  // ---- Hooks (the filter and its process models)
  // A chain starts at this state: initialisation, or a position reset.
  void Start(const FilterState& s);
  // The state moved by `phi` (x and P already moved).
  void Transition(const FilterState& s, const Eigen::MatrixXd& phi);
  // An update's correction `dx` was applied (x and P already updated).
  void Corrected(const FilterState& s, const Eigen::VectorXd& dx);

  // The epoch that holds the state now (a pose given at this time), as its
  // seq; -1 before the filter started a chain.
  int64_t Mark(const FilterState& s);
  // Hands the open epoch to the sink (end of a drive). Idempotent.
  void Finish();

  int64_t epochs() const { return next_seq_; }  // made so far (the open one included)
  // The epoch still taking updates (the newest state), or nullptr.
  const Epoch* open() const { return has_open_ ? &open_ : nullptr; }

 private:
  void Emit();

  Sink sink_;
  Epoch open_;
  bool has_open_ = false;
  bool open_updated_ = false;  // the open epoch took an update: the next transition starts a new one
  int64_t next_seq_ = 0;
};

}  // namespace locaid::fusion
