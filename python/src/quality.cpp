// isk.quality: the per-frame measures of isk-skin's report
// (isk/tools/skin_quality.hpp) for one frame of a rig.
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "arrays.hpp"
#include "bindings.hpp"
#include "isk/fields/bone_partition.hpp"
#include "isk/rig/rig.hpp"
#include "isk/tools/self_intersection.hpp"
#include "isk/tools/skin_quality.hpp"

namespace isk::python {

namespace {

using RigPtr = std::shared_ptr<Rig>;

py::object optional(const std::optional<double>& value) {
  return value ? py::cast(*value) : py::none();
}

// Each bone's part (by its joint's name), ascending joint index.
py::list partsList(const std::vector<PartQuality>& parts, const Rig& rig) {
  py::list out;
  for (const PartQuality& p : parts) {
    py::dict part;
    part["joint"] = rig.skeleton.joints[p.part].name;
    part["edges"] = p.edges;
    part["edge_strain_mean"] = p.edge_strain_mean;
    part["dqs_edge_strain_mean"] = p.dqs_edge_strain_mean;
    part["dqs_distance_max"] = p.dqs_distance_max;
    part["new_pairs"] = p.new_pairs;
    part["dqs_new_pairs"] = p.dqs_new_pairs;
    part["crumpled_edges"] = p.crumpled_edges;
    part["dqs_crumpled_edges"] = p.dqs_crumpled_edges;
    out.append(part);
  }
  return out;
}

py::dict frameDict(const FrameQuality& frame, const SkinQuality& measure,
                   const Rig& rig) {
  py::dict out;
  out["self_intersections"] = frame.self_intersections;
  out["new_self_intersections"] = frame.new_self_intersections;
  out["rest_self_intersections"] = static_cast<int>(measure.restPairs().size());
  out["volume_ratio"] = optional(frame.volume_ratio);
  out["covered_volume_ratio"] = optional(frame.covered_volume_ratio);
  out["rest_volume"] = measure.restVolume();
  out["edge_strain_mean"] = frame.edge_strain_mean;
  out["edge_strain_max"] = frame.edge_strain_max;
  out["crumpled_edges"] = frame.crumpled_edges;
  out["contact_region_vertices"] = frame.contact_region_vertices;
  out["dqs_distance_mean"] = frame.dqs_distance_mean;
  out["dqs_distance_max"] = frame.dqs_distance_max;
  out["parts"] = partsList(frame.parts, rig);
  return out;
}

// Welded at the seams as isk-skin's report is without a tracking mesh, with
// its bones' parts.
std::unique_ptr<SkinQuality> makeMeasure(const Rig& rig, float contact_radius) {
  SkinQualityOptions options;
  options.contact_radius = contact_radius;
  options.vertex_parts = partitionMesh(rig).vertex_joint;
  return std::make_unique<SkinQuality>(
      rig.mesh, coincidentVertexGroups(rig.mesh.positions), options);
}

// The frames of one clip in order: SkinQuality, whose jitter needs the two
// frames before.
class ClipQuality {
 public:
  ClipQuality(RigPtr rig, float contact_radius) : rig_(std::move(rig)) {
    py::gil_scoped_release release;
    measure_ = makeMeasure(*rig_, contact_radius);
  }

  py::dict measure(py::handle positions_in, py::handle dqs_in, int lost) {
    const int n = rig_->mesh.vertexCount();
    const Matrix3Xf positions = matrix3Xf(positions_in, "positions", n);
    std::optional<Matrix3Xf> dqs;
    if (!dqs_in.is_none()) dqs = matrix3Xf(dqs_in, "dqs_positions", n);
    if (lost < 0) fail("lost", "expected a count >= 0");
    FrameQuality frame;
    {
      py::gil_scoped_release release;
      frame =
          measure_->measure(positions, dqs ? &*dqs : nullptr, nullptr, lost);
    }
    frames_.push_back(frame);
    py::dict out = frameDict(frame, *measure_, *rig_);
    out["jitter_mean"] = optional(frame.jitter_mean);
    out["jitter_max"] = optional(frame.jitter_max);
    out["lost_vertices"] = frame.lost_vertices;
    return out;
  }

  py::dict summary() const {
    const QualitySummary s = summarizeQuality(frames_);
    py::dict out;
    out["frames"] = s.frames;
    out["new_self_intersections_max"] = s.new_self_intersections_max;
    out["new_self_intersections_total"] = s.new_self_intersections_total;
    out["volume_ratio_min"] = optional(s.volume_ratio_min);
    out["volume_ratio_max"] = optional(s.volume_ratio_max);
    out["covered_volume_ratio_min"] = optional(s.covered_volume_ratio_min);
    out["covered_volume_ratio_max"] = optional(s.covered_volume_ratio_max);
    out["edge_strain_mean"] = s.edge_strain_mean;
    out["edge_strain_max"] = s.edge_strain_max;
    out["crumpled_edges_max"] = s.crumpled_edges_max;
    out["crumpled_edges_total"] = s.crumpled_edges_total;
    out["dqs_distance_max"] = s.dqs_distance_max;
    out["jitter_max"] = optional(s.jitter_max);
    out["lost_vertices_max"] = s.lost_vertices_max;
    out["worst_frame"] = s.worst_frame;
    out["parts"] = partsList(s.parts, *rig_);
    return out;
  }

 private:
  RigPtr rig_;
  std::unique_ptr<SkinQuality> measure_;
  std::vector<FrameQuality> frames_;
};

py::dict quality(const Rig& rig, py::handle positions_in, py::handle dqs_in,
                 float contact_radius) {
  const int n = rig.mesh.vertexCount();
  const Matrix3Xf positions = matrix3Xf(positions_in, "positions", n);
  std::optional<Matrix3Xf> dqs;
  if (!dqs_in.is_none()) dqs = matrix3Xf(dqs_in, "dqs_positions", n);
  std::unique_ptr<SkinQuality> measure;
  FrameQuality frame;
  {
    py::gil_scoped_release release;
    measure = makeMeasure(rig, contact_radius);
    frame = measure->measure(positions, dqs ? &*dqs : nullptr);
  }
  return frameDict(frame, *measure, rig);
}

}  // namespace

void registerQuality(py::module_& m) {
  m.def("quality", &quality, py::arg("rig"), py::arg("positions"),
        py::arg("dqs_positions") = py::none(),
        py::arg("contact_radius") = SkinQualityOptions{}.contact_radius);
  py::class_<ClipQuality>(m, "SkinQuality")
      .def(py::init<RigPtr, float>(), py::arg("rig"),
           py::arg("contact_radius") = SkinQualityOptions{}.contact_radius)
      .def("measure", &ClipQuality::measure, py::arg("positions"),
           py::arg("dqs_positions") = py::none(), py::arg("lost") = 0)
      .def("summary", &ClipQuality::summary);
}

}  // namespace isk::python
