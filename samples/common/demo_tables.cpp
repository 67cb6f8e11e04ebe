#include "demo_tables.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace isk::samples::demo {

const MethodSpec kMethods[kMethodCount] = {
    {"lbs", "LBS", false, SkinningMethod::kLinearBlend},
    {"dqs", "DQS", false, SkinningMethod::kDualQuaternion},
    {"implicit", "implicit", true, SkinningMethod::kDualQuaternion}};

namespace {

std::string optionalNumber(const char* format,
                           const std::optional<double>& value,
                           const char* absent) {
  return value ? formatNumber(format, *value) : absent;
}

std::string joinPictures(const std::vector<std::string>& pictures) {
  std::string joined;
  for (const std::string& p : pictures) {
    joined += (joined.empty() ? "" : ", ") + p;
  }
  return joined;
}

// The skipped rigs, each on a line of its own.
std::string formatSkipped(const std::vector<std::string>& notes) {
  std::string skipped;
  for (const std::string& note : notes) skipped += "\n" + note + ".\n";
  return skipped;
}

}  // namespace

std::string formatNumber(const char* format, double value) {
  char text[64];
  std::snprintf(text, sizeof(text), format, value);
  return text;
}

FramePlan planFrames(int requested, const AnimationClip& clip) {
  FramePlan plan;
  plan.full_count = defaultFrameCount(clip);
  plan.count =
      requested > 0 ? requested : std::min(plan.full_count, kDefaultMaxFrames);
  return plan;
}

std::string describeFramePlan(const std::string& rig, const FramePlan& plan) {
  return rig + " " + std::to_string(plan.count) + " of the " +
         std::to_string(plan.full_count) + " at 30 per second";
}

std::string formatFrameNote(const std::vector<std::string>& frame_counts,
                            int requested) {
  std::string note = "Frames per clip (uniformly over the clip): ";
  for (size_t i = 0; i < frame_counts.size(); ++i) {
    note += (i ? "; " : "") + frame_counts[i];
  }
  note += requested > 0 ? " (--frames " + std::to_string(requested) + ")."
                        : " (at most " + std::to_string(kDefaultMaxFrames) +
                              " by default; --frames N to change).";
  return note;
}

Row makeRow(const std::string& rig, const AnimationClip& clip,
            const MethodSpec& method, const std::string& device,
            const RunResult& result) {
  Row row;
  row.rig = rig;
  row.clip = clip.name + " (" + formatNumber("%.2f", clip.duration) + " s)";
  row.method = method.name;
  row.device = device;
  row.frames = result.frames;
  row.median_ms = result.frame.median;
  row.volume_min = result.volume_ratio_min;
  row.volume_max = result.volume_ratio_max;
  const CountTotals intersections = countTotals(result.self_intersections);
  row.intersections_max = intersections.max;
  row.intersections_total = intersections.total;
  if (method.implicit)
    row.contact_median = medianCount(result.contact_vertices);
  return row;
}

std::string formatTable(const std::vector<Row>& rows) {
  std::ostringstream out;
  out << "| rig | clip | method | device | frames | ms/frame (median) | "
         "volume ratio min | volume ratio max | new self-intersecting pairs "
         "max "
         "per frame | new self-intersecting pairs total | contact vertices "
         "(median) | "
         "reference ms/frame (median) | max abs(opencl - reference) / "
         "diagonal |\n"
      << "|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const Row& row : rows) {
    out << "| " << row.rig << " | " << row.clip << " | " << row.method << " | "
        << row.device << " | " << row.frames << " | "
        << formatNumber("%.3f", row.median_ms) << " | "
        << optionalNumber("%.4f", row.volume_min, "n/a") << " | "
        << optionalNumber("%.4f", row.volume_max, "n/a") << " | "
        << row.intersections_max << " | " << row.intersections_total << " | "
        << optionalNumber("%.0f", row.contact_median, "-") << " | "
        << optionalNumber("%.3f", row.reference_ms, "-") << " | "
        << optionalNumber("%.2e", row.max_difference, "-") << " |\n";
  }
  return out.str();
}

std::string formatPictureTable(const std::vector<PictureRow>& rows) {
  std::ostringstream out;
  out << "| rig | frame | time (s) | most bent joint | bend (deg) | LBS "
         "self-intersections | DQS self-intersections | implicit "
         "self-intersections | implicit contact vertices | pictures |\n"
      << "|---|---:|---:|---|---:|---:|---:|---:|---:|---|\n";
  for (const PictureRow& row : rows) {
    out << "| " << row.rig << " | " << row.frame << " | "
        << formatNumber("%.3f", row.time) << " | " << row.joint << " | "
        << formatNumber("%.1f", row.degrees) << " | " << row.intersections[0]
        << " | " << row.intersections[1] << " | " << row.intersections[2]
        << " | " << row.contacts << " | " << joinPictures(row.pictures)
        << " |\n";
  }
  return out.str();
}

FieldRow describeFields(const std::string& rig, const ImplicitFields& fields) {
  FieldRow row;
  row.rig = rig;
  row.fields = fields.grids.fieldCount();
  for (size_t i = 0; i < fields.samples.size(); ++i) {
    const int count =
        fields.samples[i].surface.size() + fields.samples[i].closure.size();
    row.samples_min = i == 0 ? count : std::min(row.samples_min, count);
    row.samples_max = i == 0 ? count : std::max(row.samples_max, count);
  }
  // Loaded from the cache: nothing was fitted or baked; the read's time.
  row.cached = fields.cache_origin == FieldCacheOrigin::kLoaded;
  row.fit_bake_ms = row.cached
                        ? fields.times.sampling_ms
                        : fields.times.fitting_ms + fields.times.baking_ms;
  row.mib = fields.grids.bytes() / (1024.0 * 1024.0);
  for (const float iso : fields.iso_values) {
    const double off = std::abs(iso - 0.5);
    row.iso_mean += off;
    row.iso_max = std::max(row.iso_max, off);
  }
  if (!fields.iso_values.empty()) row.iso_mean /= fields.iso_values.size();
  return row;
}

std::string formatFieldTable(const std::vector<FieldRow>& rows) {
  std::ostringstream out;
  out << "| rig | fields | samples per field | fit+bake ms (cached: load "
         "ms) | field MiB | "
         "mean abs(iso - 0.5) | max abs(iso - 0.5) | OpenCL storage | max "
         "abs(opencl - reference) field value | pictures |\n"
      << "|---|---:|---:|---:|---:|---:|---:|---|---:|---|\n";
  for (const FieldRow& row : rows) {
    out << "| " << row.rig << " | " << row.fields << " | " << row.samples_min
        << "-" << row.samples_max << " | "
        << formatNumber("%.1f", row.fit_bake_ms) << " | "
        << formatNumber("%.2f", row.mib) << " | "
        << formatNumber("%.4f", row.iso_mean) << " | "
        << formatNumber("%.4f", row.iso_max) << " | " << row.storage << " | "
        << optionalNumber("%.2e", row.max_difference, "-") << " | "
        << joinPictures(row.pictures) << " |\n";
  }
  std::string cached;
  for (const FieldRow& row : rows)
    if (row.cached) cached += (cached.empty() ? "" : ", ") + row.rig;
  if (!cached.empty())
    out << "\nFields loaded from the field cache (ISK_CACHE_DIR; off "
           "disables it), fit+bake column gives the load: "
        << cached << "\n";
  return out.str();
}

std::string formatStdoutSummary(const Summary& summary) {
  std::ostringstream out;
  out << summary.frame_note << "\n\n"
      << formatTable(summary.rows) << formatSkipped(summary.notes) << "\n"
      << formatPictureTable(summary.picture_rows) << "\n"
      << formatFieldTable(summary.field_rows) << "\n"
      << summary.table_errors << "\n"
      << summary.bend_table;
  return out.str();
}

std::string formatSummaryMarkdown(const Summary& summary) {
  const std::string& out_dir = summary.out_dir;
  return "# isk-demo summary\n\nFrames: " + out_dir +
         "/<rig>/<method>/frame_XXXX.obj (the OpenCL frames; the "
         "reference's without an OpenCL device)\n\n" +
         summary.frame_note +
         "\n\nMethods: lbs (linear blend), dqs (dual quaternions), implicit "
         "(Vaillant et al. 2013: DQS, then surface tracking in the rig's "
         "implicit fields with the paper's parameters). Self-intersections: "
         "pairs of non-adjacent triangles that intersect, per frame. "
         "Contact vertices: vertices the tracking stopped at a contact "
         "(median over the frames). ms/frame: skinning + tracking + "
         "normals + read-back, on the device of the row and on the CPU "
         "reference; the last column compares their frames (LBS and DQS "
         "within " +
         formatNumber("%.0e", kAgreementTolerance) + ", implicit within " +
         formatNumber("%.0e", kImplicitAgreementTolerance) +
         " of the diagonal).\n\n" + formatTable(summary.rows) +
         formatSkipped(summary.notes) +
         "\n## Pictures\n\nAt each rig's most bent frame (the largest "
         "rotation of a joint relative to its parent bone, from the bind "
         "pose), the three methods side by side, same view and scale, "
         "looking along the joint's bend axis (relative to " +
         out_dir +
         "): compare.png (the whole mesh) and closeup.png (around the "
         "joint's fold, seen " +
         formatNumber("%.0f", kCloseUpTiltDegrees) +
         " degrees off the bend axis from inside the fold). Grey: skin; red: "
         "skin seen from inside (pushed through "
         "other skin); green: contact vertices of implicit skinning; dark "
         "lines: silhouettes, folds and creases. Self-intersections and "
         "contact vertices of the pictured frame:\n\n" +
         formatPictureTable(summary.picture_rows) +
         "\n## Implicit fields\n\nOne field per bone (HRBF fit, baked "
         "32^3), evaluated at the skinned vertices (DQS) of the bind pose "
         "and of the clip's middle frame on OpenCL and on the CPU "
         "reference. Pictures (relative to " +
         out_dir +
         "): the composed field at the bind pose (composed.png) and at the "
         "middle frame (composed_bent.png), inside red, outside blue, the "
         "0.5 iso black, the mesh section green.\n\n" +
         formatFieldTable(summary.field_rows) +
         "\n## Composition operators\n\nPictures in " + summary.operators_dir +
         " (see samples/operator-plots/README.md): operator_union.png, "
         "operator_blend.png, operator_bulge.png, each operator's "
         "iso-curves over the (f1, f2) unit square for theta = 0, pi/16, "
         "pi/8, 3pi/16 and pi/4 (left to right). Largest abs(table - "
         "direct) operator value over each panel:\n\n" +
         summary.table_errors +
         "\nbend_<op>_<deg>.png and bend_grid.png (the paper's Figure "
         "5(c)): the arm's composed field around its elbow bent by 0, 45, "
         "90 and 135 degrees with each operator at every joint; areas "
         "within " +
         formatNumber("%.1f", summary.measure_radius) +
         " model units of the elbow, compared with the union's:\n\n" +
         summary.bend_table;
}

std::vector<std::string> agreementFailures(const Agreement& agreement) {
  std::vector<std::string> failures;
  if (!agreement.skinning) {
    std::ostringstream message;
    message << "isk-demo: OpenCL and the CPU reference differ by more than "
            << kAgreementTolerance << " of the bounding-box diagonal";
    failures.push_back(message.str());
  }
  if (!agreement.implicit) {
    std::ostringstream message;
    message << "isk-demo: implicit skinning on OpenCL and on the CPU "
               "reference differ by more than "
            << kImplicitAgreementTolerance << " of the bounding-box diagonal";
    failures.push_back(message.str());
  }
  if (!agreement.fields) {
    std::ostringstream message;
    message << "isk-demo: OpenCL and CPU reference field values differ by "
               "more than "
            << kFieldTolerance[0] << " (buffer) or " << kFieldTolerance[1]
            << " (image)";
    failures.push_back(message.str());
  }
  return failures;
}

}  // namespace isk::samples::demo
