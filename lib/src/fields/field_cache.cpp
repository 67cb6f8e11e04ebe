#include "isk/fields/field_cache.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <type_traits>

#include "core/cache_file.hpp"

namespace isk {

namespace detail {

// Appends plain values to a byte string.
class CacheWriter {
 public:
  template <typename T>
  void pod(const T& value) {
    static_assert(std::is_trivially_copyable<T>::value, "plain data only");
    bytes_.append(reinterpret_cast<const char*>(&value), sizeof(T));
  }
  void raw(const void* data, size_t size) {
    bytes_.append(static_cast<const char*>(data), size);
  }
  void string(const std::string& s) {
    pod<uint64_t>(s.size());
    raw(s.data(), s.size());
  }
  void vec3(const Eigen::Vector3d& v) { raw(v.data(), 3 * sizeof(double)); }
  void vec3s(const std::vector<Eigen::Vector3d>& vs) {
    pod<uint64_t>(vs.size());
    for (const auto& v : vs) vec3(v);
  }
  std::string& bytes() { return bytes_; }

 private:
  std::string bytes_;
};

// Reads them back; any read past the end or absurd count sets failed().
class CacheReader {
 public:
  CacheReader(const char* data, size_t size) : data_(data), size_(size) {}

  template <typename T>
  T pod() {
    T value{};
    raw(&value, sizeof(T));
    return value;
  }
  void raw(void* out, size_t size) {
    if (failed_ || size > size_ - at_) {
      failed_ = true;
      return;
    }
    std::memcpy(out, data_ + at_, size);
    at_ += size;
  }
  // A count of items of at least `item_bytes` each that must fit in what
  // is left.
  size_t count(size_t item_bytes) {
    const uint64_t n = pod<uint64_t>();
    if (failed_ || (item_bytes > 0 && n > (size_ - at_) / item_bytes)) {
      failed_ = true;
      return 0;
    }
    return static_cast<size_t>(n);
  }
  std::string string() {
    std::string s(count(1), '\0');
    raw(s.data(), s.size());
    return s;
  }
  Eigen::Vector3d vec3() {
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    raw(v.data(), 3 * sizeof(double));
    return v;
  }
  std::vector<Eigen::Vector3d> vec3s() {
    std::vector<Eigen::Vector3d> vs(count(3 * sizeof(double)));
    for (auto& v : vs) v = vec3();
    return vs;
  }
  bool failed() const { return failed_; }
  bool atEnd() const { return at_ == size_; }

 private:
  const char* data_;
  size_t size_;
  size_t at_ = 0;
  bool failed_ = false;
};

struct HrbfAccess {
  static void write(CacheWriter& w, const Hrbf& h) {
    w.vec3s(h.centres_);
    w.vec3s(h.unit_centres_);
    w.pod<uint64_t>(h.lambda_.size());
    w.raw(h.lambda_.data(), h.lambda_.size() * sizeof(double));
    w.vec3s(h.beta_);
    w.vec3(h.poly_a_);
    w.pod(h.poly_b_);
    w.vec3(h.origin_);
    w.pod(h.scale_);
    w.pod(h.value_residual_);
    w.pod(h.gradient_residual_);
    w.pod<uint8_t>(h.regularised_ ? 1 : 0);
  }
  static void read(CacheReader& r, Hrbf& h) {
    h.centres_ = r.vec3s();
    h.unit_centres_ = r.vec3s();
    h.lambda_.resize(r.count(sizeof(double)));
    r.raw(h.lambda_.data(), h.lambda_.size() * sizeof(double));
    h.beta_ = r.vec3s();
    h.poly_a_ = r.vec3();
    h.poly_b_ = r.pod<double>();
    h.origin_ = r.vec3();
    h.scale_ = r.pod<double>();
    h.value_residual_ = r.pod<double>();
    h.gradient_residual_ = r.pod<double>();
    h.regularised_ = r.pod<uint8_t>() != 0;
  }
};

}  // namespace detail

namespace {

namespace fs = std::filesystem;
using detail::CacheReader;
using detail::CacheWriter;

// Bumped whenever sampling, fitting or baking changes their results.
constexpr uint32_t kFieldBuildVersion = 8;
constexpr detail::CacheFileKind kFieldCacheFile = {
    {'I', 'S', 'K', 'F', 'I', 'E', 'L', 'D'},
    1,  // format version: bumping it orphans every file written
    "an isk field cache",
    detail::ChecksumWords::k64Bit};

// The 64-byte header of a field cache file; the payload follows.
struct FieldCacheHeader {
  detail::CacheFilePreamble preamble;
  uint64_t mesh_hash;
  uint64_t weights_hash;
  uint64_t skeleton_hash;
  uint64_t parameter_hash;
  uint64_t payload_bytes;
  uint64_t checksum;  // of the payload
};
static_assert(sizeof(FieldCacheHeader) == 64,
              "the header is 64 bytes, unpadded");

template <typename Matrix>
uint64_t hashMatrix(const Matrix& m, uint64_t hash) {
  const int64_t rows = m.rows(), cols = m.cols();
  hash = detail::fnv1a(&rows, sizeof(rows), hash);
  hash = detail::fnv1a(&cols, sizeof(cols), hash);
  return detail::fnv1aWords(m.data(), m.size() * sizeof(m.data()[0]), hash);
}

uint64_t meshHash(const Mesh& mesh) {
  uint64_t h = hashMatrix(mesh.positions, detail::kFnvOffset);
  h = hashMatrix(mesh.normals, h);
  return hashMatrix(mesh.triangles, h);
}

uint64_t weightsHash(const SkinWeights& w) {
  uint64_t h = detail::kFnvOffset;
  for (const auto* v : {&w.offsets, &w.joints}) {
    const uint64_t n = v->size();
    h = detail::fnv1a(&n, sizeof(n), h);
    h = detail::fnv1aWords(v->data(), v->size() * sizeof(uint32_t), h);
  }
  const uint64_t n = w.weights.size();
  h = detail::fnv1a(&n, sizeof(n), h);
  return detail::fnv1aWords(w.weights.data(), n * sizeof(float), h);
}

uint64_t skeletonHash(const Skeleton& s) {
  uint64_t h = detail::kFnvOffset;
  for (const Joint& j : s.joints) {
    const uint64_t length = j.name.size();
    h = detail::fnv1a(&length, sizeof(length), h);
    h = detail::fnv1a(j.name.data(), j.name.size(), h);
    const int32_t parent = j.parent;
    const uint8_t skin = j.is_skin_joint ? 1 : 0;
    h = detail::fnv1a(&parent, sizeof(parent), h);
    h = detail::fnv1a(&skin, sizeof(skin), h);
    h = detail::fnv1a(j.rest_local.matrix().data(), 16 * sizeof(float), h);
    h = detail::fnv1a(j.inverse_bind.matrix().data(), 16 * sizeof(float), h);
  }
  return detail::fnv1a(s.root_parent.matrix().data(), 16 * sizeof(float), h);
}

uint64_t parameterHash(const ImplicitFieldsOptions& o) {
  char text[256];
  std::snprintf(text, sizeof(text),
                "build=%u samples=%d h=%.17g closure=%d seed=%u grid=%d "
                "skin_only=%d",
                kFieldBuildVersion, o.sampling.target_samples,
                o.sampling.culling_h, o.sampling.closure_points ? 1 : 0,
                o.sampling.seed, o.grid_resolution,
                o.sampling.skin_only ? 1 : 0);
  uint64_t h = detail::fnv1a(text, std::strlen(text));
  for (const auto& [name, samples] : o.joint_samples) {
    const uint64_t length = name.size();
    h = detail::fnv1a(&length, sizeof(length), h);
    h = detail::fnv1a(name.data(), name.size(), h);
    h = detail::fnv1a(&samples, sizeof(samples), h);
  }
  return h;
}

void writeSamples(CacheWriter& w, const HermiteSamples& s) {
  w.vec3s(s.positions);
  w.vec3s(s.normals);
}
HermiteSamples readSamples(CacheReader& r) {
  HermiteSamples s;
  s.positions = r.vec3s();
  s.normals = r.vec3s();
  return s;
}

template <typename Scalar>
void writeIsometry(CacheWriter& w,
                   const Eigen::Transform<Scalar, 3, Eigen::Isometry>& t) {
  w.raw(t.matrix().data(), 16 * sizeof(Scalar));
}
template <typename Scalar>
void readIsometry(CacheReader& r,
                  Eigen::Transform<Scalar, 3, Eigen::Isometry>& t) {
  Eigen::Matrix<Scalar, 4, 4> m = Eigen::Matrix<Scalar, 4, 4>::Identity();
  r.raw(m.data(), 16 * sizeof(Scalar));
  t.matrix() = m;
}

std::string payloadOf(const ImplicitFields& fields) {
  CacheWriter w;
  w.pod<uint64_t>(fields.warnings.size());
  for (const std::string& s : fields.warnings) w.string(s);
  w.pod<int32_t>(fields.grids.resolution);
  w.pod<uint64_t>(fields.fields.size());
  for (size_t i = 0; i < fields.fields.size(); ++i) {
    const BoneSamples& s = fields.samples[i];
    w.pod<int32_t>(s.joint);
    writeSamples(w, s.surface);
    writeSamples(w, s.closure);
    w.pod<int32_t>(s.culled);

    const BoneField& f = fields.fields[i];
    w.pod<int32_t>(f.joint);
    detail::HrbfAccess::write(w, f.hrbf);
    w.pod(f.radius);
    w.pod(f.guard_radius);
    const BoneSegment& g = f.segment;
    w.pod<int32_t>(g.joint);
    w.vec3(g.start);
    w.vec3(g.end);
    w.pod<int32_t>(g.end_joint);
    w.pod<uint8_t>(g.degenerate);
    w.pod<uint8_t>(g.close_start);
    w.pod<uint8_t>(g.close_end);
    writeIsometry(w, f.bone_to_model);
    w.vec3(f.support_box.min());
    w.vec3(f.support_box.max());

    const FieldGrid& grid = fields.grids.grids[i];
    w.pod<int32_t>(grid.joint);
    w.pod<int32_t>(grid.resolution);
    writeIsometry(w, grid.bone_to_model);
    w.raw(grid.box_min.data(), 3 * sizeof(float));
    w.raw(grid.box_max.data(), 3 * sizeof(float));
    w.pod<uint64_t>(grid.nodes.size());
    w.raw(grid.nodes.data(), grid.nodes.size() * sizeof(float));
  }
  return std::move(w.bytes());
}

// False when the payload is inconsistent.
bool readPayload(const char* data, size_t size, int joint_count,
                 ImplicitFields* out) {
  CacheReader r(data, size);
  ImplicitFields in;
  in.warnings.resize(r.count(8));
  for (std::string& s : in.warnings) s = r.string();
  in.grids.resolution = r.pod<int32_t>();
  const size_t n = r.count(64);
  in.samples.resize(n);
  in.fields.resize(n);
  in.grids.grids.resize(n);
  in.grids.field_of_joint.assign(joint_count, -1);
  for (size_t i = 0; i < n && !r.failed(); ++i) {
    BoneSamples& s = in.samples[i];
    s.joint = r.pod<int32_t>();
    s.surface = readSamples(r);
    s.closure = readSamples(r);
    s.culled = r.pod<int32_t>();

    BoneField& f = in.fields[i];
    f.joint = r.pod<int32_t>();
    detail::HrbfAccess::read(r, f.hrbf);
    f.radius = r.pod<double>();
    f.guard_radius = r.pod<double>();
    BoneSegment& g = f.segment;
    g.joint = r.pod<int32_t>();
    g.start = r.vec3();
    g.end = r.vec3();
    g.end_joint = r.pod<int32_t>();
    g.degenerate = r.pod<uint8_t>() != 0;
    g.close_start = r.pod<uint8_t>() != 0;
    g.close_end = r.pod<uint8_t>() != 0;
    readIsometry(r, f.bone_to_model);
    const Eigen::Vector3d lo = r.vec3(), hi = r.vec3();
    f.support_box = Eigen::AlignedBox3d(lo, hi);

    FieldGrid& grid = in.grids.grids[i];
    grid.joint = r.pod<int32_t>();
    grid.resolution = r.pod<int32_t>();
    readIsometry(r, grid.bone_to_model);
    r.raw(grid.box_min.data(), 3 * sizeof(float));
    r.raw(grid.box_max.data(), 3 * sizeof(float));
    grid.nodes.resize(r.count(sizeof(float)));
    r.raw(grid.nodes.data(), grid.nodes.size() * sizeof(float));
    if (r.failed()) return false;
    const size_t res = static_cast<size_t>(grid.resolution);
    if (grid.joint < 0 || grid.joint >= joint_count || f.joint != grid.joint ||
        grid.resolution != in.grids.resolution ||
        grid.nodes.size() != 4 * res * res * res ||
        in.grids.field_of_joint[grid.joint] != -1)
      return false;
    in.grids.field_of_joint[grid.joint] = static_cast<int>(i);
  }
  if (r.failed() || !r.atEnd()) return false;
  out->warnings = std::move(in.warnings);
  out->samples = std::move(in.samples);
  out->fields = std::move(in.fields);
  out->grids = std::move(in.grids);
  return true;
}

}  // namespace

std::string fieldCacheFileName(const Rig& rig,
                               const ImplicitFieldsOptions& options) {
  return "fields-v" + std::to_string(kFieldCacheFile.format_version) + "-" +
         detail::hashText(detail::fnv1a(rig.source.data(), rig.source.size())) +
         "-" + detail::hashText(parameterHash(options)) + ".bin";
}

bool saveFieldCache(const ImplicitFields& fields, const Rig& rig,
                    const ImplicitFieldsOptions& options,
                    const std::string& path, std::string* error) {
  if (fields.samples.size() != fields.fields.size() ||
      fields.grids.grids.size() != fields.fields.size()) {
    if (error) *error = "the fields' samples, fits and grids differ in count";
    return false;
  }
  const std::string payload = payloadOf(fields);
  FieldCacheHeader header{};
  header.preamble = detail::cacheFilePreamble(kFieldCacheFile);
  header.mesh_hash = meshHash(rig.mesh);
  header.weights_hash = weightsHash(rig.weights);
  header.skeleton_hash = skeletonHash(rig.skeleton);
  header.parameter_hash = parameterHash(options);
  header.payload_bytes = payload.size();
  header.checksum = detail::cacheFileChecksum(kFieldCacheFile, payload.data(),
                                              payload.size());
  return detail::writeFileAtomically(
      path, {{&header, sizeof(header)}, {payload.data(), payload.size()}},
      detail::ParentFolder::kCreate, error);
}

bool loadFieldCache(const std::string& path, const Rig& rig,
                    const ImplicitFieldsOptions& options,
                    ImplicitFields* fields, std::string* error, bool* stale) {
  if (stale) *stale = false;
  auto fail = [&](const std::string& why, bool is_stale = false) {
    if (error) *error = why;
    if (stale) *stale = is_stale;
    return false;
  };
  // Mapped rather than read: the payload is parsed straight from the page
  // cache, with no intermediate copy (fresh memory is what a load costs).
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) return fail("cannot open '" + path + "'");
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    ::close(fd);
    return fail("cannot read the size of '" + path + "'");
  }
  const size_t size = static_cast<size_t>(st.st_size);
  if (size < sizeof(FieldCacheHeader)) {
    ::close(fd);
    return fail("'" + path + "' is shorter than its header (corrupt)");
  }
  void* mapped = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE, fd, 0);
  ::close(fd);
  if (mapped == MAP_FAILED) return fail("cannot map '" + path + "'");
  struct Unmap {
    void* p;
    size_t n;
    ~Unmap() { ::munmap(p, n); }
  } unmap{mapped, size};
  const char* bytes = static_cast<const char*>(mapped);
  FieldCacheHeader header{};
  std::memcpy(&header, bytes, sizeof(header));
  std::string mismatch;
  switch (detail::matchCacheFilePreamble(header.preamble, kFieldCacheFile, path,
                                         &mismatch)) {
    case detail::PreambleMatch::kMatches:
      break;
    case detail::PreambleMatch::kOtherKind:
      return fail(mismatch);
    case detail::PreambleMatch::kOtherFormatVersion:
    case detail::PreambleMatch::kOtherByteOrder:
      return fail(mismatch, true);  // ours, from another build or machine
  }
  if (header.parameter_hash != parameterHash(options))
    return fail("'" + path + "' was built with other parameters", true);
  if (header.mesh_hash != meshHash(rig.mesh))
    return fail("'" + path +
                    "' is stale: the mesh changed (positions, normals or "
                    "triangles)",
                true);
  if (header.weights_hash != weightsHash(rig.weights))
    return fail("'" + path + "' is stale: the skin weights changed", true);
  if (header.skeleton_hash != skeletonHash(rig.skeleton))
    return fail("'" + path + "' is stale: the skeleton changed", true);
  if (header.payload_bytes != size - sizeof(FieldCacheHeader))
    return fail(
        "'" + path + "' has " + std::to_string(size) +
        " bytes, its header says " +
        std::to_string(header.payload_bytes + sizeof(FieldCacheHeader)) +
        " (corrupt)");
  const char* payload = bytes + sizeof(FieldCacheHeader);
  const size_t payload_size = size - sizeof(FieldCacheHeader);
  if (!detail::checkCacheFileChecksum(kFieldCacheFile, payload, payload_size,
                                      header.checksum, path, error))
    return false;
  if (!readPayload(payload, payload_size, rig.skeleton.jointCount(), fields))
    return fail("'" + path + "' holds an inconsistent payload (corrupt)");
  return true;
}

}  // namespace isk
