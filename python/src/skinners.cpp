// isk.ImplicitSkinner and isk.GeometricSkinner: one rig skinned frame by
// frame on an OpenCL device or on the CPU reference. Building and every
// frame run without the GIL; calls are serialized by a lock per device (the
// skinners of one device share its context and queue) or per CPU reference
// skinner, since the C++ skinners are not meant for concurrent calls.
#include <pybind11/functional.h>
#include <pybind11/stl.h>

#include <chrono>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "arrays.hpp"
#include "bindings.hpp"
#include "isk/cl/runtime.hpp"
#include "isk/cl/skinning.hpp"
#include "isk/core/error.hpp"
#include "isk/fields/composition_operator.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/skinning/cpu_skinning.hpp"

namespace isk::python {

namespace {

using RigPtr = std::shared_ptr<Rig>;
using Clock = std::chrono::steady_clock;

double millisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start)
      .count();
}

// The ClContext selection of `device`, or nullopt for the CPU reference.
std::optional<std::string> deviceSelection(const std::string& device) {
  if (device == "reference") return std::nullopt;
  if (device == "opencl") return std::string();
  if (device == "gpu" || device == "cpu" || device.rfind("opencl:", 0) == 0) {
    return device;
  }
  fail("device",
       "expected 'opencl', 'opencl:N', 'gpu', 'cpu' or "
       "'reference', got '" +
           device + "'");
}

// A device's context and the lock of every call that uses it.
struct SharedDevice {
  std::shared_ptr<ClContext> context;
  std::shared_ptr<std::mutex> mutex = std::make_shared<std::mutex>();
};

// One context per selection for the whole process, so that skinners share
// the built programs. Never destroyed: tearing OpenCL down while the
// interpreter exits is left to the driver.
SharedDevice sharedDevice(const std::string& selection) {
  static auto* devices = new std::map<std::string, SharedDevice>;
  static std::mutex mutex;
  std::lock_guard<std::mutex> lock(mutex);
  auto found = devices->find(selection);
  if (found != devices->end()) return found->second;
  SharedDevice device;
  device.context = ClContext::create(selection);
  devices->emplace(selection, device);
  return device;
}

CompositionOperator parseOperator(const std::string& name,
                                  const std::string& what) {
  CompositionOperator op;
  if (!parseCompositionOperator(name, &op)) {
    fail(what, "expected 'union', 'blend' or 'bulge', got '" + name + "'");
  }
  return op;
}

SkinningMethod parseMethod(const std::string& name, const std::string& what) {
  if (name == "dqs") return SkinningMethod::kDualQuaternion;
  if (name == "lbs") return SkinningMethod::kLinearBlend;
  fail(what, "expected 'dqs' or 'lbs', got '" + name + "'");
}

py::dict implicitTimes(const ImplicitStageTimes& t) {
  py::dict out;
  out["upload"] = t.upload_ms;
  out["skinning"] = t.skinning_ms;
  out["projection"] = t.tracking.projection_ms;
  out["relaxation"] = t.tracking.relaxation_ms;
  out["smoothing"] = t.tracking.smoothing_ms;
  out["volume"] = t.tracking.volume_ms;
  out["strain_limit"] = t.tracking.strain_limit_ms;
  out["normals"] = t.tracking.normals_ms;
  out["readback"] = t.readback_ms;
  return out;
}

// The last frame's positions or normals of a skinner's device or CPU
// reference (one of them set). The lock is taken without the GIL, so that a
// thread waiting for it never blocks one that needs the GIL back.
template <typename Device, typename Reference>
Matrix3Xf readLastFrame(std::mutex& mutex, Device* device, Reference* reference,
                        bool positions) {
  py::gil_scoped_release release;
  std::lock_guard<std::mutex> lock(mutex);
  Matrix3Xf out;
  if (device) {
    positions ? device->readPositions(out) : device->readNormals(out);
  } else {
    positions ? reference->readPositions(out) : reference->readNormals(out);
  }
  return out;
}

class PyImplicitSkinner {
 public:
  PyImplicitSkinner(
      RigPtr rig, const std::string& device, const std::string& op,
      py::object joint_operators, py::object untracked_joints,
      std::optional<double> bulge_strength, std::optional<double> blend_theta,
      std::optional<int> rounds, std::optional<float> sigma,
      std::optional<float> contact_angle, std::optional<int> smoothing_steps,
      std::optional<bool> relaxation,
      std::optional<bool> skinned_ring_relaxation,
      std::optional<bool> crease_gate, std::optional<float> volume_restore,
      std::optional<float> contact_bulge, std::optional<bool> dislocation_guard,
      const std::string& base_skinning, bool layers,
      const std::string& rigid_pieces, const std::string& tracking_mode,
      std::optional<std::string> cache_dir, py::object progress)
      : rig_(std::move(rig)) {
    const std::optional<std::string> selection = deviceSelection(device);
    ImplicitSkinnerOptions options;
    CompositionOptions& composition = options.fields.composition;
    if (!parseOperatorChoice(op, &composition)) {
      fail("operator",
           "expected 'auto', 'union', 'blend' or 'bulge', got '" + op + "'");
    }
    if (!joint_operators.is_none()) {
      if (!py::isinstance<py::dict>(joint_operators)) {
        fail("joint_operators", "expected a dict of joint name to operator");
      }
      for (auto [key, value] : joint_operators.cast<py::dict>()) {
        const std::string name = py::str(key);
        if (rig_->skeleton.find(name) < 0) {
          fail("joint_operators",
               "no joint named '" + name + "' in " + rig_->source);
        }
        composition.joint_operators[name] =
            parseOperator(py::str(value), "joint_operators['" + name + "']");
      }
    }
    if (!untracked_joints.is_none()) {
      if (py::isinstance<py::str>(untracked_joints) ||
          !py::isinstance<py::sequence>(untracked_joints)) {
        fail("untracked_joints", "expected a list of joint names");
      }
      for (const py::handle item : untracked_joints.cast<py::sequence>()) {
        if (!py::isinstance<py::str>(item)) {
          fail("untracked_joints", "expected joint names (str), got " +
                                       std::string(py::repr(item)));
        }
        const std::string name = py::str(item);
        if (rig_->skeleton.find(name) < 0) {
          fail("untracked_joints",
               "no joint named '" + name + "' in " + rig_->source);
        }
        options.fields.untracked_joints.insert(name);
      }
    }
    // Validated with the fields' options (buildImplicitFields).
    if (bulge_strength) composition.bulge_strength = *bulge_strength;
    if (blend_theta) composition.blend_theta = *blend_theta;
    SurfaceTrackingOptions& tracking = options.tracking;
    if (rounds) tracking.rounds = *rounds;
    if (sigma) tracking.sigma = *sigma;
    if (contact_angle) tracking.contact_angle_degrees = *contact_angle;
    if (smoothing_steps) tracking.smoothing_steps = *smoothing_steps;
    if (relaxation) tracking.relaxation = *relaxation;
    if (skinned_ring_relaxation)
      tracking.skinned_ring_relaxation = *skinned_ring_relaxation;
    if (crease_gate) tracking.crease_gate = *crease_gate;
    if (volume_restore) tracking.volume_restore = *volume_restore;
    if (contact_bulge) tracking.contact_bulge = *contact_bulge;
    if (dislocation_guard) tracking.dislocation_guard = *dislocation_guard;
    options.base_skinning = parseMethod(base_skinning, "base_skinning");
    options.fields.sampling.skin_only = layers;
    if (!parseRigidPieces(rigid_pieces, &options.fields.rigid_pieces)) {
      fail("rigid_pieces",
           "expected 'auto', 'rigid' or 'tracked', got '" + rigid_pieces + "'");
    }
    if (tracking_mode == "history") {
      options.tracking_mode = TrackingMode::kHistory;
    } else if (tracking_mode != "2013") {
      fail("tracking",
           "expected '2013' or 'history', got '" + tracking_mode + "'");
    }
    if (cache_dir) {
      options.fields.cache = true;
      options.fields.cache_folder = *cache_dir;
    }
    if (const Validation v = options.validate(); !v) {
      throw Error(ErrorCode::kInvalidArgument,
                  "ImplicitSkinner: " + v.reason());
    }
    if (!progress.is_none()) {
      if (!PyCallable_Check(progress.ptr())) {
        fail("progress", "expected a callable(stage: str, fraction: float)");
      }
      // Copies of the options copy this pointer, not the Python object,
      // so no reference count changes without the GIL; the last copy
      // takes the GIL to let it go.
      std::shared_ptr<py::object> callback(new py::object(progress),
                                           [](py::object* p) {
                                             py::gil_scoped_acquire gil;
                                             delete p;
                                           });
      options.fields.progress = [callback](const char* stage, float fraction) {
        py::gil_scoped_acquire gil;
        (*callback)(stage, fraction);
      };
    }
    {
      py::gil_scoped_release release;
      const auto start = Clock::now();
      if (selection) {
        const SharedDevice shared = sharedDevice(*selection);
        mutex_ = shared.mutex;
        std::lock_guard<std::mutex> lock(*mutex_);
        device_ =
            std::make_unique<ImplicitSkinner>(shared.context, *rig_, options);
      } else {
        reference_ = std::make_unique<CpuImplicitSkinner>(*rig_, options);
      }
      build_ms_ = millisecondsSince(start);
    }
    warnings_ = fields().warnings;
    warnUnusedControllers(bulge_strength.has_value(), blend_theta.has_value());
  }

  void run(py::handle matrices) {
    const TransformList pose =
        transformList(matrices, "matrices", rig_->skeleton.jointCount());
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(*mutex_);
    const auto start = Clock::now();
    if (device_) {
      device_->run(pose);
    } else {
      reference_->run(pose);
    }
    last_frame_ms_ = millisecondsSince(start);
  }

  FloatArray positions() { return ownedArray(read(true)); }
  FloatArray normals() { return ownedArray(read(false)); }

  py::tuple deform(py::handle matrices) {
    run(matrices);
    FloatArray p = positions();
    return py::make_tuple(p, normals());
  }

  void resetHistory() {
    std::lock_guard<std::mutex> lock(*mutex_);
    if (device_) {
      device_->resetHistory();
    } else {
      reference_->resetHistory();
    }
  }

  int contactCount() {
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(*mutex_);
    return device_ ? device_->contactCount() : reference_->contactCount();
  }

  const ImplicitFields& fields() const {
    return device_ ? device_->fields() : reference_->fields();
  }
  // The fields' build warnings, then the controller settings that shape no
  // joint of the built composition.
  const std::vector<std::string>& warnings() const { return warnings_; }
  py::dict stageTimes() {
    ImplicitStageTimes times;
    {
      py::gil_scoped_release release;
      std::lock_guard<std::mutex> lock(*mutex_);
      times = device_ ? device_->lastTimes() : reference_->lastTimes();
    }
    return implicitTimes(times);
  }
  std::string device() const {
    return device_ ? device_->context().info().describe()
                   : std::string("reference (CPU)");
  }
  const Rig& rig() const { return *rig_; }
  double lastFrameMs() const { return last_frame_ms_; }
  double buildMs() const { return build_ms_; }

 private:
  Matrix3Xf read(bool positions) {
    return readLastFrame(*mutex_, device_.get(), reference_.get(), positions);
  }

  // As isk-skin's --blend-theta / --bulge-strength: a setting given for an
  // operator no joint composes with (under 'auto' a rig without mirrored
  // limbs blends nowhere) changes nothing, so it is said, in `warnings` and
  // as a Python UserWarning.
  void warnUnusedControllers(bool bulge_strength_given,
                             bool blend_theta_given) {
    const Composition& built = fields().composition;
    std::vector<std::string> unused;
    if (bulge_strength_given && !built.uses(CompositionOperator::kBulge))
      unused.push_back("bulge_strength has no effect: no joint uses bulge");
    if (blend_theta_given && !built.uses(CompositionOperator::kBlend))
      unused.push_back("blend_theta has no effect: no joint uses blend");
    for (const std::string& warning : unused) {
      warnings_.push_back(warning);
      if (PyErr_WarnEx(PyExc_UserWarning,
                       ("ImplicitSkinner: " + warning).c_str(), 1) != 0)
        throw py::error_already_set();
    }
  }

  RigPtr rig_;
  std::vector<std::string> warnings_;
  std::unique_ptr<ImplicitSkinner> device_;
  std::unique_ptr<CpuImplicitSkinner> reference_;
  // The device's lock, or this skinner's own on the CPU reference.
  std::shared_ptr<std::mutex> mutex_ = std::make_shared<std::mutex>();
  double last_frame_ms_ = 0, build_ms_ = 0;
};

class PyGeometricSkinner {
 public:
  PyGeometricSkinner(RigPtr rig, const std::string& method,
                     const std::string& device)
      : rig_(std::move(rig)), method_(parseMethod(method, "method")) {
    const std::optional<std::string> selection = deviceSelection(device);
    py::gil_scoped_release release;
    const int joints = rig_->skeleton.jointCount();
    if (selection) {
      const SharedDevice shared = sharedDevice(*selection);
      mutex_ = shared.mutex;
      std::lock_guard<std::mutex> lock(*mutex_);
      device_ = std::make_unique<ClSkinning>(shared.context, rig_->mesh,
                                             rig_->weights, joints);
    } else {
      reference_ =
          std::make_unique<CpuSkinning>(rig_->mesh, rig_->weights, joints);
    }
  }

  void run(py::handle matrices) {
    const TransformList pose =
        transformList(matrices, "matrices", rig_->skeleton.jointCount());
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(*mutex_);
    const auto start = Clock::now();
    // Normals recomputed from the skinned positions, as isk-skin does.
    if (device_) {
      device_->run(method_, pose, /*recompute_normals=*/true);
    } else {
      reference_->run(method_, pose, /*recompute_normals=*/true);
    }
    last_frame_ms_ = millisecondsSince(start);
  }

  FloatArray positions() { return ownedArray(read(true)); }
  FloatArray normals() { return ownedArray(read(false)); }

  py::tuple deform(py::handle matrices) {
    run(matrices);
    FloatArray p = positions();
    return py::make_tuple(p, normals());
  }

  std::string method() const {
    return method_ == SkinningMethod::kDualQuaternion ? "dqs" : "lbs";
  }
  std::string device() const {
    return device_ ? device_->context().info().describe()
                   : std::string("reference (CPU)");
  }
  const Rig& rig() const { return *rig_; }
  double lastFrameMs() const { return last_frame_ms_; }

 private:
  Matrix3Xf read(bool positions) {
    return readLastFrame(*mutex_, device_.get(), reference_.get(), positions);
  }

  RigPtr rig_;
  SkinningMethod method_;
  std::unique_ptr<ClSkinning> device_;
  std::unique_ptr<CpuSkinning> reference_;
  // The device's lock, or this skinner's own on the CPU reference.
  std::shared_ptr<std::mutex> mutex_ = std::make_shared<std::mutex>();
  double last_frame_ms_ = 0;
};

}  // namespace

void registerSkinners(py::module_& m) {
  py::class_<PyImplicitSkinner>(m, "ImplicitSkinner",
                                "Implicit skinning of one rig "
                                "(isk::ImplicitSkinner, "
                                "isk::CpuImplicitSkinner).")
      .def(
          py::init<
              RigPtr, const std::string&, const std::string&, py::object,
              py::object, std::optional<double>, std::optional<double>,
              std::optional<int>, std::optional<float>, std::optional<float>,
              std::optional<int>, std::optional<bool>, std::optional<bool>,
              std::optional<bool>, std::optional<float>, std::optional<float>,
              std::optional<bool>, const std::string&, bool, const std::string&,
              const std::string&, std::optional<std::string>, py::object>(),
          py::arg("rig"), py::kw_only(), py::arg("device") = "opencl",
          py::arg("operator") = "auto", py::arg("joint_operators") = py::none(),
          py::arg("untracked_joints") = py::none(),
          py::arg("bulge_strength") = py::none(),
          py::arg("blend_theta") = py::none(), py::arg("rounds") = py::none(),
          py::arg("sigma") = py::none(), py::arg("contact_angle") = py::none(),
          py::arg("smoothing_steps") = py::none(),
          py::arg("relaxation") = py::none(),
          py::arg("skinned_ring_relaxation") = py::none(),
          py::arg("crease_gate") = py::none(),
          py::arg("volume_restore") = py::none(),
          py::arg("contact_bulge") = py::none(),
          py::arg("dislocation_guard") = py::none(),
          py::arg("base_skinning") = "dqs", py::arg("layers") = true,
          py::arg("rigid_pieces") = "auto", py::arg("tracking") = "2013",
          py::arg("cache_dir") = py::none(), py::arg("progress") = py::none())
      .def("run", &PyImplicitSkinner::run, py::arg("matrices"))
      .def("reset_history", &PyImplicitSkinner::resetHistory,
           "tracking='history': the next frame starts from skinning, as the "
           "first does (a jump in the animation)")
      .def("positions", &PyImplicitSkinner::positions)
      .def("normals", &PyImplicitSkinner::normals)
      .def("deform", &PyImplicitSkinner::deform, py::arg("matrices"))
      .def_property_readonly("contact_count", &PyImplicitSkinner::contactCount)
      .def_property_readonly("last_frame_ms", &PyImplicitSkinner::lastFrameMs)
      .def_property_readonly("build_ms", &PyImplicitSkinner::buildMs)
      .def_property_readonly("stage_times", &PyImplicitSkinner::stageTimes)
      .def_property_readonly("device", &PyImplicitSkinner::device)
      .def_property_readonly(
          "vertex_count",
          [](const PyImplicitSkinner& s) { return s.rig().mesh.vertexCount(); })
      .def_property_readonly("joint_count",
                             [](const PyImplicitSkinner& s) {
                               return s.rig().skeleton.jointCount();
                             })
      .def_property_readonly(
          "warnings", [](const PyImplicitSkinner& s) { return s.warnings(); })
      .def_property_readonly("cache_origin", [](const PyImplicitSkinner& s) {
        return std::string(fieldCacheOriginName(s.fields().cache_origin));
      });

  py::class_<PyGeometricSkinner>(m, "GeometricSkinner",
                                 "Dual quaternion or linear blend skinning "
                                 "of one rig (isk::ClSkinning, "
                                 "isk::CpuSkinning).")
      .def(py::init<RigPtr, const std::string&, const std::string&>(),
           py::arg("rig"), py::kw_only(), py::arg("method") = "dqs",
           py::arg("device") = "opencl")
      .def("run", &PyGeometricSkinner::run, py::arg("matrices"))
      .def("positions", &PyGeometricSkinner::positions)
      .def("normals", &PyGeometricSkinner::normals)
      .def("deform", &PyGeometricSkinner::deform, py::arg("matrices"))
      .def_property_readonly("method", &PyGeometricSkinner::method)
      .def_property_readonly("last_frame_ms", &PyGeometricSkinner::lastFrameMs)
      .def_property_readonly("device", &PyGeometricSkinner::device)
      .def_property_readonly("vertex_count",
                             [](const PyGeometricSkinner& s) {
                               return s.rig().mesh.vertexCount();
                             })
      .def_property_readonly("joint_count", [](const PyGeometricSkinner& s) {
        return s.rig().skeleton.jointCount();
      });
}

}  // namespace isk::python
