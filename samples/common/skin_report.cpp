#include "skin_report.hpp"

#include <algorithm>
#include <iomanip>
#include <set>
#include <sstream>

#include "isk/fields/composition_operator.hpp"
#include "isk/fields/field_composition.hpp"
#include "isk/fields/field_grid.hpp"

namespace isk::samples::skin {

namespace {

nlohmann::json deviceSection(const ClDeviceInfo* info) {
  if (!info) return "reference";
  return {{"platform", info->platform},
          {"name", info->name},
          {"version", info->version}};
}

constexpr const char* kCountedPairs =
    "pairs of triangles of the mesh welded by position that intersect "
    "anywhere but at the vertices or edge they share (fold-overs of adjacent "
    "triangles included), not intersecting at rest";
constexpr const char* kMeasures =
    "per frame: self_intersections (all pairs), new_self_intersections (not "
    "at rest), volume_ratio (to rest), covered_volume_ratio (the volume "
    "enclosed once or more, overlaps counted once, to rest), "
    "edge_strain_mean/max (|length / rest length - 1|), crumpled_edges "
    "(welded edges between two triangles whose bending angle changed from "
    "rest by more than 60 degrees: crumples and spikes), "
    "dqs_distance_mean/max "
    "(distance from the DQS frame of the "
    "same pose over the rest bounding-box diagonal, of the vertices farther "
    "than 5% of the diagonal from any contact), jitter_mean/max (second "
    "difference over three frames minus DQS's, over the diagonal), "
    "lost_vertices, state_changes (implicit: vertices whose tracking state "
    "-- converged, contact, crease, lost... -- differs from the frame "
    "before's)";

std::string partName(const PartQuality& p, const Skeleton& skeleton) {
  return p.part < skeleton.jointCount() ? skeleton.joints[p.part].name
                                        : std::to_string(p.part);
}

nlohmann::json optionalNumber(const std::optional<double>& value) {
  return value ? nlohmann::json(*value) : nlohmann::json(nullptr);
}

nlohmann::json frameJson(const FrameQuality& q) {
  return {{"self_intersections", q.self_intersections},
          {"new_self_intersections", q.new_self_intersections},
          {"volume_ratio", optionalNumber(q.volume_ratio)},
          {"covered_volume_ratio", optionalNumber(q.covered_volume_ratio)},
          {"edge_strain_mean", q.edge_strain_mean},
          {"edge_strain_max", q.edge_strain_max},
          {"crumpled_edges", q.crumpled_edges},
          {"contact_region_vertices", q.contact_region_vertices},
          {"dqs_distance_mean", q.dqs_distance_mean},
          {"dqs_distance_max", q.dqs_distance_max},
          {"jitter_mean", optionalNumber(q.jitter_mean)},
          {"jitter_max", optionalNumber(q.jitter_max)},
          {"lost_vertices", q.lost_vertices}};
}

nlohmann::json qualitySection(const Options& options, const RunResult& result,
                              const Skeleton& skeleton) {
  nlohmann::json quality;
  if (result.volume_ratio_min) {
    quality["volume_ratio"] = {{"min", *result.volume_ratio_min},
                               {"max", *result.volume_ratio_max}};
  } else {
    quality["volume_ratio"] = nullptr;
    quality["volume_note"] =
        "the rest pose encloses about no volume (open or flat mesh): no "
        "ratio";
  }
  quality["rest_volume"] = result.rest_volume;
  quality["rest_pose_error"] = result.rest_pose_error;
  if (!result.self_intersections.empty()) {
    const CountTotals totals = countTotals(result.self_intersections);
    quality["self_intersections"] = {
        {"max", totals.max},
        {"total", totals.total},
        {"at_rest", result.rest_self_intersections},
        {"counted", kCountedPairs}};
  }
  if (options.method == "implicit") {
    quality["contact_vertices"] = medianCount(result.contact_vertices);
  }
  if (!result.quality.empty()) {
    const QualitySummary summary = summarizeQuality(result.quality);
    quality["edge_strain"] = {{"mean", summary.edge_strain_mean},
                              {"max", summary.edge_strain_max}};
    if (summary.covered_volume_ratio_min)
      quality["covered_volume_ratio"] = {
          {"min", *summary.covered_volume_ratio_min},
          {"max", *summary.covered_volume_ratio_max}};
    else
      quality["covered_volume_ratio"] = nullptr;
    quality["crumpled_edges"] = {{"max", summary.crumpled_edges_max},
                                 {"total", summary.crumpled_edges_total}};
    quality["dqs_distance_max"] = summary.dqs_distance_max;
    quality["jitter_max"] = optionalNumber(summary.jitter_max);
    quality["lost_vertices_max"] = summary.lost_vertices_max;
    quality["worst_frame"] = summary.worst_frame;
    quality["measures"] = kMeasures;
    nlohmann::json frames = nlohmann::json::array();
    for (const FrameQuality& q : result.quality) frames.push_back(frameJson(q));
    if (result.state_changes.size() == result.quality.size()) {
      for (size_t i = 0; i < frames.size(); ++i)
        frames[i]["state_changes"] =
            result.state_changes[i] ? nlohmann::json(*result.state_changes[i])
                                    : nlohmann::json(nullptr);
      const std::optional<StateChangeSummary> changes =
          summarizeStateChanges(result.state_changes);
      quality["state_changes"] =
          changes
              ? nlohmann::json{{"mean", changes->mean}, {"max", changes->max}}
              : nlohmann::json(nullptr);
    }
    quality["frames"] = frames;
    nlohmann::json parts = nlohmann::json::array();
    for (const PartQuality& p : partsByExcessStrain(summary)) {
      parts.push_back({{"joint", partName(p, skeleton)},
                       {"edges", p.edges},
                       {"edge_strain_mean", p.edge_strain_mean},
                       {"dqs_edge_strain_mean", p.dqs_edge_strain_mean},
                       {"dqs_distance_max", p.dqs_distance_max},
                       {"new_pairs", p.new_pairs},
                       {"dqs_new_pairs", p.dqs_new_pairs},
                       {"crumpled_edges", p.crumpled_edges},
                       {"dqs_crumpled_edges", p.dqs_crumpled_edges}});
    }
    quality["parts"] = parts;
  }
  return quality;
}

nlohmann::json trackingSection(const SurfaceTrackingOptions& t) {
  return {{"base_skinning", "dqs"},
          {"rounds", t.rounds},
          {"projection_steps", t.projection_steps},
          {"sigma", t.sigma},
          {"contact_angle_degrees", t.contact_angle_degrees},
          {"tolerance", t.tolerance},
          {"relaxation", t.relaxation},
          {"skinned_ring_relaxation", t.skinned_ring_relaxation},
          {"home_contact", t.home_contact},
          {"contact_entry", t.contact_entry},
          {"contact_home_slack", t.contact_home_slack},
          {"contact_home_reach", t.contact_home_reach},
          {"rest_crease_degrees", t.rest_crease_degrees},
          {"blend_contact_degrees", t.blend_contact_degrees},
          {"beta_diffusion", t.beta_diffusion},
          {"smoothing_steps", t.smoothing_steps},
          {"crease_steps", t.crease_steps},
          {"crease_gate", t.crease_gate},
          {"dislocation_guard", t.dislocation_guard},
          {"volume_restore", t.volume_restore},
          {"contact_bulge", t.contact_bulge},
          {"contact_bulge_radius", t.contact_bulge_radius},
          {"contact_bulge_steps", t.contact_bulge_steps},
          {"contact_bulge_clearance", t.contact_bulge_clearance},
          {"strain_limit", t.strain_limit},
          {"strain_limit_steps", t.strain_limit_steps},
          {"restore_again_steps", t.restore_again_steps},
          {"fold_guard", t.fold_guard},
          {"fold_strain_limit", t.fold_strain_limit},
          {"fold_rings", t.fold_rings},
          {"fold_check_steps", t.fold_check_steps},
          {"tilt_guard_degrees", t.tilt_guard_degrees},
          {"tilt_strain_limit", t.tilt_strain_limit},
          {"history_keep", t.history_keep}};
}

}  // namespace

nlohmann::json implicitFieldsSection(const ImplicitFields& fields,
                                     const Skeleton& skeleton,
                                     const IsoDrift& drift) {
  const Composition& composition = fields.composition;
  nlohmann::json operators = nlohmann::json::object();
  for (const int index : composition.blended_pairs) {
    const FieldPair& pair = composition.pairs[index];
    operators[skeleton.joints[pair.joint].name] =
        compositionOperatorName(pair.op);
  }
  nlohmann::json section;
  section["composition"] = describeComposition(composition, skeleton);
  section["operators"] = operators;
  section["fields"] = fields.grids.fieldCount();
  section["grid_precision"] = gridPrecisionName(fields.grids.precision);
  int layer_vertices = 0;
  for (const uint8_t layer : fields.partition.vertex_layer)
    layer_vertices += layer;
  section["layer_vertices"] = layer_vertices;
  // The joints whose parts stay on skinning, by name, and their vertices.
  std::set<std::string> untracked_joints;
  for (const int v : fields.untracked_vertices) {
    if (std::binary_search(fields.rigid_piece_vertices.begin(),
                           fields.rigid_piece_vertices.end(), v))
      continue;
    const int j = fields.partition.vertex_joint[v];
    if (j >= 0 && j < skeleton.jointCount())
      untracked_joints.insert(skeleton.joints[j].name);
  }
  section["untracked_joints"] = untracked_joints;
  section["untracked_vertices"] = fields.untracked_vertices.size();
  section["rigid_piece_vertices"] = fields.rigid_piece_vertices.size();
  section["build_ms"] = drift.build_ms;
  section["upload_ms"] = drift.upload_ms;
  section["operator_tables_mib"] = composition.tableBytes() / kMiB;
  section["evaluation"] = drift.evaluation;
  section["tracked_vertices"] = drift.tracked_vertices;
  if (drift.mean) {
    section["iso_drift"] = {{"mean", *drift.mean}, {"max", *drift.max}};
    section["field_ms"] = *drift.field_ms;
  } else {
    section["iso_drift"] = nullptr;
    section["field_ms"] = nullptr;
    section["drift_note"] =
        fields.grids.fieldCount() == 0
            ? "the rig has no implicit field: nothing to measure"
            : "no vertex lies inside a field's support: nothing to measure";
  }
  return section;
}

nlohmann::json makeReport(const Options& options, const Rig& rig,
                          const std::string& clip_name, const RunDevice& device,
                          const PrecomputeTimes& precompute,
                          const RunResult& result,
                          const nlohmann::json* implicit_fields) {
  nlohmann::json report;
  report["input"] = options.input;
  report["vertices"] = rig.mesh.vertexCount();
  report["triangles"] = rig.mesh.triangleCount();
  report["joints"] = rig.skeleton.jointCount();
  report["skin_joints"] = rig.skeleton.skinJointCount();
  report["frames"] = result.frames;
  report["first_frame"] = result.first_frame;
  report["warm_up_frames"] = result.warm_up_frames;
  report["method"] = options.method;
  report["clip"] = clip_name;
  report["device"] = deviceSection(device.info);
  report["precompute_ms"] = precompute.load_ms + precompute.setup_ms;
  report["precompute_breakdown_ms"] = {{"load", precompute.load_ms},
                                       {"build_upload", precompute.setup_ms}};
  report["frame_ms"] = {{"median", result.frame.median},
                        {"p95", result.frame.p95},
                        {"min", result.frame.min}};
  nlohmann::json stages = nlohmann::json::object();
  for (const auto& [name, ms] : result.stage_median) stages[name] = ms;
  report["stage_ms"] = stages;
  report["quality"] = qualitySection(options, result, rig.skeleton);
  report["out"] = options.out_dir.empty() ? nlohmann::json(nullptr)
                                          : nlohmann::json(options.out_dir);
  report["format"] = options.format;
  if (implicit_fields) report["implicit"] = *implicit_fields;
  if (options.method == "implicit") {
    report["implicit"]["tracking"] = trackingSection(options.tracking);
    report["implicit"]["tracking"]["mode"] = options.tracking_mode;
    report["implicit"]["tracking"]["history_reset_degrees"] =
        options.history_reset_degrees;
    report["implicit"]["rigid_pieces"] = options.rigid_pieces;
    if (device.tracking_mesh) {
      report["implicit"]["relaxation_weights"] =
          device.tracking_mesh->relaxation.describe();
    }
  }
  return report;
}

std::string formatRunSummary(const Options& options,
                             const std::string& clip_name,
                             const std::string& device_name,
                             const RunResult& result) {
  std::ostringstream out;
  out << std::setprecision(4) << "isk-skin: " << result.frames << " frame"
      << (result.frames == 1 ? "" : "s");
  if (result.first_frame > 0 || result.warm_up_frames > 0) {
    out << " (" << result.first_frame << " to "
        << result.first_frame + result.frames - 1 << ", after "
        << result.warm_up_frames << " warm-up frame"
        << (result.warm_up_frames == 1 ? "" : "s") << ")";
  }
  out << " of clip '" << clip_name << "' (" << options.method << " on "
      << device_name << "): median " << result.frame.median << " ms/frame, p95 "
      << result.frame.p95 << " ms; volume ratio ";
  if (result.volume_ratio_min) {
    out << *result.volume_ratio_min << " to " << *result.volume_ratio_max;
  } else {
    out << "n/a";
  }
  out << "; rest-pose error " << result.rest_pose_error;
  if (!result.self_intersections.empty()) {
    out << "; new self-intersecting pairs max "
        << countTotals(result.self_intersections).max << " ("
        << result.rest_self_intersections << " at rest)";
  }
  if (!result.contact_vertices.empty()) {
    out << "; contact vertices median " << medianCount(result.contact_vertices);
  }
  if (const std::optional<StateChangeSummary> changes =
          summarizeStateChanges(result.state_changes)) {
    out << "; tracking state changes per frame mean " << changes->mean
        << ", max " << changes->max;
  }
  if (!options.out_dir.empty()) {
    out << "; wrote " << result.files.size() << " files to " << options.out_dir;
  }
  out << "\n";
  return out.str();
}

namespace {

// The summary's parts, the largest `excess` first (ties in part order).
template <typename Excess>
std::vector<PartQuality> partsByExcess(const QualitySummary& summary,
                                       Excess excess) {
  std::vector<PartQuality> parts = summary.parts;
  std::stable_sort(parts.begin(), parts.end(),
                   [&](const PartQuality& a, const PartQuality& b) {
                     return excess(a) > excess(b);
                   });
  return parts;
}

// "HEADING: A ...; B ... (TAIL)\n" over the first `count` of `parts` that
// `exceeds`, each written by `describe`; empty when none does.
template <typename Exceeds, typename Describe>
std::string partsLine(const std::vector<PartQuality>& parts, int count,
                      const std::string& heading, Exceeds exceeds,
                      Describe describe, const std::string& tail) {
  std::ostringstream out;
  out << std::setprecision(3) << heading << ":";
  int shown = 0;
  for (const PartQuality& p : parts) {
    if (shown == count || !exceeds(p)) break;
    out << (shown ? "; " : " ");
    describe(out, p);
    ++shown;
  }
  if (shown == 0) return "";
  out << " (" << tail << ")\n";
  return out.str();
}

}  // namespace

std::vector<PartQuality> partsByExcessStrain(const QualitySummary& summary) {
  return partsByExcess(summary, [](const PartQuality& p) {
    return p.edge_strain_mean - p.dqs_edge_strain_mean;
  });
}

std::string formatPartsSummary(const RunResult& result,
                               const Skeleton& skeleton, int count) {
  if (result.quality.empty()) return "";
  return partsLine(
      partsByExcessStrain(summarizeQuality(result.quality)), count,
      "isk-skin: parts whose edge strain exceeds DQS's most",
      [](const PartQuality& p) {
        return p.edge_strain_mean > p.dqs_edge_strain_mean;
      },
      [&](std::ostream& out, const PartQuality& p) {
        out << partName(p, skeleton) << " strain " << p.edge_strain_mean
            << " (DQS " << p.dqs_edge_strain_mean << "), up to "
            << 100 * p.dqs_distance_max << "% of the diagonal from DQS";
      },
      "--untracked-joint keeps a part on skinning");
}

std::vector<PartQuality> partsByExcessPairs(const QualitySummary& summary) {
  return partsByExcess(summary, [](const PartQuality& p) {
    return p.new_pairs - p.dqs_new_pairs;
  });
}

std::string formatPairPartsSummary(const RunResult& result,
                                   const Skeleton& skeleton, int count) {
  if (result.quality.empty()) return "";
  return partsLine(
      partsByExcessPairs(summarizeQuality(result.quality)), count,
      "isk-skin: parts whose new intersecting pairs exceed DQS's most",
      [](const PartQuality& p) { return p.new_pairs > p.dqs_new_pairs; },
      [&](std::ostream& out, const PartQuality& p) {
        out << partName(p, skeleton) << " " << p.new_pairs << " (DQS "
            << p.dqs_new_pairs << ")";
      },
      "summed over the frames; --untracked-joint keeps a part on skinning");
}

std::string formatIsoDriftSummary(const std::string& composition,
                                  const IsoDrift& drift) {
  std::ostringstream out;
  out << std::setprecision(4) << "isk-skin: implicit fields (" << composition
      << "): ";
  if (drift.mean) {
    out << "iso drift mean " << *drift.mean << ", max " << *drift.max
        << "; field evaluation " << *drift.field_ms << " ms/frame\n";
  } else {
    out << "no iso drift to measure\n";
  }
  return out.str();
}

}  // namespace isk::samples::skin
