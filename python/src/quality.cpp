// isk.quality: the per-frame measures of isk-skin's report
// (isk/tools/skin_quality.hpp) for one frame of a rig.
#include <memory>
#include <optional>

#include "arrays.hpp"
#include "bindings.hpp"
#include "isk/rig/rig.hpp"
#include "isk/tools/self_intersection.hpp"
#include "isk/tools/skin_quality.hpp"

namespace isk::python {

namespace {

py::dict quality(const Rig& rig, py::handle positions_in, py::handle dqs_in,
                 float contact_radius) {
  const int n = rig.mesh.vertexCount();
  const Matrix3Xf positions = matrix3Xf(positions_in, "positions", n);
  std::optional<Matrix3Xf> dqs;
  if (!dqs_in.is_none()) dqs = matrix3Xf(dqs_in, "dqs_positions", n);
  FrameQuality frame;
  int rest_pairs = 0;
  double rest_volume = 0;
  {
    py::gil_scoped_release release;
    // Welded at the seams as isk-skin's report is without a tracking mesh.
    SkinQualityOptions options;
    options.contact_radius = contact_radius;
    SkinQuality measure(rig.mesh, coincidentVertexGroups(rig.mesh.positions),
                        options);
    frame = measure.measure(positions, dqs ? &*dqs : nullptr);
    rest_pairs = static_cast<int>(measure.restPairs().size());
    rest_volume = measure.restVolume();
  }
  py::dict out;
  out["self_intersections"] = frame.self_intersections;
  out["new_self_intersections"] = frame.new_self_intersections;
  out["rest_self_intersections"] = rest_pairs;
  out["volume_ratio"] =
      frame.volume_ratio ? py::cast(*frame.volume_ratio) : py::none();
  out["covered_volume_ratio"] = frame.covered_volume_ratio
                                    ? py::cast(*frame.covered_volume_ratio)
                                    : py::none();
  out["rest_volume"] = rest_volume;
  out["edge_strain_mean"] = frame.edge_strain_mean;
  out["edge_strain_max"] = frame.edge_strain_max;
  out["contact_region_vertices"] = frame.contact_region_vertices;
  out["dqs_distance_mean"] = frame.dqs_distance_mean;
  out["dqs_distance_max"] = frame.dqs_distance_max;
  return out;
}

}  // namespace

void registerQuality(py::module_& m) {
  m.def("quality", &quality, py::arg("rig"), py::arg("positions"),
        py::arg("dqs_positions") = py::none(),
        py::arg("contact_radius") = SkinQualityOptions{}.contact_radius);
}

}  // namespace isk::python
