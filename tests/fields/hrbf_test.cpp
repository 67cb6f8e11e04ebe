// The HRBF fit (eq. 1) and the re-parameterization t_r of section 4.1, on
// synthetic Hermite data: interpolation, the properties of t_r, and the
// guarded solve (duplicates, clustered samples, too few samples, bad input).
#include "isk/fields/hrbf.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "isk/core/error.hpp"

namespace isk {
namespace {

// Points of a sphere (Fibonacci lattice) with outward normals.
HermiteSamples sphereSamples(int count, const Eigen::Vector3d& centre,
                             double radius) {
  HermiteSamples s;
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    const double y = 1.0 - 2.0 * (i + 0.5) / count;
    const double ring = std::sqrt(1.0 - y * y);
    const Eigen::Vector3d n(ring * std::cos(golden * i), y,
                            ring * std::sin(golden * i));
    s.positions.push_back(centre + radius * n);
    s.normals.push_back(n);
  }
  return s;
}

TEST(Hrbf, InterpolatesPositionsAndNormalsAtEveryScale) {
  // The same shape at the scale of centimetres and of a 100x unit
  // conversion: the normalised solve makes the residuals scale-free.
  for (double radius : {0.01, 1.0, 250.0}) {
    const HermiteSamples samples =
        sphereSamples(50, Eigen::Vector3d(3 * radius, -radius, 0), radius);
    std::vector<std::string> warnings;
    const Hrbf h = Hrbf::fit(samples, "sphere", &warnings);
    EXPECT_TRUE(warnings.empty()) << warnings.front();
    EXPECT_FALSE(h.regularised());
    for (int k = 0; k < samples.size(); ++k) {
      double d;
      Eigen::Vector3d g;
      h.evaluate(samples.positions[k], d, g);
      ASSERT_LT(std::abs(d), 1e-9 * radius) << "sample " << k;
      ASSERT_LT((g - samples.normals[k]).norm(), 1e-9) << "sample " << k;
    }
    EXPECT_LT(h.maxValueResidual(), 1e-9 * radius);
    EXPECT_LT(h.maxGradientResidual(), 1e-9);
    // Negative inside, positive outside, and close to the signed distance
    // near the surface.
    const Eigen::Vector3d centre(3 * radius, -radius, 0);
    EXPECT_LT(h.value(centre), 0);
    EXPECT_GT(h.value(centre + Eigen::Vector3d(1.5 * radius, 0, 0)), 0);
    EXPECT_NEAR(h.value(centre + Eigen::Vector3d(0, 0, 1.1 * radius)),
                0.1 * radius, 0.02 * radius);
  }
}

TEST(Hrbf, GradientIsTheDerivativeOfTheValue) {
  const HermiteSamples samples = sphereSamples(40, Eigen::Vector3d::Zero(), 1);
  const Hrbf h = Hrbf::fit(samples, "sphere");
  const double step = 1e-6;
  for (const Eigen::Vector3d& x :
       {Eigen::Vector3d(0.3, 0.2, -0.1), Eigen::Vector3d(1.2, -0.4, 0.7),
        Eigen::Vector3d(-2, 1, 0.5)}) {
    Eigen::Vector3d numeric;
    for (int a = 0; a < 3; ++a) {
      Eigen::Vector3d e = Eigen::Vector3d::Zero();
      e[a] = step;
      numeric[a] = (h.value(x + e) - h.value(x - e)) / (2 * step);
    }
    EXPECT_LT((numeric - h.gradient(x)).norm(), 1e-6) << x.transpose();
  }
}

TEST(Hrbf, MergesDuplicateSamplesWithAWarning) {
  HermiteSamples samples = sphereSamples(30, Eigen::Vector3d::Zero(), 1);
  samples.positions.push_back(samples.positions[4] +
                              Eigen::Vector3d(1e-9, 0, 0));
  samples.normals.push_back(samples.normals[4]);
  std::vector<std::string> warnings;
  const Hrbf h = Hrbf::fit(samples, "joint 'dup'", &warnings);
  EXPECT_EQ(h.centreCount(), 30);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("joint 'dup'"), std::string::npos);
  EXPECT_NE(warnings[0].find("duplicate"), std::string::npos);
  EXPECT_TRUE(std::isfinite(h.value(Eigen::Vector3d(0.1, 0.2, 0.3))));
}

TEST(Hrbf, NearlyCoincidentSamplesWithOpposedNormalsStayFinite) {
  // Two samples 1e-5 apart (above the merge distance) with opposite
  // normals: a nearly singular system. The guarded solve never gives NaN.
  HermiteSamples samples = sphereSamples(20, Eigen::Vector3d::Zero(), 1);
  samples.positions.push_back(samples.positions[0] +
                              Eigen::Vector3d(1e-5, 0, 0));
  samples.normals.push_back(-samples.normals[0]);
  std::vector<std::string> warnings;
  const Hrbf h = Hrbf::fit(samples, "joint 'close'", &warnings);
  for (const Eigen::Vector3d& x :
       {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(2, 0, 0),
        samples.positions[0]}) {
    double d;
    Eigen::Vector3d g;
    h.evaluate(x, d, g);
    EXPECT_TRUE(std::isfinite(d));
    EXPECT_TRUE(g.allFinite());
  }
  // The other samples are still interpolated.
  for (int k = 1; k < 20; ++k)
    EXPECT_LT(std::abs(h.value(samples.positions[k])), 1e-3) << "sample " << k;
}

TEST(Hrbf, RejectsTooFewSamplesAndBadData) {
  HermiteSamples three = sphereSamples(3, Eigen::Vector3d::Zero(), 1);
  try {
    Hrbf::fit(three, "joint 'tiny'");
    FAIL() << "3 samples were accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("joint 'tiny'"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("at least 4"), std::string::npos);
  }
  HermiteSamples nan = sphereSamples(10, Eigen::Vector3d::Zero(), 1);
  nan.positions[6].x() = std::nan("");
  EXPECT_THROW(Hrbf::fit(nan, "joint 'nan'"), Error);
  HermiteSamples zero_normal = sphereSamples(10, Eigen::Vector3d::Zero(), 1);
  zero_normal.normals[2].setZero();
  EXPECT_THROW(Hrbf::fit(zero_normal, "joint 'flat'"), Error);
  HermiteSamples mismatched = sphereSamples(10, Eigen::Vector3d::Zero(), 1);
  mismatched.normals.pop_back();
  EXPECT_THROW(Hrbf::fit(mismatched, "joint 'odd'"), Error);
}

TEST(Reparameterization, MatchesSection41) {
  for (double r : {0.01, 1.0, 40.0}) {
    EXPECT_DOUBLE_EQ(reparameterize(0, r), 0.5);
    EXPECT_DOUBLE_EQ(reparameterize(-r, r), 1.0);
    EXPECT_DOUBLE_EQ(reparameterize(r, r), 0.0);
    EXPECT_DOUBLE_EQ(reparameterize(-3 * r, r), 1.0);
    EXPECT_DOUBLE_EQ(reparameterize(5 * r, r), 0.0);
    // Continuous at +-r, with a zero slope on both sides.
    const double eps = 1e-7 * r;
    EXPECT_NEAR(reparameterize(-r + eps, r), 1.0, 1e-12);
    EXPECT_NEAR(reparameterize(r - eps, r), 0.0, 1e-12);
    EXPECT_NEAR(reparameterizeDerivative(-r + eps, r) * r, 0.0, 1e-9);
    EXPECT_NEAR(reparameterizeDerivative(r - eps, r) * r, 0.0, 1e-9);
    EXPECT_EQ(reparameterizeDerivative(-r - eps, r), 0.0);
    EXPECT_EQ(reparameterizeDerivative(r + eps, r), 0.0);
    // The derivative is the slope of the function, and it decreases.
    double previous = 1.0;
    for (int i = -99; i < 100; ++i) {
      const double d = r * i / 100.0;
      const double h = 1e-6 * r;
      const double numeric =
          (reparameterize(d + h, r) - reparameterize(d - h, r)) / (2 * h);
      EXPECT_NEAR(reparameterizeDerivative(d, r) * r, numeric * r, 1e-6)
          << "d = " << d;
      EXPECT_LT(reparameterize(d, r), previous) << "d = " << d;
      previous = reparameterize(d, r);
    }
    EXPECT_NEAR(reparameterizeDerivative(0, r) * r, -15.0 / 16.0, 1e-12);
  }
}

}  // namespace
}  // namespace isk
