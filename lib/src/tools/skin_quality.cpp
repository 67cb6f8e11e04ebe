#include "isk/tools/skin_quality.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <iterator>
#include <map>
#include <string>
#include <unordered_map>

#include "isk/core/error.hpp"
#include "isk/tools/mesh_metrics.hpp"
#include "isk/tools/self_intersection.hpp"

namespace isk {

namespace {

std::vector<std::pair<int, int>> pairsOf(const Matrix3Xf& positions,
                                         const TriangleMatrix& triangles,
                                         const std::vector<int>& groups) {
  std::vector<std::pair<int, int>> pairs;
  countSelfIntersections(positions, triangles, &groups, &pairs);
  return pairs;
}

std::vector<std::pair<int, int>> notIn(
    const std::vector<std::pair<int, int>>& pairs,
    const std::vector<std::pair<int, int>>& excluded) {
  std::vector<std::pair<int, int>> out;
  std::set_difference(pairs.begin(), pairs.end(), excluded.begin(),
                      excluded.end(), std::back_inserter(out));
  return out;
}

void checkRows(const Matrix3Xf& m, size_t rows, const char* what) {
  if (static_cast<size_t>(m.rows()) != rows) {
    throw Error(ErrorCode::kInvalidArgument,
                std::string("SkinQuality::measure: ") + what + " has " +
                    std::to_string(m.rows()) + " rows for " +
                    std::to_string(rows) + " vertices");
  }
}

// Integer cell of a point on a grid of `cell`-sized cubes.
struct Cell {
  int64_t x, y, z;
  int64_t key() const {
    return (x & 0x1fffff) | ((y & 0x1fffff) << 21) | ((z & 0x1fffff) << 42);
  }
};

Cell cellOf(const Eigen::RowVector3f& p, float cell) {
  return {static_cast<int64_t>(std::floor(p.x() / cell)),
          static_cast<int64_t>(std::floor(p.y() / cell)),
          static_cast<int64_t>(std::floor(p.z() / cell))};
}

// Adds to each part's `count` the pairs (triangle indices) with a corner of
// either triangle in it, once per pair and part; `index` maps part ids to
// `parts`.
void countPartPairs(const std::vector<std::pair<int, int>>& pairs,
                    const TriangleMatrix& triangles,
                    const std::vector<int>& vertex_parts,
                    const std::map<int, size_t>& index,
                    long long PartQuality::*count,
                    std::vector<PartQuality>* parts) {
  std::vector<size_t> touched;
  for (const auto& [t0, t1] : pairs) {
    touched.clear();
    for (const int t : {t0, t1})
      for (int c = 0; c < 3; ++c) {
        const auto it = index.find(vertex_parts[triangles(t, c)]);
        if (it != index.end()) touched.push_back(it->second);
      }
    std::sort(touched.begin(), touched.end());
    touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
    for (const size_t k : touched) ++((*parts)[k].*count);
  }
}

// The angle (radians, in (-pi, pi]) of the hinge's second wing (its
// corner d) around the edge a-b, from its first wing (corner c), in the
// plane across the edge: +-pi where the two triangles lie flat, 0 where
// they fold onto each other. Unset where the edge or a wing is degenerate.
std::optional<double> hingeAngle(const Matrix3Xf& x,
                                 const std::array<int, 4>& hinge) {
  const Eigen::Vector3d a = x.row(hinge[0]).transpose().cast<double>();
  Eigen::Vector3d e = x.row(hinge[1]).transpose().cast<double>() - a;
  const double length = e.norm();
  if (!(length > 0)) return std::nullopt;
  e /= length;
  Eigen::Vector3d u = x.row(hinge[2]).transpose().cast<double>() - a;
  Eigen::Vector3d w = x.row(hinge[3]).transpose().cast<double>() - a;
  u -= u.dot(e) * e;
  w -= w.dot(e) * e;
  const double u_length = u.norm(), w_length = w.norm();
  const double degenerate = 1e-6 * length;
  if (!(u_length > degenerate) || !(w_length > degenerate)) return std::nullopt;
  u /= u_length;
  const Eigen::Vector3d v = e.cross(u);
  return std::atan2(w.dot(v), w.dot(u));
}

}  // namespace

SkinQuality::SkinQuality(const Mesh& rest, std::vector<int> vertex_groups,
                         SkinQualityOptions options)
    : triangles_(rest.triangles),
      groups_(std::move(vertex_groups)),
      options_(options) {
  const size_t vertex_count = rest.positions.rows();
  if (groups_.size() != vertex_count) {
    throw Error(ErrorCode::kInvalidArgument,
                "SkinQuality: " + std::to_string(groups_.size()) +
                    " vertex groups for " + std::to_string(vertex_count) +
                    " vertices");
  }
  for (size_t v = 0; v < vertex_count; ++v) {
    if (groups_[v] < 0 || static_cast<size_t>(groups_[v]) >= vertex_count) {
      throw Error(ErrorCode::kInvalidArgument,
                  "SkinQuality: vertex " + std::to_string(v) + " has group " +
                      std::to_string(groups_[v]) + ", not a vertex index");
    }
  }
  const std::vector<int>& parts = options_.vertex_parts;
  if (!parts.empty() && parts.size() != vertex_count) {
    throw Error(ErrorCode::kInvalidArgument,
                "SkinQuality: " + std::to_string(parts.size()) +
                    " vertex parts for " + std::to_string(vertex_count) +
                    " vertices");
  }
  for (size_t v = 0; v < parts.size(); ++v) {
    if (parts[v] < -1) {
      throw Error(ErrorCode::kInvalidArgument,
                  "SkinQuality: vertex " + std::to_string(v) + " has part " +
                      std::to_string(parts[v]) + " (expected -1 or more)");
    }
  }
  if (!(options_.crumple_degrees > 0 && options_.crumple_degrees <= 180)) {
    throw Error(ErrorCode::kInvalidArgument,
                "SkinQuality: crumple_degrees is " +
                    std::to_string(options_.crumple_degrees) +
                    " (expected more than 0 and at most 180)");
  }
  diagonal_ = boundingBoxDiagonal(rest.positions);
  rest_pairs_ = pairsOf(rest.positions, triangles_, groups_);
  rest_volume_ = enclosedVolume(rest.positions, triangles_);
  const double d = diagonal_;
  volume_meaningful_ = d > 0 && std::abs(rest_volume_) > 1e-6 * d * d * d;
  if (volume_meaningful_) {
    rest_covered_volume_ = coveredVolume(rest.positions, triangles_);
    volume_meaningful_ = rest_covered_volume_ > 0;
  }

  // The welded edges, each once, with their rest lengths.
  for (Eigen::Index f = 0; f < triangles_.rows(); ++f) {
    for (int c = 0; c < 3; ++c) {
      int a = groups_[triangles_(f, c)];
      int b = groups_[triangles_(f, (c + 1) % 3)];
      if (a == b) continue;
      if (a > b) std::swap(a, b);
      edges_.emplace_back(a, b);
    }
  }
  std::sort(edges_.begin(), edges_.end());
  edges_.erase(std::unique(edges_.begin(), edges_.end()), edges_.end());
  std::vector<std::pair<int, int>> kept;
  for (const auto& [a, b] : edges_) {
    const float length = (rest.positions.row(a) - rest.positions.row(b)).norm();
    // A zero-length rest edge has no strain to speak of.
    if (length > 0) {
      kept.emplace_back(a, b);
      edge_rest_lengths_.push_back(length);
    }
  }
  edges_ = std::move(kept);

  // The hinges: welded edges of exactly two triangles (boundary and
  // non-manifold edges have no bending angle to speak of).
  std::map<std::pair<int, int>, std::vector<int>> wings;  // opposite corners
  for (Eigen::Index f = 0; f < triangles_.rows(); ++f) {
    const int g[3] = {groups_[triangles_(f, 0)], groups_[triangles_(f, 1)],
                      groups_[triangles_(f, 2)]};
    if (g[0] == g[1] || g[1] == g[2] || g[2] == g[0]) continue;
    for (int c = 0; c < 3; ++c) {
      const int a = g[c], b = g[(c + 1) % 3];
      wings[{std::min(a, b), std::max(a, b)}].push_back(g[(c + 2) % 3]);
    }
  }
  for (const auto& [edge, corners] : wings) {
    if (corners.size() != 2 || corners[0] == corners[1]) continue;
    const std::array<int, 4> hinge = {edge.first, edge.second, corners[0],
                                      corners[1]};
    const std::optional<double> angle = hingeAngle(rest.positions, hinge);
    if (!angle) continue;
    hinges_.push_back(hinge);
    hinge_rest_angles_.push_back(static_cast<float>(*angle));
  }

  // Each part's edges: those with an end in it, once.
  if (!parts.empty()) {
    std::map<int, std::vector<int>> by_part;
    for (size_t e = 0; e < edges_.size(); ++e) {
      const int pa = parts[edges_[e].first], pb = parts[edges_[e].second];
      if (pa >= 0) by_part[pa].push_back(static_cast<int>(e));
      if (pb >= 0 && pb != pa) by_part[pb].push_back(static_cast<int>(e));
    }
    for (auto& [part, edges] : by_part) {
      part_ids_.push_back(part);
      part_edges_.push_back(std::move(edges));
    }
  }
}

std::vector<uint8_t> SkinQuality::crumpledHinges(
    const Matrix3Xf& positions) const {
  const double crumple = options_.crumple_degrees * M_PI / 180.0;
  std::vector<uint8_t> out(hinges_.size(), 0);
  for (size_t h = 0; h < hinges_.size(); ++h) {
    const std::optional<double> angle = hingeAngle(positions, hinges_[h]);
    if (!angle) continue;
    // The change of the bending angle, wrapped to [0, pi].
    double change = std::abs(*angle - hinge_rest_angles_[h]);
    if (change > M_PI) change = 2 * M_PI - change;
    out[h] = change > crumple;
  }
  return out;
}

std::vector<uint8_t> SkinQuality::contactRegion(
    const Matrix3Xf& reference, const std::vector<uint8_t>* contacts,
    const std::vector<std::pair<int, int>>& reference_new_pairs) const {
  const size_t vertex_count = groups_.size();
  std::vector<uint8_t> seed(vertex_count, 0);
  if (contacts) {
    for (size_t v = 0; v < vertex_count; ++v)
      if ((*contacts)[v]) seed[groups_[v]] = 1;
  }
  for (const auto& [f, g] : reference_new_pairs) {
    for (int c = 0; c < 3; ++c) {
      seed[groups_[triangles_(f, c)]] = 1;
      seed[groups_[triangles_(g, c)]] = 1;
    }
  }
  const float radius = options_.contact_radius * diagonal_;
  std::vector<uint8_t> region(vertex_count, 0);
  if (!(radius > 0)) {
    for (size_t v = 0; v < vertex_count; ++v) region[v] = seed[groups_[v]];
    return region;
  }
  std::unordered_map<int64_t, std::vector<int>> cells;
  for (size_t v = 0; v < vertex_count; ++v) {
    if (seed[v]) cells[cellOf(reference.row(v), radius).key()].push_back(v);
  }
  if (cells.empty()) return region;
  const float radius2 = radius * radius;
  for (size_t v = 0; v < vertex_count; ++v) {
    if (groups_[v] != static_cast<int>(v)) continue;
    const Cell c = cellOf(reference.row(v), radius);
    bool near = false;
    for (int dx = -1; dx <= 1 && !near; ++dx)
      for (int dy = -1; dy <= 1 && !near; ++dy)
        for (int dz = -1; dz <= 1 && !near; ++dz) {
          const auto it = cells.find(Cell{c.x + dx, c.y + dy, c.z + dz}.key());
          if (it == cells.end()) continue;
          for (const int s : it->second) {
            if ((reference.row(v) - reference.row(s)).squaredNorm() <=
                radius2) {
              near = true;
              break;
            }
          }
        }
    region[v] = near;
  }
  for (size_t v = 0; v < vertex_count; ++v) region[v] = region[groups_[v]];
  return region;
}

FrameQuality SkinQuality::measure(const Matrix3Xf& positions,
                                  const Matrix3Xf* dqs,
                                  const std::vector<uint8_t>* contacts,
                                  int lost) {
  const size_t vertex_count = groups_.size();
  checkRows(positions, vertex_count, "the frame");
  if (dqs) checkRows(*dqs, vertex_count, "the DQS frame");
  if (contacts && contacts->size() != vertex_count) {
    throw Error(ErrorCode::kInvalidArgument,
                "SkinQuality::measure: " + std::to_string(contacts->size()) +
                    " contact flags for " + std::to_string(vertex_count) +
                    " vertices");
  }
  FrameQuality q;
  q.lost_vertices = lost;
  last_pairs_ = pairsOf(positions, triangles_, groups_);
  last_new_pairs_ = notIn(last_pairs_, rest_pairs_);
  q.self_intersections = static_cast<int>(last_pairs_.size());
  q.new_self_intersections = static_cast<int>(last_new_pairs_.size());
  if (volume_meaningful_) {
    q.volume_ratio = enclosedVolume(positions, triangles_) / rest_volume_;
    q.covered_volume_ratio =
        coveredVolume(positions, triangles_) / rest_covered_volume_;
  }

  double strain_sum = 0;
  for (size_t e = 0; e < edges_.size(); ++e) {
    const auto [a, b] = edges_[e];
    const double strain = std::abs(
        (positions.row(a) - positions.row(b)).norm() / edge_rest_lengths_[e] -
        1.0);
    strain_sum += strain;
    q.edge_strain_max = std::max(q.edge_strain_max, strain);
  }
  if (!edges_.empty()) q.edge_strain_mean = strain_sum / edges_.size();

  const std::vector<uint8_t> crumpled = crumpledHinges(positions);
  q.crumpled_edges = static_cast<int>(
      std::count(crumpled.begin(), crumpled.end(), uint8_t{1}));

  const Matrix3Xf& reference = dqs ? *dqs : positions;
  const std::vector<std::pair<int, int>> reference_new =
      dqs ? notIn(pairsOf(*dqs, triangles_, groups_), rest_pairs_)
          : last_new_pairs_;
  if (!part_ids_.empty()) {
    auto strainOf = [&](const Matrix3Xf& x, int e) {
      const auto [a, b] = edges_[e];
      return std::abs((x.row(a) - x.row(b)).norm() / edge_rest_lengths_[e] -
                      1.0);
    };
    std::map<int, size_t> index;
    q.parts.resize(part_ids_.size());
    for (size_t k = 0; k < part_ids_.size(); ++k) {
      PartQuality& part = q.parts[k];
      part.part = part_ids_[k];
      part.edges = static_cast<int>(part_edges_[k].size());
      for (const int e : part_edges_[k]) {
        part.edge_strain_mean += strainOf(positions, e);
        part.dqs_edge_strain_mean += strainOf(reference, e);
      }
      part.edge_strain_mean /= part.edges;
      part.dqs_edge_strain_mean /= part.edges;
      index[part.part] = k;
    }
    const double inverse = diagonal_ > 0 ? 1.0 / diagonal_ : 1.0;
    for (size_t v = 0; v < vertex_count; ++v) {
      const int part = options_.vertex_parts[v];
      if (groups_[v] != static_cast<int>(v) || part < 0) continue;
      const auto it = index.find(part);
      if (it == index.end()) continue;
      double& largest = q.parts[it->second].dqs_distance_max;
      largest = std::max(
          largest, (positions.row(v) - reference.row(v)).norm() * inverse);
    }
    countPartPairs(last_new_pairs_, triangles_, options_.vertex_parts, index,
                   &PartQuality::new_pairs, &q.parts);
    countPartPairs(reference_new, triangles_, options_.vertex_parts, index,
                   &PartQuality::dqs_new_pairs, &q.parts);
    // Each crumpled hinge once in each part of its two ends.
    auto countCrumpled = [&](const std::vector<uint8_t>& flags,
                             long long PartQuality::*count) {
      for (size_t h = 0; h < hinges_.size(); ++h) {
        if (!flags[h]) continue;
        const int pa = options_.vertex_parts[hinges_[h][0]];
        const int pb = options_.vertex_parts[hinges_[h][1]];
        auto add = [&](int part) {
          const auto it = index.find(part);
          if (it != index.end()) ++(q.parts[it->second].*count);
        };
        add(pa);
        if (pb != pa) add(pb);
      }
    };
    countCrumpled(crumpled, &PartQuality::crumpled_edges);
    countCrumpled(dqs ? crumpledHinges(*dqs) : crumpled,
                  &PartQuality::dqs_crumpled_edges);
  }
  const std::vector<uint8_t> region =
      contactRegion(reference, contacts, reference_new);
  const double scale = diagonal_ > 0 ? 1.0 / diagonal_ : 1.0;
  double distance_sum = 0;
  int far_count = 0;
  for (size_t v = 0; v < vertex_count; ++v) {
    if (groups_[v] != static_cast<int>(v)) continue;
    if (region[v]) {
      ++q.contact_region_vertices;
      continue;
    }
    const double d = (positions.row(v) - reference.row(v)).norm() * scale;
    distance_sum += d;
    ++far_count;
    q.dqs_distance_max = std::max(q.dqs_distance_max, d);
  }
  if (far_count) q.dqs_distance_mean = distance_sum / far_count;

  if (history_.size() == 2) {
    double jitter_sum = 0, jitter_max = 0;
    int count = 0;
    for (size_t v = 0; v < vertex_count; ++v) {
      if (groups_[v] != static_cast<int>(v)) continue;
      const Eigen::RowVector3f a =
          positions.row(v) - 2 * history_[1].row(v) + history_[0].row(v);
      const Eigen::RowVector3f b = reference.row(v) -
                                   2 * dqs_history_[1].row(v) +
                                   dqs_history_[0].row(v);
      const double j = (a - b).norm() * scale;
      jitter_sum += j;
      jitter_max = std::max(jitter_max, j);
      ++count;
    }
    q.jitter_mean = count ? jitter_sum / count : 0.0;
    q.jitter_max = jitter_max;
  }
  if (history_.size() == 2) {
    history_.erase(history_.begin());
    dqs_history_.erase(dqs_history_.begin());
  }
  history_.push_back(positions);
  dqs_history_.push_back(reference);
  return q;
}

QualitySummary summarizeQuality(const std::vector<FrameQuality>& frames) {
  QualitySummary s;
  s.frames = static_cast<int>(frames.size());
  double strain_sum = 0;
  double worst_volume = -1;
  for (size_t i = 0; i < frames.size(); ++i) {
    const FrameQuality& q = frames[i];
    s.self_intersections_max =
        std::max(s.self_intersections_max, q.self_intersections);
    s.new_self_intersections_total += q.new_self_intersections;
    if (q.volume_ratio) {
      s.volume_ratio_min = s.volume_ratio_min
                               ? std::min(*s.volume_ratio_min, *q.volume_ratio)
                               : *q.volume_ratio;
      s.volume_ratio_max = s.volume_ratio_max
                               ? std::max(*s.volume_ratio_max, *q.volume_ratio)
                               : *q.volume_ratio;
    }
    if (q.covered_volume_ratio) {
      const double r = *q.covered_volume_ratio;
      s.covered_volume_ratio_min =
          std::min(s.covered_volume_ratio_min.value_or(r), r);
      s.covered_volume_ratio_max =
          std::max(s.covered_volume_ratio_max.value_or(r), r);
    }
    strain_sum += q.edge_strain_mean;
    s.edge_strain_max = std::max(s.edge_strain_max, q.edge_strain_max);
    s.crumpled_edges_max = std::max(s.crumpled_edges_max, q.crumpled_edges);
    s.crumpled_edges_total += q.crumpled_edges;
    s.dqs_distance_max = std::max(s.dqs_distance_max, q.dqs_distance_max);
    if (q.jitter_max) {
      s.jitter_max =
          s.jitter_max ? std::max(*s.jitter_max, *q.jitter_max) : *q.jitter_max;
    }
    s.lost_vertices_max = std::max(s.lost_vertices_max, q.lost_vertices);
    const double volume =
        q.volume_ratio ? std::abs(*q.volume_ratio - 1.0) : 0.0;
    if (s.worst_frame < 0 ||
        q.new_self_intersections > s.new_self_intersections_max ||
        (q.new_self_intersections == s.new_self_intersections_max &&
         volume > worst_volume)) {
      s.worst_frame = static_cast<int>(i);
      s.new_self_intersections_max = q.new_self_intersections;
      worst_volume = volume;
    }
  }
  if (!frames.empty()) s.edge_strain_mean = strain_sum / frames.size();

  // Per part: the means of the frames' means, the largest distance.
  std::map<int, std::pair<PartQuality, int>> parts;
  for (const FrameQuality& q : frames) {
    for (const PartQuality& p : q.parts) {
      auto& [sum, count] = parts[p.part];
      sum.part = p.part;
      sum.edges = p.edges;
      sum.edge_strain_mean += p.edge_strain_mean;
      sum.dqs_edge_strain_mean += p.dqs_edge_strain_mean;
      sum.dqs_distance_max = std::max(sum.dqs_distance_max, p.dqs_distance_max);
      sum.new_pairs += p.new_pairs;
      sum.dqs_new_pairs += p.dqs_new_pairs;
      sum.crumpled_edges += p.crumpled_edges;
      sum.dqs_crumpled_edges += p.dqs_crumpled_edges;
      ++count;
    }
  }
  for (auto& [id, entry] : parts) {
    PartQuality p = entry.first;
    p.edge_strain_mean /= entry.second;
    p.dqs_edge_strain_mean /= entry.second;
    s.parts.push_back(p);
  }
  return s;
}

}  // namespace isk
