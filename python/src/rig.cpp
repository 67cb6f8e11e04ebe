// isk.Rig: loading, the procedural rigs, rigs from arrays, and poses.
#include "isk/rig/rig.hpp"

#include <pybind11/stl.h>

#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "arrays.hpp"
#include "bindings.hpp"
#include "isk/core/error.hpp"
#include "isk/core/vertex_normals.hpp"
#include "isk/io/import.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/pose.hpp"
#include "isk/tools/procedural.hpp"

namespace isk::python {

namespace {

using RigPtr = std::shared_ptr<Rig>;

// The clip `clip` names: an index into rig.clips or a clip name.
const AnimationClip& findClip(const Rig& rig, const py::object& clip) {
  if (py::isinstance<py::str>(clip)) {
    const std::string name = clip.cast<std::string>();
    const int index = rig.findClip(name);
    if (index < 0) {
      std::string names;
      for (const AnimationClip& c : rig.clips) {
        names += (names.empty() ? "'" : ", '") + c.name + "'";
      }
      fail("clip", "no clip named '" + name + "' (the rig has " +
                       (names.empty() ? std::string("none") : names) + ")");
    }
    return rig.clips[index];
  }
  if (!py::isinstance<py::int_>(clip)) {
    fail("clip", "expected a clip index or name");
  }
  const long long index = clip.cast<long long>();
  if (index < 0 || index >= static_cast<long long>(rig.clips.size())) {
    fail("clip", "index " + std::to_string(index) +
                     " out of range (the rig has " +
                     std::to_string(rig.clips.size()) + " clips)");
  }
  return rig.clips[static_cast<size_t>(index)];
}

FloatArray poseAt(const Rig& rig, const AnimationClip& clip, double time) {
  const TransformList locals = clip.sampleLocal(rig.skeleton, time);
  return transformsArray(
      skinningTransforms(rig.skeleton, globalTransforms(rig.skeleton, locals)));
}

RigPtr fromArrays(py::handle positions_in, py::handle triangles_in,
                  py::handle parents_in, py::handle inverse_binds_in,
                  py::handle weight_indices_in, py::handle weights_in,
                  std::optional<std::vector<std::string>> joint_names,
                  py::handle normals_in, const std::string& source) {
  auto rig = std::make_shared<Rig>();
  rig->source = source;
  Mesh& mesh = rig->mesh;
  mesh.positions = matrix3Xf(positions_in, "positions");
  const int vertex_count = mesh.vertexCount();
  if (vertex_count == 0) fail("positions", "no vertex");

  const IntArray triangles = intArray(triangles_in, "triangles", {-1, 3});
  const auto triangle_count = static_cast<int>(triangles.shape(0));
  if (triangle_count == 0) fail("triangles", "no triangle");
  mesh.triangles.resize(triangle_count, 3);
  for (int t = 0; t < triangle_count; ++t) {
    for (int k = 0; k < 3; ++k) {
      const int32_t v = triangles.at(t, k);
      if (v < 0 || v >= vertex_count) {
        fail("triangles", "triangle " + std::to_string(t) + ": vertex index " +
                              std::to_string(v) + " out of range [0, " +
                              std::to_string(vertex_count) + ")");
      }
      mesh.triangles(t, k) = v;
    }
  }
  mesh.parts.push_back({source, 0, vertex_count, 0, triangle_count});

  if (!normals_in.is_none()) {
    mesh.normals = matrix3Xf(normals_in, "normals", vertex_count);
  } else {
    // Area-weighted normals; +z for a vertex of no (or only degenerate)
    // triangle.
    const Matrix3Xf fallback = Matrix3Xf::Zero(vertex_count, 3).rowwise() +
                               Eigen::RowVector3f(0, 0, 1);
    const VertexTriangleAdjacency adjacency =
        VertexTriangleAdjacency::build(mesh.triangles, vertex_count);
    VertexNormalsJob job;
    job.positions = &mesh.positions;
    job.triangles = &mesh.triangles;
    job.adjacency = &adjacency;
    job.fallback_normals = &fallback;
    job.out_normals = &mesh.normals;
    job.validate().throwIfFailed("Rig.from_arrays normals");
    job.run();
  }

  const IntArray parents = intArray(parents_in, "parents", {-1});
  const auto joint_count = static_cast<int>(parents.shape(0));
  if (joint_count == 0) fail("parents", "no joint");
  const TransformList inverse_binds =
      transformList(inverse_binds_in, "inverse_bind_matrices", joint_count);
  if (joint_names && static_cast<int>(joint_names->size()) != joint_count) {
    fail("joint_names", std::to_string(joint_names->size()) + " names for " +
                            std::to_string(joint_count) + " joints");
  }
  Skeleton& skeleton = rig->skeleton;
  skeleton.joints.resize(joint_count);
  for (int j = 0; j < joint_count; ++j) {
    Joint& joint = skeleton.joints[j];
    joint.name = joint_names ? (*joint_names)[j] : "joint_" + std::to_string(j);
    joint.parent = parents.at(j);
    joint.inverse_bind = inverse_binds[j];
    joint.rest_local = Eigen::Affine3f::Identity();  // set once validated
    joint.is_skin_joint = true;
  }
  // Rest locals from the bind pose: bind(parent)^-1 * bind(j), where
  // bind = inverse_bind^-1. An out-of-order parent is left to
  // Skeleton::validate to name.
  if (Validation v = skeleton.validate(); !v) {
    throw Error(ErrorCode::kInvalidArgument, "Rig.from_arrays: " + v.reason());
  }
  for (int j = 0; j < joint_count; ++j) {
    Joint& joint = skeleton.joints[j];
    const Eigen::Affine3f bind = joint.inverse_bind.inverse(Eigen::Affine);
    joint.rest_local = joint.parent < 0
                           ? bind
                           : skeleton.joints[joint.parent].inverse_bind * bind;
  }

  const IntArray indices =
      intArray(weight_indices_in, "weight_indices", {vertex_count, -1});
  const auto influences = indices.shape(1);
  if (influences == 0) fail("weight_indices", "no influence per vertex");
  const FloatArray weights =
      floatArray(weights_in, "weights", {vertex_count, influences});
  std::vector<std::vector<std::pair<int, float>>> lists(vertex_count);
  for (int v = 0; v < vertex_count; ++v) {
    for (py::ssize_t k = 0; k < influences; ++k) {
      const float w = weights.at(v, k);
      const int32_t joint = indices.at(v, k);
      // A zero weight is padding, whatever its index.
      if (w == 0.f) continue;
      if (joint < 0 || joint >= joint_count) {
        fail("weight_indices",
             "vertex " + std::to_string(v) + " influence " + std::to_string(k) +
                 ": joint index " + std::to_string(joint) +
                 " out of range [0, " + std::to_string(joint_count) + ")");
      }
      lists[v].emplace_back(joint, w);
    }
  }
  rig->weights = SkinWeights::fromLists(lists);
  rig->weights.sortByWeight();

  if (Validation v = rig->validate(); !v) {
    throw Error(ErrorCode::kInvalidArgument, "Rig.from_arrays: " + v.reason());
  }
  return rig;
}

}  // namespace

void registerRig(py::module_& m) {
  py::class_<AnimationClip>(m, "Clip", "An animation clip of a rig.")
      .def_readonly("name", &AnimationClip::name)
      .def_readonly("start", &AnimationClip::start, "seconds")
      .def_readonly("duration", &AnimationClip::duration, "seconds")
      .def("__repr__", [](const AnimationClip& c) {
        return "Clip('" + c.name + "', start=" + std::to_string(c.start) +
               ", duration=" + std::to_string(c.duration) + ")";
      });

  py::class_<Rig, RigPtr>(m, "Rig",
                          "A skinned character: mesh, skeleton, weights and "
                          "clips (isk::Rig).")
      .def_static("from_arrays", &fromArrays, py::arg("positions"),
                  py::arg("triangles"), py::arg("parents"),
                  py::arg("inverse_bind_matrices"), py::arg("weight_indices"),
                  py::arg("weights"), py::arg("joint_names") = py::none(),
                  py::arg("normals") = py::none(), py::arg("source") = "arrays")
      .def_readonly("source", &Rig::source)
      .def_readonly("warnings", &Rig::warnings)
      .def_property_readonly("vertex_count",
                             [](const Rig& r) { return r.mesh.vertexCount(); })
      .def_property_readonly(
          "triangle_count", [](const Rig& r) { return r.mesh.triangleCount(); })
      .def_property_readonly(
          "joint_count", [](const Rig& r) { return r.skeleton.jointCount(); })
      .def_property_readonly("joint_names",
                             [](const Rig& r) {
                               std::vector<std::string> names;
                               for (const Joint& j : r.skeleton.joints)
                                 names.push_back(j.name);
                               return names;
                             })
      .def_property_readonly(
          "parents",
          [](const Rig& r) {
            IntArray out({static_cast<py::ssize_t>(r.skeleton.jointCount())});
            for (int j = 0; j < r.skeleton.jointCount(); ++j) {
              out.mutable_at(j) = r.skeleton.joints[j].parent;
            }
            return out;
          })
      .def_property_readonly("inverse_bind_matrices",
                             [](const Rig& r) {
                               TransformList inverse_binds;
                               for (const Joint& j : r.skeleton.joints) {
                                 inverse_binds.push_back(j.inverse_bind);
                               }
                               return transformsArray(inverse_binds);
                             })
      .def_property_readonly(
          "rest_positions",
          [](const Rig& r) { return copiedArray(r.mesh.positions); })
      .def_property_readonly(
          "rest_normals",
          [](const Rig& r) { return copiedArray(r.mesh.normals); })
      .def_property_readonly(
          "triangles",
          [](const Rig& r) {
            IntArray out({static_cast<py::ssize_t>(r.mesh.triangleCount()),
                          py::ssize_t{3}});
            if (r.mesh.triangleCount() > 0) {
              std::copy(r.mesh.triangles.data(),
                        r.mesh.triangles.data() + r.mesh.triangles.size(),
                        out.mutable_data());
            }
            return out;
          })
      .def("weight_arrays",
           [](const Rig& r) {
             const SkinWeights& w = r.weights;
             const int n = w.vertexCount();
             const int k = std::max(w.maxInfluences(), 1);
             IntArray indices({static_cast<py::ssize_t>(n), py::ssize_t{k}});
             FloatArray weights({static_cast<py::ssize_t>(n), py::ssize_t{k}});
             for (int v = 0; v < n; ++v) {
               for (int i = 0; i < k; ++i) {
                 const bool used = i < w.influenceCount(v);
                 indices.mutable_at(v, i) =
                     used ? static_cast<int32_t>(w.joints[w.offsets[v] + i])
                          : -1;
                 weights.mutable_at(v, i) =
                     used ? w.weights[w.offsets[v] + i] : 0.f;
               }
             }
             return py::make_tuple(indices, weights);
           })
      .def_property_readonly("bounding_box_diagonal", &Rig::boundingBoxDiagonal)
      .def_property_readonly("clips", [](const Rig& r) { return r.clips; })
      .def(
          "clip_pose",
          [](const Rig& r, const py::object& clip, double time) {
            if (!std::isfinite(time)) fail("time", "not finite");
            return poseAt(r, findClip(r, clip), time);
          },
          py::arg("clip"), py::arg("time"))
      .def(
          "bend_pose",
          [](const Rig& r, double degrees) {
            if (!(degrees >= 0 && degrees <= 180)) {
              fail("degrees",
                   "expected 0 to 180, got " + std::to_string(degrees));
            }
            // isk-skin's --clip bend:D at its last frame.
            const AnimationClip bend = makeBendClip(
                r.skeleton, static_cast<float>(degrees * M_PI / 180.0), 1.0);
            return poseAt(r, bend, 1.0);
          },
          py::arg("degrees"))
      .def(
          "skinning_matrices",
          [](const Rig& r, py::handle joint_world) {
            // A DCC's joint world (model-space) matrices, times the
            // inverse binds: what the skinners take.
            return transformsArray(skinningTransforms(
                r.skeleton, transformList(joint_world, "joint_world",
                                          r.skeleton.jointCount())));
          },
          py::arg("joint_world"))
      .def("bind_pose",
           [](const Rig& r) {
             return transformsArray(bindPoseSkinning(r.skeleton));
           })
      .def("__repr__", [](const Rig& r) {
        return "Rig('" + r.source + "', " +
               std::to_string(r.mesh.vertexCount()) + " vertices, " +
               std::to_string(r.skeleton.jointCount()) + " joints, " +
               std::to_string(r.clips.size()) + " clips)";
      });

  m.def(
      "load_rig",
      [](const std::string& path) {
        py::gil_scoped_release release;
        return std::make_shared<Rig>(importRig(path));
      },
      py::arg("path"));
  m.def(
      "builtin_rig",
      [](const std::string& name) {
        return std::make_shared<Rig>(makeBuiltinRig(name));
      },
      py::arg("name"));
  m.def("builtin_rig_names", &builtinRigNames);
}

}  // namespace isk::python
