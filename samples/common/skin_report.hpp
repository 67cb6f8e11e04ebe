// What isk-skin says about a finished run: the JSON report (--report) and
// the summary lines on stderr, assembled from the run's results. Host only:
// the device is described, never used.
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "isk/cl/runtime.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/rig.hpp"
#include "isk/tracking/surface_tracking.hpp"
#include "skin_options.hpp"
#include "skin_runner.hpp"

namespace isk::samples::skin {

// The device a run skinned on, as the report names it.
struct RunDevice {
  const ClDeviceInfo* info = nullptr;           // null: the CPU reference
  const TrackingMesh* tracking_mesh = nullptr;  // with implicit skinning
};

// Milliseconds before the first frame.
struct PrecomputeTimes {
  double load_ms = 0;   // the rig's import (or procedural build)
  double setup_ms = 0;  // the skinner's build and upload
};

// The iso drift of the implicit fields over the run's frames: each
// vertex's |f(v) - iso_v| over the vertices with iso_v > 0.
struct IsoDrift {
  double build_ms = 0;   // the fields' build (or cache read)
  double upload_ms = 0;  // the OpenCL field evaluation's upload
  // "opencl (<storage>)" or "reference".
  std::string evaluation = "reference";
  size_t tracked_vertices = 0;  // vertices with iso value > 0
  // Unset when no frame was measured (no field, or no tracked vertex).
  std::optional<double> mean;      // median over the frames of the mean
  std::optional<double> max;       // largest over the frames
  std::optional<double> field_ms;  // median field evaluation per frame
};

// The report's "implicit" section: the composition of `fields` (joint names
// from `skeleton`), their size and build, and the drift measured.
nlohmann::json implicitFieldsSection(const ImplicitFields& fields,
                                     const Skeleton& skeleton,
                                     const IsoDrift& drift);

// The JSON report of a run of `rig`'s clip `clip_name` with `options`;
// `implicit_fields`, when set, is implicitFieldsSection's (the tracking
// options join it with --method implicit).
nlohmann::json makeReport(const Options& options, const Rig& rig,
                          const std::string& clip_name, const RunDevice& device,
                          const PrecomputeTimes& precompute,
                          const RunResult& result,
                          const nlohmann::json* implicit_fields);

// The summary line of a run on the device `device_name`, newline included:
// frames, timings, volume, rest-pose error, self-intersections, contacts
// and the frame files written.
// The summary's parts (QualitySummary::parts), the largest excess of edge
// strain over DQS's first (edge_strain_mean - dqs_edge_strain_mean).
std::vector<PartQuality> partsByExcessStrain(const QualitySummary& summary);

// One line naming the `count` parts whose edge strain exceeds DQS's most
// (with DQS's and their largest distance from DQS), for the console; empty
// when no frame was measured or no part exceeds DQS's strain.
std::string formatPartsSummary(const RunResult& result,
                               const Skeleton& skeleton, int count = 3);

// The summary's parts, the largest excess of new intersecting pairs over
// DQS's first (new_pairs - dqs_new_pairs, summed over the frames).
std::vector<PartQuality> partsByExcessPairs(const QualitySummary& summary);

// One line naming the `count` parts whose new intersecting pairs exceed
// DQS's most (with DQS's), for the console; empty when no frame was measured
// or no part has more than DQS.
std::string formatPairPartsSummary(const RunResult& result,
                                   const Skeleton& skeleton, int count = 3);

std::string formatRunSummary(const Options& options,
                             const std::string& clip_name,
                             const std::string& device_name,
                             const RunResult& result);

// The line on the implicit fields (`composition` as
// isk::describeComposition says it) and their iso drift, newline included.
std::string formatIsoDriftSummary(const std::string& composition,
                                  const IsoDrift& drift);

}  // namespace isk::samples::skin
