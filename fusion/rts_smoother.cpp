#include "fusion/rts_smoother.hpp"

#include <Eigen/Eigenvalues>

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace locaid::fusion {
namespace {

// Pseudo-inverse of a covariance, taken on its correlation matrix.
Eigen::MatrixXd CovariancePseudoInverse(const Eigen::MatrixXd& P) {
  const Eigen::Index n = P.rows();
  Eigen::VectorXd d(n);
  for (Eigen::Index i = 0; i < n; ++i) d(i) = P(i, i) > 0 ? 1.0 / std::sqrt(P(i, i)) : 0.0;
  const Eigen::MatrixXd C = d.asDiagonal() * P * d.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(C);
  const Eigen::VectorXd& l = eig.eigenvalues();
  const double tol = 1e-11 * std::max(1.0, l.cwiseAbs().maxCoeff());
  Eigen::VectorXd inv(n);
  for (Eigen::Index i = 0; i < n; ++i) inv(i) = l(i) > tol ? 1.0 / l(i) : 0.0;
  const Eigen::MatrixXd C_pinv = eig.eigenvectors() * inv.asDiagonal() * eig.eigenvectors().transpose();
  return d.asDiagonal() * C_pinv * d.asDiagonal();
}

void PackSymmetric(const Eigen::MatrixXd& M, double*& out) {
  for (Eigen::Index c = 0; c < M.cols(); ++c)
    for (Eigen::Index r = c; r < M.rows(); ++r) *out++ = M(r, c);
}

Eigen::MatrixXd UnpackSymmetric(int n, const double*& in) {
  Eigen::MatrixXd M(n, n);
  for (int c = 0; c < n; ++c)
    for (int r = c; r < n; ++r) M(r, c) = M(c, r) = *in++;
  return M;
}

size_t RecordDoubles(int n) {
  const auto m = static_cast<size_t>(n);
  return 3 /* seq t linked */ + m * m /* phi */ + m * (m + 1) /* P- P+ */ + m /* c */ + 21 /* x */;
}

std::string Errno() { return std::strerror(errno); }

}  // namespace

SmoothedError ChainEnd(const Epoch& epoch) {
  return {Eigen::VectorXd::Zero(epoch.P_post.rows()), epoch.P_post};
}

SmoothedError RtsStep(const Epoch& k, const Epoch& next, const SmoothedError& next_smoothed) {
  const Eigen::MatrixXd G = k.P_post * next.phi.transpose() * CovariancePseudoInverse(next.P_prior);
  SmoothedError out;
  out.dx = G * (next_smoothed.dx + next.correction);
  out.P = k.P_post + G * (next_smoothed.P - next.P_prior) * G.transpose();
  out.P = 0.5 * (out.P + out.P.transpose()).eval();
  return out;
}

FusedPose SmoothedPose(const Epoch& epoch, const SmoothedError& s, const ErrorLayout& layout,
                       const FusedPose& forward) {
  FusedPose out = forward;
  out.smoothed = true;
  const Vec3 dp = s.dx.head<3>();
  const Vec3 dth = s.dx.segment<3>(layout.attitude);
  out.T_enu_body.linear() = ExpSO3(dth) * epoch.x_post.R_enu_body;
  out.T_enu_body.translation() = epoch.x_post.p_enu_m + dp;
  out.v_enu_mps = epoch.x_post.v_enu_mps;
  if (layout.velocity >= 0) out.v_enu_mps += s.dx.segment<3>(layout.velocity);
  const int th = layout.attitude;
  out.covariance.block<3, 3>(0, 0) = s.P.block<3, 3>(0, 0);
  out.covariance.block<3, 3>(0, 3) = s.P.block<3, 3>(0, th);
  out.covariance.block<3, 3>(3, 0) = s.P.block<3, 3>(th, 0);
  out.covariance.block<3, 3>(3, 3) = s.P.block<3, 3>(th, th);
  return out;
}

size_t EpochBytes(int n) { return RecordDoubles(n) * sizeof(double); }

EpochStore::EpochStore(EpochStoreOptions options) : options_(std::move(options)) {}

EpochStore::~EpochStore() {
  if (fd_ >= 0) ::close(fd_);
}

void EpochStore::Encode(const Epoch& e, double* out) const {
  *out++ = static_cast<double>(e.seq);
  *out++ = static_cast<double>(e.t_ns);  // exact below 2^53 ns (104 days)
  *out++ = e.linked ? 1.0 : 0.0;
  std::copy(e.phi.data(), e.phi.data() + e.phi.size(), out);
  out += e.phi.size();
  PackSymmetric(e.P_prior, out);
  PackSymmetric(e.P_post, out);
  std::copy(e.correction.data(), e.correction.data() + n_, out);
  out += n_;
  const NominalState& x = e.x_post;
  for (const Vec3* v : {&x.p_enu_m, &x.v_enu_mps, &x.accel_bias_mps2, &x.gyro_bias_radps})
    for (int i = 0; i < 3; ++i) *out++ = (*v)(i);
  std::copy(x.R_enu_body.data(), x.R_enu_body.data() + 9, out);
}

Epoch EpochStore::Decode(const double* in) const {
  Epoch e;
  e.seq = static_cast<int64_t>(*in++);
  e.t_ns = static_cast<int64_t>(*in++);
  e.linked = *in++ != 0.0;
  e.phi = Eigen::Map<const Eigen::MatrixXd>(in, n_, n_);
  in += static_cast<ptrdiff_t>(n_) * n_;
  e.P_prior = UnpackSymmetric(n_, in);
  e.P_post = UnpackSymmetric(n_, in);
  e.correction = Eigen::Map<const Eigen::VectorXd>(in, n_);
  in += n_;
  NominalState& x = e.x_post;
  for (Vec3* v : {&x.p_enu_m, &x.v_enu_mps, &x.accel_bias_mps2, &x.gyro_bias_radps})
    for (int i = 0; i < 3; ++i) (*v)(i) = *in++;
  x.R_enu_body = Eigen::Map<const Mat3>(in);
  return e;
}

void EpochStore::Append(const Epoch& epoch) {
  const int n = static_cast<int>(epoch.P_post.rows());
  if (n_ < 0) {
    n_ = n;
    record_doubles_ = RecordDoubles(n);
  } else if (n != n_) {
    throw std::runtime_error("smoother: an epoch of " + std::to_string(n) + " states after epochs of " +
                             std::to_string(n_));
  }
  if (bytes_in_memory() + EpochBytes(n_) > options_.memory_budget_bytes && !memory_.empty()) Spill();
  const size_t at = memory_.size();
  memory_.resize(at + record_doubles_);
  Encode(epoch, memory_.data() + at);
  ++count_;
}

void EpochStore::Spill() {
  if (fd_ < 0) {
    std::string pattern = (options_.spill_dir / "locaid-smoother-XXXXXX").string();
    fd_ = ::mkstemp(pattern.data());
    if (fd_ < 0)
      throw std::runtime_error("smoother: cannot create a spill file in '" + options_.spill_dir.string() +
                               "': " + Errno());
    ::unlink(pattern.c_str());
  }
  const auto* bytes = reinterpret_cast<const char*>(memory_.data());
  size_t left = memory_.size() * sizeof(double);
  while (left > 0) {
    const ssize_t w = ::write(fd_, bytes, left);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0)
      throw std::runtime_error("smoother: cannot write the spill file in '" + options_.spill_dir.string() +
                               "': " + Errno());
    bytes += w;
    left -= static_cast<size_t>(w);
  }
  spilled_ += static_cast<int64_t>(memory_.size() / record_doubles_);
  memory_.clear();
}

void EpochStore::SmoothBackward(const std::function<void(const Epoch&, const SmoothedError&)>& visit) const {
  if (count_ == 0) return;
  std::vector<double> record(record_doubles_);
  const auto record_at = [&](int64_t i) -> const double* {
    if (i >= spilled_) return memory_.data() + static_cast<size_t>(i - spilled_) * record_doubles_;
    const size_t bytes = record_doubles_ * sizeof(double);
    const auto offset = static_cast<off_t>(static_cast<size_t>(i) * bytes);
    size_t got = 0;
    while (got < bytes) {
      const ssize_t r = ::pread(fd_, reinterpret_cast<char*>(record.data()) + got, bytes - got,
                                offset + static_cast<off_t>(got));
      if (r < 0 && errno == EINTR) continue;
      if (r <= 0) throw std::runtime_error("smoother: cannot read back the spill file: " + Errno());
      got += static_cast<size_t>(r);
    }
    return record.data();
  };
  Epoch next = Decode(record_at(count_ - 1));
  SmoothedError next_s = ChainEnd(next);
  visit(next, next_s);
  for (int64_t i = count_ - 2; i >= 0; --i) {
    Epoch k = Decode(record_at(i));
    SmoothedError k_s = next.linked ? RtsStep(k, next, next_s) : ChainEnd(k);
    visit(k, k_s);
    next = std::move(k);
    next_s = std::move(k_s);
  }
}

}  // namespace locaid::fusion
