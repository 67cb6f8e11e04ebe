#include "io/rig_serialization.hpp"

#include <cstdint>
#include <cstring>
#include <type_traits>

#include "isk/core/error.hpp"

namespace isk::detail {
namespace {

// The layout starts with this tag so that bytes of another producer are
// refused instead of misread.
constexpr char kMagic[8] = {'i', 's', 'k', 'r', 'i', 'g', '0', '1'};

class Writer {
 public:
  template <typename T>
  void pod(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    bytes_.append(reinterpret_cast<const char*>(&value), sizeof(T));
  }
  void count(size_t n) { pod(static_cast<uint64_t>(n)); }
  void raw(const void* data, size_t size) {
    bytes_.append(static_cast<const char*>(data), size);
  }
  void text(const std::string& s) {
    count(s.size());
    raw(s.data(), s.size());
  }
  template <typename T>
  void array(const std::vector<T>& values) {
    static_assert(std::is_trivially_copyable_v<T>);
    count(values.size());
    raw(values.data(), values.size() * sizeof(T));
  }
  void affine(const Eigen::Affine3f& t) { raw(t.matrix().data(), 16 * 4); }
  std::string take() { return std::move(bytes_); }

 private:
  std::string bytes_;
};

class Reader {
 public:
  explicit Reader(const std::string& bytes) : bytes_(bytes) {}

  void raw(void* out, size_t size, const char* field) {
    if (size > bytes_.size() - at_) {
      throw Error(ErrorCode::kInternal,
                  std::string("serialized rig: truncated at '") + field +
                      "' (needs " + std::to_string(size) + " bytes at offset " +
                      std::to_string(at_) + " of " +
                      std::to_string(bytes_.size()) + ")");
    }
    if (size > 0) std::memcpy(out, bytes_.data() + at_, size);
    at_ += size;
  }
  template <typename T>
  T pod(const char* field) {
    T value;
    raw(&value, sizeof(T), field);
    return value;
  }
  // A count of items of `item_size` bytes that must fit what is left.
  size_t count(size_t item_size, const char* field) {
    const uint64_t n = pod<uint64_t>(field);
    if (item_size > 0 && n > (bytes_.size() - at_) / item_size) {
      throw Error(ErrorCode::kInternal,
                  std::string("serialized rig: count of '") + field + "' (" +
                      std::to_string(n) + ") exceeds the remaining bytes");
    }
    return static_cast<size_t>(n);
  }
  std::string text(const char* field) {
    std::string s(count(1, field), '\0');
    raw(s.data(), s.size(), field);
    return s;
  }
  template <typename T>
  std::vector<T> array(const char* field) {
    std::vector<T> values(count(sizeof(T), field));
    raw(values.data(), values.size() * sizeof(T), field);
    return values;
  }
  Eigen::Affine3f affine(const char* field) {
    Eigen::Affine3f t;
    raw(t.matrix().data(), 16 * 4, field);
    return t;
  }
  bool atEnd() const { return at_ == bytes_.size(); }

 private:
  const std::string& bytes_;
  size_t at_ = 0;
};

template <typename Matrix>
void writeRows(Writer& w, const Matrix& m) {
  w.count(static_cast<size_t>(m.rows()));
  w.raw(m.data(),
        static_cast<size_t>(m.size()) * sizeof(typename Matrix::Scalar));
}

template <typename Matrix>
void readRows(Reader& r, Matrix& m, const char* field) {
  const size_t rows =
      r.count(m.ColsAtCompileTime * sizeof(typename Matrix::Scalar), field);
  m.resize(static_cast<Eigen::Index>(rows), m.ColsAtCompileTime);
  r.raw(m.data(),
        static_cast<size_t>(m.size()) * sizeof(typename Matrix::Scalar), field);
}

// The floats of a key value (3 for a vector, x y z w for a quaternion).
inline const float* floatsOf(const Eigen::Vector3f& v) { return v.data(); }
inline float* floatsOf(Eigen::Vector3f& v) { return v.data(); }
inline const float* floatsOf(const Eigen::Quaternionf& q) {
  return q.coeffs().data();
}
inline float* floatsOf(Eigen::Quaternionf& q) { return q.coeffs().data(); }
template <typename T>
constexpr size_t kFloatsOf = std::is_same_v<T, Eigen::Quaternionf> ? 4 : 3;

template <typename T>
void writeVectors(Writer& w, const std::vector<T>& values) {
  w.count(values.size());
  for (const T& v : values) w.raw(floatsOf(v), sizeof(float) * kFloatsOf<T>);
}

template <typename T>
std::vector<T> readVectors(Reader& r, const char* field) {
  std::vector<T> values(r.count(sizeof(float) * kFloatsOf<T>, field));
  for (T& v : values) r.raw(floatsOf(v), sizeof(float) * kFloatsOf<T>, field);
  return values;
}

}  // namespace

std::string serializeRig(const Rig& rig) {
  Writer w;
  w.raw(kMagic, sizeof(kMagic));
  w.text(rig.source);

  writeRows(w, rig.mesh.positions);
  writeRows(w, rig.mesh.normals);
  writeRows(w, rig.mesh.triangles);
  w.count(rig.mesh.parts.size());
  for (const MeshPart& part : rig.mesh.parts) {
    w.text(part.name);
    w.pod(part.first_vertex);
    w.pod(part.vertex_count);
    w.pod(part.first_triangle);
    w.pod(part.triangle_count);
  }

  w.count(rig.skeleton.joints.size());
  for (const Joint& joint : rig.skeleton.joints) {
    w.text(joint.name);
    w.pod(joint.parent);
    w.affine(joint.rest_local);
    w.affine(joint.inverse_bind);
    w.pod(static_cast<uint8_t>(joint.is_skin_joint));
  }
  w.affine(rig.skeleton.root_parent);

  w.array(rig.weights.offsets);
  w.array(rig.weights.joints);
  w.array(rig.weights.weights);

  w.count(rig.clips.size());
  for (const AnimationClip& clip : rig.clips) {
    w.text(clip.name);
    w.pod(clip.start);
    w.pod(clip.duration);
    w.count(clip.channels.size());
    for (const JointChannel& channel : clip.channels) {
      w.pod(channel.joint);
      w.array(channel.translation_times);
      writeVectors(w, channel.translations);
      w.array(channel.rotation_times);
      writeVectors(w, channel.rotations);
      w.array(channel.scale_times);
      writeVectors(w, channel.scales);
    }
  }

  w.count(rig.warnings.size());
  for (const std::string& warning : rig.warnings) w.text(warning);
  return w.take();
}

Rig deserializeRig(const std::string& bytes) {
  Reader r(bytes);
  char magic[sizeof(kMagic)];
  r.raw(magic, sizeof(magic), "magic");
  if (std::memcmp(magic, kMagic, sizeof(kMagic)) != 0) {
    throw Error(ErrorCode::kInternal,
                "serialized rig: the bytes do not start with the rig tag");
  }
  Rig rig;
  rig.source = r.text("source");

  readRows(r, rig.mesh.positions, "mesh.positions");
  readRows(r, rig.mesh.normals, "mesh.normals");
  readRows(r, rig.mesh.triangles, "mesh.triangles");
  rig.mesh.parts.resize(r.count(8 + 4 * sizeof(int), "mesh.parts"));
  for (MeshPart& part : rig.mesh.parts) {
    part.name = r.text("part.name");
    part.first_vertex = r.pod<int>("part.first_vertex");
    part.vertex_count = r.pod<int>("part.vertex_count");
    part.first_triangle = r.pod<int>("part.first_triangle");
    part.triangle_count = r.pod<int>("part.triangle_count");
  }

  rig.skeleton.joints.resize(r.count(8 + 4 + 2 * 64 + 1, "skeleton.joints"));
  for (Joint& joint : rig.skeleton.joints) {
    joint.name = r.text("joint.name");
    joint.parent = r.pod<int>("joint.parent");
    joint.rest_local = r.affine("joint.rest_local");
    joint.inverse_bind = r.affine("joint.inverse_bind");
    joint.is_skin_joint = r.pod<uint8_t>("joint.is_skin_joint") != 0;
  }
  rig.skeleton.root_parent = r.affine("skeleton.root_parent");

  rig.weights.offsets = r.array<uint32_t>("weights.offsets");
  rig.weights.joints = r.array<uint32_t>("weights.joints");
  rig.weights.weights = r.array<float>("weights.weights");

  rig.clips.resize(r.count(8 + 2 * sizeof(double) + 8, "clips"));
  for (AnimationClip& clip : rig.clips) {
    clip.name = r.text("clip.name");
    clip.start = r.pod<double>("clip.start");
    clip.duration = r.pod<double>("clip.duration");
    clip.channels.resize(r.count(4 + 6 * 8, "clip.channels"));
    for (JointChannel& channel : clip.channels) {
      channel.joint = r.pod<int>("channel.joint");
      channel.translation_times = r.array<double>("channel.translation_times");
      channel.translations =
          readVectors<Eigen::Vector3f>(r, "channel.translations");
      channel.rotation_times = r.array<double>("channel.rotation_times");
      channel.rotations =
          readVectors<Eigen::Quaternionf>(r, "channel.rotations");
      channel.scale_times = r.array<double>("channel.scale_times");
      channel.scales = readVectors<Eigen::Vector3f>(r, "channel.scales");
    }
  }

  rig.warnings.resize(r.count(8, "warnings"));
  for (std::string& warning : rig.warnings) warning = r.text("warning");
  if (!r.atEnd()) {
    throw Error(ErrorCode::kInternal,
                "serialized rig: bytes left over after the last field");
  }
  return rig;
}

}  // namespace isk::detail
