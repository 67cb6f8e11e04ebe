#include "isk/fields/hrbf.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <sstream>

#include "isk/core/error.hpp"

namespace isk {
namespace {

// phi(v) = |v|^3, grad phi = 3|v| v, Hessian = 3(|v| I + v v^T / |v|).
void kernelTerms(const Eigen::Vector3d& v, double& phi, Eigen::Vector3d& grad,
                 Eigen::Matrix3d& hessian) {
  const double r = v.norm();
  phi = r * r * r;
  grad = 3.0 * r * v;
  if (r > 0) {
    hessian = 3.0 * (r * Eigen::Matrix3d::Identity() + v * v.transpose() / r);
  } else {
    hessian.setZero();
  }
}

}  // namespace

Hrbf Hrbf::fit(const HermiteSamples& samples, const std::string& what,
               std::vector<std::string>* warnings) {
  if (samples.positions.size() != samples.normals.size())
    throw Error(ErrorCode::kInvalidArgument,
                what + ": " + std::to_string(samples.positions.size()) +
                    " sample positions but " +
                    std::to_string(samples.normals.size()) + " normals");
  for (int k = 0; k < samples.size(); ++k) {
    if (!samples.positions[k].allFinite() || !samples.normals[k].allFinite() ||
        samples.normals[k].norm() < 1e-12)
      throw Error(ErrorCode::kInvalidArgument,
                  what + ": sample " + std::to_string(k) +
                      " has a non-finite position or a zero normal");
  }
  Hrbf h;
  // Normalised frame: centred on the samples, scaled to their extent.
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& p : samples.positions) centroid += p;
  if (samples.size() > 0) centroid /= samples.size();
  double extent = 0;
  for (const auto& p : samples.positions)
    extent = std::max(extent, (p - centroid).norm());
  if (!(extent > 0)) extent = 1;
  h.origin_ = centroid;
  h.scale_ = extent;

  // Merge samples closer than 1e-6 of the extent: they make the system
  // singular and carry no information.
  std::vector<Eigen::Vector3d> normals;
  int merged = 0;
  const double merge_distance = 1e-6;
  for (int k = 0; k < samples.size(); ++k) {
    const Eigen::Vector3d c = (samples.positions[k] - centroid) / extent;
    bool duplicate = false;
    for (const auto& kept : h.unit_centres_) {
      if ((kept - c).norm() < merge_distance) {
        duplicate = true;
        break;
      }
    }
    if (duplicate) {
      ++merged;
      continue;
    }
    h.unit_centres_.push_back(c);
    h.centres_.push_back(samples.positions[k]);
    normals.push_back(samples.normals[k].normalized());
  }
  const int m = static_cast<int>(h.unit_centres_.size());
  if (m < 4) {
    std::ostringstream msg;
    msg << what << ": " << m << " distinct samples"
        << (merged
                ? " (after merging " + std::to_string(merged) + " duplicates)"
                : std::string())
        << ", at least 4 are needed to fit an HRBF";
    throw Error(ErrorCode::kInvalidArgument, msg.str());
  }
  if (merged > 0 && warnings)
    warnings->push_back(what + ": merged " + std::to_string(merged) +
                        " duplicate samples before the HRBF fit");

  // Unknowns: (lambda_k, beta_k) per centre, then a (3) and b.
  const int n = 4 * m + 4;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n);
  double phi;
  Eigen::Vector3d grad;
  Eigen::Matrix3d hessian;
  for (int j = 0; j < m; ++j) {
    const Eigen::Vector3d& cj = h.unit_centres_[j];
    for (int k = 0; k < m; ++k) {
      kernelTerms(cj - h.unit_centres_[k], phi, grad, hessian);
      A(4 * j, 4 * k) = phi;
      A.block<1, 3>(4 * j, 4 * k + 1) = grad.transpose();
      A.block<3, 1>(4 * j + 1, 4 * k) = grad;
      A.block<3, 3>(4 * j + 1, 4 * k + 1) = hessian;
    }
    A.block<1, 3>(4 * j, 4 * m) = cj.transpose();
    A(4 * j, 4 * m + 3) = 1;
    A.block<3, 3>(4 * j + 1, 4 * m) = Eigen::Matrix3d::Identity();
    rhs.segment<3>(4 * j + 1) = normals[j];
    // Orthogonality to degree-1 polynomials.
    A(4 * m + 3, 4 * j) = 1;
    A.block<3, 1>(4 * m, 4 * j) = cj;
    A.block<3, 3>(4 * m, 4 * j + 1) = -Eigen::Matrix3d::Identity();
  }

  Eigen::PartialPivLU<Eigen::MatrixXd> lu(A);
  Eigen::VectorXd x = lu.solve(rhs);
  const double rcond = lu.rcond();
  auto relativeResidual = [&](const Eigen::VectorXd& sol) {
    return (A * sol - rhs).norm() / std::max(rhs.norm(), 1e-300);
  };
  if (!x.allFinite() || rcond < 1e-13 || relativeResidual(x) > 1e-6) {
    // Near singular (nearly coplanar or clustered samples): the minimum-norm
    // least-squares solution stays finite and smooth.
    Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(A);
    cod.setThreshold(1e-12);
    x = cod.solve(rhs);
    h.regularised_ = true;
    if (warnings) {
      std::ostringstream msg;
      msg << what << ": the HRBF system is near singular (reciprocal condition "
          << rcond << "); used a regularised least-squares solve";
      warnings->push_back(msg.str());
    }
    if (!x.allFinite())
      throw Error(ErrorCode::kInternal,
                  what + ": the HRBF solve gave non-finite coefficients");
  }
  h.lambda_.resize(m);
  h.beta_.resize(m);
  for (int k = 0; k < m; ++k) {
    h.lambda_[k] = x(4 * k);
    h.beta_[k] = x.segment<3>(4 * k + 1);
  }
  h.poly_a_ = x.segment<3>(4 * m);
  h.poly_b_ = x(4 * m + 3);

  for (int k = 0; k < m; ++k) {
    double value;
    Eigen::Vector3d gradient;
    h.evaluate(h.centres_[k], value, gradient);
    h.value_residual_ = std::max(h.value_residual_, std::abs(value));
    h.gradient_residual_ =
        std::max(h.gradient_residual_, (gradient - normals[k]).norm());
  }
  return h;
}

void Hrbf::evaluate(const Eigen::Vector3d& x, double& value,
                    Eigen::Vector3d& gradient) const {
  const Eigen::Vector3d u = (x - origin_) / scale_;
  double d = poly_a_.dot(u) + poly_b_;
  Eigen::Vector3d g = poly_a_;
  for (size_t k = 0; k < unit_centres_.size(); ++k) {
    const Eigen::Vector3d v = u - unit_centres_[k];
    const double r = v.norm();
    const double vb = v.dot(beta_[k]);
    // lambda phi + beta . grad phi, and its gradient lambda grad phi + H beta.
    d += lambda_[k] * r * r * r + 3.0 * r * vb;
    g += 3.0 * r * (lambda_[k] * v + beta_[k]);
    if (r > 0) g += (3.0 * vb / r) * v;
  }
  value = d * scale_;
  gradient = g;
}

double Hrbf::value(const Eigen::Vector3d& x) const {
  double v;
  Eigen::Vector3d g;
  evaluate(x, v, g);
  return v;
}

Eigen::Vector3d Hrbf::gradient(const Eigen::Vector3d& x) const {
  double v;
  Eigen::Vector3d g;
  evaluate(x, v, g);
  return g;
}

double reparameterize(double d, double r) {
  if (d <= -r) return 1.0;
  if (d >= r) return 0.0;
  const double x = d / r;
  const double x2 = x * x;
  return x * (-3.0 / 16.0 * x2 * x2 + 5.0 / 8.0 * x2 - 15.0 / 16.0) + 0.5;
}

double reparameterizeDerivative(double d, double r) {
  if (d <= -r || d >= r) return 0.0;
  const double x = d / r;
  const double x2 = x * x;
  return (-15.0 / 16.0) / r * (x2 * x2 - 2.0 * x2 + 1.0);
}

}  // namespace isk
