#include "fusion/epoch_log.hpp"

#include "fusion/process_model.hpp"

namespace locaid::fusion {

void EpochLog::Emit() {
  if (!has_open_) return;
  has_open_ = false;
  sink_(std::move(open_));
  open_ = Epoch{};
}

void EpochLog::Start(const FilterState& s) {
  Emit();
  const Eigen::Index n = s.P.rows();
  open_.seq = next_seq_++;
  open_.t_ns = s.t_ns;
  open_.linked = false;
  open_.phi = Eigen::MatrixXd::Identity(n, n);
  open_.P_prior = open_.P_post = s.P;
  open_.correction = Eigen::VectorXd::Zero(n);
  open_.x_post = s.x;
  has_open_ = true;
  open_updated_ = true;  // nothing to add before the next transition
}

void EpochLog::Transition(const FilterState& s, const Eigen::MatrixXd& phi) {
  if (!has_open_) return;  // no chain yet (start-up)
  if (open_updated_) {
    Emit();
    open_.seq = next_seq_++;
    open_.linked = true;
    open_.phi = phi;
    open_.correction = Eigen::VectorXd::Zero(s.P.rows());
    has_open_ = true;
    open_updated_ = false;
  } else {
    open_.phi = phi * open_.phi;
  }
  open_.t_ns = s.t_ns;
  open_.P_prior = open_.P_post = s.P;
  open_.x_post = s.x;
}

void EpochLog::Corrected(const FilterState& s, const Eigen::VectorXd& dx) {
  if (!has_open_) return;
  open_updated_ = true;
  open_.correction += dx;
  open_.P_post = s.P;
  open_.x_post = s.x;
}

int64_t EpochLog::Mark(const FilterState& s) {
  if (!has_open_) return -1;
  open_updated_ = true;  // a pose was given here: later motion starts a new epoch
  open_.P_post = s.P;
  open_.x_post = s.x;
  return open_.seq;
}

void EpochLog::Finish() { Emit(); }

}  // namespace locaid::fusion
