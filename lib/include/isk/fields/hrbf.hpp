// Hermite radial basis function (HRBF) implicit surface, eq. (1) of
// Vaillant et al. 2013 (after Wendland 2005 and Macedo et al. 2011):
//
//   d(x) = sum_k lambda_k phi(|x - c_k|) + beta_k . grad phi(|x - c_k|)
//          + a . x + b,        phi(r) = r^3,
//
// with d(c_k) = 0 and grad d(c_k) = n_k at every centre c_k (unit outward
// normals n_k), so d < 0 inside. The degree-1 polynomial (a, b) with its four
// orthogonality conditions (sum lambda_k = 0, sum lambda_k c_k - beta_k = 0)
// makes the system well posed for the cubic kernel.
//
// The solve is dense, in double precision (Eigen), in coordinates centred and
// scaled to the samples' extent, so the conditioning does not depend on the
// model's units. Samples closer than 1e-6 of the extent are merged first;
// a near-singular system falls back to a regularised least-squares solve;
// both leave a warning. Never NaN: a fit that still fails throws.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace isk {

namespace detail {
struct HrbfAccess;  // the field cache's (de)serializer
}  // namespace detail

// Hermite data: points with unit outward normals.
struct HermiteSamples {
  std::vector<Eigen::Vector3d> positions;
  std::vector<Eigen::Vector3d> normals;  // as many as positions
  // Number of samples.
  int size() const { return static_cast<int>(positions.size()); }
};

// A fitted HRBF: d(x) of eq. (1). Default-constructed: d = 0 everywhere.
class Hrbf {
 public:
  // Fits the samples (at least 4 after merging duplicates: otherwise
  // isk::Error kInvalidArgument naming `what` and the count). Warnings go to
  // `warnings` when given.
  static Hrbf fit(const HermiteSamples& samples, const std::string& what,
                  std::vector<std::string>* warnings = nullptr);

  // d(x) and grad d(x), in the samples' space (d in its length units,
  // negative inside). Never throw.
  double value(const Eigen::Vector3d& x) const;
  Eigen::Vector3d gradient(const Eigen::Vector3d& x) const;
  void evaluate(const Eigen::Vector3d& x, double& value,
                Eigen::Vector3d& gradient) const;

  // #C centres c_k after merging duplicates, in the samples' space.
  int centreCount() const { return static_cast<int>(centres_.size()); }
  const std::vector<Eigen::Vector3d>& centres() const { return centres_; }
  // Largest |d(c_k)| and |grad d(c_k) - n_k| of the fit (in the samples'
  // units and unitless), measured after the solve.
  double maxValueResidual() const { return value_residual_; }
  double maxGradientResidual() const { return gradient_residual_; }
  // True when the regularised fallback was used.
  bool regularised() const { return regularised_; }

  // Evaluation in the fit's normalised frame: x' = (x - origin) / scale;
  // d(x) = scale * d'(x'). Exposed for the bakers that evaluate in float.
  const Eigen::Vector3d& origin() const { return origin_; }
  double scale() const { return scale_; }
  // Normalised centres and coefficients: lambda (#C), beta (#C by 3), a, b.
  const std::vector<Eigen::Vector3d>& normalisedCentres() const {
    return unit_centres_;
  }
  const std::vector<double>& lambdas() const { return lambda_; }
  const std::vector<Eigen::Vector3d>& betas() const { return beta_; }
  const Eigen::Vector3d& linear() const { return poly_a_; }  // a
  double constant() const { return poly_b_; }                // b

 private:
  friend struct detail::HrbfAccess;
  std::vector<Eigen::Vector3d> centres_;
  std::vector<Eigen::Vector3d> unit_centres_;
  std::vector<double> lambda_;
  std::vector<Eigen::Vector3d> beta_;
  Eigen::Vector3d poly_a_ = Eigen::Vector3d::Zero();
  double poly_b_ = 0;
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
  double scale_ = 1;
  double value_residual_ = 0;
  double gradient_residual_ = 0;
  bool regularised_ = false;
};

// The re-parameterization t_r of section 4.1: maps d in [-r, r] smoothly onto
// [1, 0]; t_r(-r) = 1, t_r(0) = 0.5, t_r(r) = 0, zero slope at +-r; 1 below
// -r and 0 above r. d and r (> 0) in the same length units.
double reparameterize(double d, double r);
// dt_r/dd = (-15/16)(1/r)((d/r)^4 - 2(d/r)^2 + 1) inside, 0 outside.
double reparameterizeDerivative(double d, double r);

}  // namespace isk
