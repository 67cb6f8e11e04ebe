// The composition operators on their own (isk/fields/composition_operator.hpp):
// union, gradient-based blend (Appendix A) and bulge-in-contact, their
// controllers (Figure 7) and their baked tables.
#include "isk/fields/composition_operator.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "isk/core/error.hpp"

namespace isk {
namespace {

constexpr double kPi = 3.14159265358979323846;
const CompositionOperator kBaked[] = {CompositionOperator::kBlend,
                                      CompositionOperator::kBulge};

std::string nameOf(CompositionOperator op) {
  return compositionOperatorName(op);
}

// Random (f1, f2, theta) triples, the same every run.
struct Triple {
  double f1, f2, theta;
};
std::vector<Triple> randomTriples(int count, unsigned seed = 7) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Triple> out(count);
  for (Triple& t : out) t = {unit(rng), unit(rng), unit(rng) * kThetaUnion};
  return out;
}

TEST(CompositionOperator, NamesRoundTrip) {
  for (CompositionOperator op :
       {CompositionOperator::kUnion, CompositionOperator::kBlend,
        CompositionOperator::kBulge}) {
    CompositionOperator parsed = CompositionOperator::kUnion;
    ASSERT_TRUE(parseCompositionOperator(nameOf(op), &parsed)) << nameOf(op);
    EXPECT_EQ(parsed, op);
  }
  EXPECT_FALSE(parseCompositionOperator("Blend", nullptr));
  EXPECT_FALSE(parseCompositionOperator("", nullptr));
}

TEST(CompositionOperator, UnionIsMaxExactly) {
  for (const Triple& t : randomTriples(20000)) {
    const OperatorValue v = unionOperator(t.f1, t.f2);
    ASSERT_EQ(v.g, std::max(t.f1, t.f2)) << t.f1 << " " << t.f2;
    ASSERT_EQ(v.dg_df1, t.f1 >= t.f2 ? 1.0 : 0.0);
    ASSERT_EQ(v.dg_df2, t.f1 >= t.f2 ? 0.0 : 1.0);
  }
}

TEST(CompositionOperator, EqualsMaxOutsideItsBlendingRegion) {
  for (CompositionOperator op : kBaked) {
    SCOPED_TRACE(nameOf(op));
    int outside = 0, inside_differs = 0;
    for (const Triple& t : randomTriples(40000)) {
      const OperatorValue v = evaluateOperator(op, t.f1, t.f2, t.theta);
      if (!inBlendingRegion(op, t.f1, t.f2, t.theta)) {
        ++outside;
        ASSERT_EQ(v.g, std::max(t.f1, t.f2))
            << "f1 " << t.f1 << " f2 " << t.f2 << " theta " << t.theta;
      } else if (v.g > std::max(t.f1, t.f2) + 1e-6) {
        ++inside_differs;
      }
    }
    // Both kinds of points were met: the region is neither empty nor all.
    EXPECT_GT(outside, 10000);
    EXPECT_GT(inside_differs, 1000);
    // The region's documented edges: deep inside (> 0.7) and theta_u.
    EXPECT_EQ(evaluateOperator(op, 0.75, 0.6, 0.0).g, 0.75);
    EXPECT_EQ(evaluateOperator(op, 0.45, 0.4, kThetaUnion).g, 0.45);
  }
}

TEST(CompositionOperator, StaysInUnitIntervalAboveMaxAndIncreasing) {
  for (CompositionOperator op : kBaked) {
    SCOPED_TRACE(nameOf(op));
    for (const Triple& t : randomTriples(40000, 11)) {
      const OperatorValue v = evaluateOperator(op, t.f1, t.f2, t.theta);
      ASSERT_GE(v.g, std::max(t.f1, t.f2)) << t.f1 << " " << t.f2;
      ASSERT_LE(v.g, 1.0);
      // A field that grows inward stays so: both partials >= 0.
      ASSERT_GE(v.dg_df1, -1e-9) << t.f1 << " " << t.f2 << " " << t.theta;
      ASSERT_GE(v.dg_df2, -1e-9) << t.f1 << " " << t.f2 << " " << t.theta;
    }
    EXPECT_EQ(evaluateOperator(op, 0, 0, 0).g, 0.0);
    EXPECT_EQ(evaluateOperator(op, 1, 1, 0).g, 1.0);
  }
}

TEST(CompositionOperator, IsSymmetric) {
  for (CompositionOperator op : kBaked) {
    SCOPED_TRACE(nameOf(op));
    const OperatorTable& table = *sharedOperatorTable(op);
    for (const Triple& t : randomTriples(20000, 3)) {
      const OperatorValue a = evaluateOperator(op, t.f1, t.f2, t.theta);
      const OperatorValue b = evaluateOperator(op, t.f2, t.f1, t.theta);
      ASSERT_EQ(a.g, b.g) << t.f1 << " " << t.f2 << " " << t.theta;
      ASSERT_EQ(a.dg_df1, b.dg_df2);
      ASSERT_EQ(a.dg_df2, b.dg_df1);
      float ta[3], tb[3];
      const float f1 = static_cast<float>(t.f1), f2 = static_cast<float>(t.f2);
      table.sample(f1, f2, static_cast<float>(t.theta), ta);
      table.sample(f2, f1, static_cast<float>(t.theta), tb);
      ASSERT_EQ(ta[0], tb[0]);
      ASSERT_EQ(ta[1], tb[2]);
      ASSERT_EQ(ta[2], tb[1]);
    }
  }
}

// Sweeps f1 (f2 and theta fixed) across the 0.5 and 0.7 bands and the edges
// of the blending region in steps of 1e-5: no step may jump. Reading the
// blend's k_theta by the point's values instead of by C would jump by up
// to 0.09 at f1 = 0.5.
TEST(CompositionOperator, ContinuousAcrossThe05And07Bands) {
  const double step = 1e-5;
  for (CompositionOperator op : kBaked) {
    SCOPED_TRACE(nameOf(op));
    for (double theta : {0.0, 0.2, 0.5, 0.7}) {
      for (double f2 : {0.0, 0.15, 0.3, 0.42, 0.5, 0.6, 0.69}) {
        double previous = evaluateOperator(op, 0.2, f2, theta).g;
        double largest = 0;
        double where = 0;
        for (double f1 = 0.2 + step; f1 <= 0.8; f1 += step) {
          const double g = evaluateOperator(op, f1, f2, theta).g;
          if (std::abs(g - previous) > largest) {
            largest = std::abs(g - previous);
            where = f1;
          }
          previous = g;
        }
        // Steepest slope of either operator is below 4 (the blend's just
        // above C = 0.5 at theta = 0).
        EXPECT_LT(largest, 4 * step)
            << "theta " << theta << " f2 " << f2 << " jump at f1 " << where;
      }
    }
  }
}

TEST(CompositionOperator, BlendMatchesAppendixA) {
  // theta = 0: k = 0 below 0.5, the iso-curve C is the circle of radius C
  // around the origin.
  const double d = 0.5 / std::sqrt(2.0);
  EXPECT_NEAR(blendOperator(d, d, 0).g, 0.5, 1e-9);
  EXPECT_NEAR(blendOperator(0.3, 0.4, 0).g, 0.5, 1e-9);
  // Any theta: at C = 0.5 the opening is k = 0.5 tan(theta); the point
  // (k, 0.5) is where the circle meets the union's line, g = 0.5 there.
  for (double theta : {0.1, 0.4, 0.7}) {
    const double k = 0.5 * std::tan(theta);
    EXPECT_NEAR(blendOperator(0.5, k, theta).g, 0.5, 1e-9) << theta;
    // Below the opening it is the union.
    EXPECT_EQ(blendOperator(0.5, 0.999 * k, theta).g, 0.5) << theta;
    // On the diagonal: the circle's 45 degree point of C = 0.5.
    const double diagonal = k + (0.5 - k) / std::sqrt(2.0);
    EXPECT_NEAR(blendOperator(diagonal, diagonal, theta).g, 0.5, 1e-9);
  }
  // Inner part: a point on the C = 0.6 circle (theta = 0: k = 0.35, radius
  // 0.25).
  const double r = 0.25 / std::sqrt(2.0);
  EXPECT_NEAR(blendOperator(0.35 + r, 0.35 + r, 0).g, 0.6, 1e-9);
}

TEST(CompositionOperator, PartialsMatchFiniteDifferences) {
  const double h = 1e-6;
  for (CompositionOperator op : kBaked) {
    SCOPED_TRACE(nameOf(op));
    double worst = 0;
    int checked = 0;
    for (const Triple& t : randomTriples(20000, 5)) {
      const OperatorValue v = evaluateOperator(op, t.f1, t.f2, t.theta);
      // Away from the creases: the diagonal (the max's), C = 0.5 (the
      // blend's change of k) and the 0.7 corner.
      if (std::abs(t.f1 - t.f2) < 1e-3 || std::abs(v.g - 0.5) < 1e-3 ||
          std::max(t.f1, t.f2) > 0.69 || std::max(t.f1, t.f2) < 1e-3)
        continue;
      const double d1 = (evaluateOperator(op, t.f1 + h, t.f2, t.theta).g -
                         evaluateOperator(op, t.f1 - h, t.f2, t.theta).g) /
                        (2 * h);
      const double d2 = (evaluateOperator(op, t.f1, t.f2 + h, t.theta).g -
                         evaluateOperator(op, t.f1, t.f2 - h, t.theta).g) /
                        (2 * h);
      worst =
          std::max({worst, std::abs(d1 - v.dg_df1), std::abs(d2 - v.dg_df2)});
      ++checked;
    }
    EXPECT_GT(checked, 8000);
    EXPECT_LT(worst, 1e-4);
  }
}

// The baked table against the directly solved operator: values within the
// stated error (max 2e-3 for the blend, at its corner (0.7, 0.7); 5e-4 for
// the bulge; 99% within 3e-4), stored partials within 1e-4 of finite
// differences of the solved operator at the nodes (away from creases).
TEST(OperatorTable, MatchesTheSolvedOperator) {
  for (CompositionOperator op : kBaked) {
    SCOPED_TRACE(nameOf(op));
    const OperatorTable& table = *sharedOperatorTable(op);
    ASSERT_EQ(table.resolution, 128);
    ASSERT_EQ(table.bytes(), 128u * 128 * 128 * 16);
    std::vector<double> errors;
    for (const Triple& t : randomTriples(100000, 9)) {
      float out[3];
      table.sample(static_cast<float>(t.f1), static_cast<float>(t.f2),
                   static_cast<float>(t.theta), out);
      errors.push_back(
          std::abs(out[0] - evaluateOperator(op, t.f1, t.f2, t.theta).g));
    }
    std::sort(errors.begin(), errors.end());
    EXPECT_LT(errors.back(), op == CompositionOperator::kBlend ? 2e-3 : 5e-4);
    EXPECT_LT(errors[errors.size() * 99 / 100], 3e-4);

    const int n = table.resolution;
    const double h = 1e-6;
    double worst = 0;
    int checked = 0;
    std::mt19937 rng(1);
    std::uniform_int_distribution<int> node(0, n - 1);
    for (int s = 0; s < 20000; ++s) {
      const int i = node(rng), j = node(rng), k = node(rng);
      if (j > i) continue;  // the stored branch: x >= y
      const double x = i / (n - 1.0), y = j / (n - 1.0);
      const double theta = kThetaUnion * k / (n - 1.0);
      const double g = evaluateOperator(op, x, y, theta).g;
      if (i - j < 1 || x < 1e-3 || x > 0.69 || std::abs(g - 0.5) < 1e-3)
        continue;
      const float* stored = &table.nodes[4 * (i + n * (j + n * k))];
      EXPECT_NEAR(stored[0], g, 1e-6);
      const double d1 = (evaluateOperator(op, x + h, y, theta).g -
                         evaluateOperator(op, x - h, y, theta).g) /
                        (2 * h);
      const double d2 = (evaluateOperator(op, x, y + h, theta).g -
                         evaluateOperator(op, x, y - h, theta).g) /
                        (2 * h);
      worst =
          std::max({worst, std::abs(stored[1] - d1), std::abs(stored[2] - d2)});
      ++checked;
    }
    EXPECT_GT(checked, 3000);
    EXPECT_LT(worst, 1e-4);
  }
}

// In a union region the table is exactly the max (G = x is linear, which
// trilinear interpolation reproduces), so the contact crease stays sharp.
TEST(OperatorTable, KeepsTheUnionAndItsCreaseExact) {
  for (CompositionOperator op : kBaked) {
    SCOPED_TRACE(nameOf(op));
    const OperatorTable& table = *sharedOperatorTable(op);
    for (const Triple& t : randomTriples(20000, 13)) {
      float out[3];
      const float f1 = static_cast<float>(t.f1), f2 = static_cast<float>(t.f2);
      table.sample(f1, f2, static_cast<float>(kThetaUnion), out);
      ASSERT_NEAR(out[0], std::max(f1, f2), 2e-7) << f1 << " " << f2;
      ASSERT_EQ(out[1], f1 >= f2 ? 1.f : 0.f);
      ASSERT_EQ(out[2], f1 >= f2 ? 0.f : 1.f);
      table.sample(0.8f + 0.2f * f1, 0.8f * f2, static_cast<float>(t.theta),
                   out);
      ASSERT_NEAR(out[0], 0.8f + 0.2f * f1, 2e-7);  // deeper than 0.7
    }
  }
}

TEST(OperatorTable, RejectsWhatCannotBeBaked) {
  EXPECT_THROW(bakeOperatorTable(CompositionOperator::kUnion), Error);
  EXPECT_THROW(bakeOperatorTable(CompositionOperator::kBlend, 1), Error);
  EXPECT_THROW(bakeOperatorTable(CompositionOperator::kBlend, 513), Error);
  // A small table bakes and has its documented layout.
  const OperatorTable t = bakeOperatorTable(CompositionOperator::kBulge, 5, 1);
  EXPECT_EQ(t.nodes.size(), 5u * 5 * 5 * 4);
  // Node (4, 2, 0): x = 1, y = 0.5, theta = 0: deeper than 0.7, the max.
  EXPECT_EQ(t.nodes[4 * (4 + 5 * 2)], 1.f);
}

TEST(ThetaController, FollowsFigure7) {
  const float quarter = static_cast<float>(kPi / 4);
  const float half = static_cast<float>(kPi / 2);
  const float u = static_cast<float>(kThetaUnion);
  const ThetaController blend = blendController(0.1);
  ASSERT_EQ(blend.theta.size(), static_cast<size_t>(kControllerSamples));
  EXPECT_NEAR(blend.at(0), u, 1e-6);
  EXPECT_NEAR(blend.at(quarter), 0.1, 2e-3);  // the full blend at pi/4
  for (float a = half; a <= 3.1416f; a += 0.1f)
    EXPECT_NEAR(blend.at(a), u, 1e-6) << a;  // union again from pi/2 on
  const ThetaController bulge = bulgeController(0.5);
  EXPECT_NEAR(bulge.at(0), u, 1e-6);
  for (float a = half; a <= 3.1416f; a += 0.1f)
    EXPECT_NEAR(bulge.at(a), u * 0.5f, 1e-6) << a;  // maximal, then constant
  // Monotone between the ends.
  for (float a = 0; a + 0.01f < half; a += 0.01f) {
    EXPECT_GE(bulge.at(a), bulge.at(a + 0.01f)) << a;
    if (a + 0.01f < quarter) EXPECT_GE(blend.at(a), blend.at(a + 0.01f)) << a;
  }
  const ThetaController none = unionController();
  EXPECT_EQ(none.at(1.0f), u);
  EXPECT_EQ(bulgeController(0).at(2.0f), u);  // strength 0: a union
}

}  // namespace
}  // namespace isk
