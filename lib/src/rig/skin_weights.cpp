#include "isk/rig/skin_weights.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <string>

namespace isk {

int SkinWeights::maxInfluences() const {
  int most = 0;
  for (int v = 0; v < vertexCount(); ++v)
    most = std::max(most, influenceCount(v));
  return most;
}

SkinWeights SkinWeights::fromLists(
    const std::vector<std::vector<std::pair<int, float>>>& per_vertex) {
  SkinWeights result;
  result.offsets.reserve(per_vertex.size() + 1);
  result.offsets.push_back(0);
  for (const auto& list : per_vertex) {
    std::map<int, float> merged;  // repeated joints of one vertex add up
    for (const auto& [joint, weight] : list) {
      if (weight != 0.f) merged[joint] += weight;
    }
    for (const auto& [joint, weight] : merged) {
      result.joints.push_back(static_cast<uint32_t>(joint));
      result.weights.push_back(weight);
    }
    result.offsets.push_back(static_cast<uint32_t>(result.joints.size()));
  }
  return result;
}

void SkinWeights::sortByWeight() {
  std::vector<std::pair<float, uint32_t>> row;
  for (int v = 0; v < vertexCount(); ++v) {
    row.clear();
    for (uint32_t i = offsets[v]; i < offsets[v + 1]; ++i) {
      row.emplace_back(weights[i], joints[i]);
    }
    std::sort(row.begin(), row.end(), [](const auto& a, const auto& b) {
      return a.first != b.first ? a.first > b.first : a.second < b.second;
    });
    for (size_t k = 0; k < row.size(); ++k) {
      weights[offsets[v] + k] = row[k].first;
      joints[offsets[v] + k] = row[k].second;
    }
  }
}

SkinWeights::NormalizeReport SkinWeights::normalize(float tolerance) {
  NormalizeReport report;
  bool first = true;
  for (int v = 0; v < vertexCount(); ++v) {
    double sum = 0;
    for (uint32_t i = offsets[v]; i < offsets[v + 1]; ++i) sum += weights[i];
    if (sum <= 0) continue;  // validate() reports vertices without weight
    if (std::abs(sum - 1.0) > tolerance) {
      ++report.off_count;
      report.min_sum =
          first ? float(sum) : std::min(report.min_sum, float(sum));
      report.max_sum =
          first ? float(sum) : std::max(report.max_sum, float(sum));
      first = false;
    }
    for (uint32_t i = offsets[v]; i < offsets[v + 1]; ++i) {
      weights[i] = static_cast<float>(weights[i] / sum);
    }
  }
  return report;
}

Validation SkinWeights::validate(int vertex_count, int joint_count) const {
  if (vertexCount() != vertex_count) {
    return Validation::fail("skin weights have " +
                            std::to_string(vertexCount()) + " rows for " +
                            std::to_string(vertex_count) + " vertices");
  }
  if (joints.size() != weights.size() || offsets.empty() || offsets[0] != 0 ||
      offsets.back() != joints.size()) {
    return Validation::fail("skin weight arrays are inconsistent");
  }
  for (int v = 0; v < vertex_count; ++v) {
    if (offsets[v + 1] < offsets[v]) {
      return Validation::fail("skin weight offsets decrease at vertex " +
                              std::to_string(v));
    }
    if (offsets[v + 1] == offsets[v]) {
      return Validation::fail("vertex " + std::to_string(v) +
                              " has no skin weight");
    }
    double sum = 0;
    for (uint32_t i = offsets[v]; i < offsets[v + 1]; ++i) {
      if (joints[i] >= static_cast<uint32_t>(joint_count)) {
        return Validation::fail("vertex " + std::to_string(v) +
                                " is weighted to joint " +
                                std::to_string(joints[i]) + " (there are " +
                                std::to_string(joint_count) + " joints)");
      }
      if (!std::isfinite(weights[i]) || weights[i] < 0.f) {
        return Validation::fail("vertex " + std::to_string(v) +
                                " has an invalid weight " +
                                std::to_string(weights[i]));
      }
      sum += weights[i];
    }
    if (std::abs(sum - 1.0) > 1e-3) {
      return Validation::fail("vertex " + std::to_string(v) +
                              " has weights summing to " + std::to_string(sum));
    }
  }
  return Validation::ok();
}

}  // namespace isk
