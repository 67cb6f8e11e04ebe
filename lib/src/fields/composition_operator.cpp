#include "isk/fields/composition_operator.hpp"

#include <sys/mman.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <utility>

#include "core/cache_file.hpp"
#include "core/parallel_for.hpp"
#include "fields/trilinear.hpp"
#include "isk/core/error.hpp"

namespace isk {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kInnerUnion = 0.7;  // Appendix A: a union deeper inside

double clamp01(double v) { return std::min(1.0, std::max(0.0, v)); }
double clampTheta(double theta) {
  return std::min(kThetaUnion, std::max(0.0, theta));
}

// k(C) and k'(C) of the blend's opening (header comment).
struct Opening {
  double k, dk;
};
Opening opening(double c, double t) {
  if (c <= 0.5) return {t * c, t};
  if (c < kInnerUnion)
    return {0.5 * (7 - 5 * t) * c + 1.75 * (t - 1), 0.5 * (7 - 5 * t)};
  return {c, 1};
}

// The blend with its larger argument first (x >= y): value and partials.
// tan(theta), 1 (the union) within rounding of theta_u.
double openingSlope(double theta) {
  const double t = std::tan(clampTheta(theta));
  return t > 1 - 1e-9 ? 1.0 : t;
}

OperatorValue blendOrdered(double x, double y, double theta) {
  const double t = openingSlope(theta);
  // At x = 0 both fields vanish: the union's partials (the blend's are
  // undefined at the origin, where it is homogeneous of degree 1).
  if (x >= kInnerUnion || y < opening(x, t).k || x <= 0 || t == 1)
    return {x, 1, 0};
  // Is (x, y) below the iso-curve C (inside its circle, or outside the
  // quadrant the arc spans)? False at C = x, true at C = 0.7.
  auto below = [&](double c) {
    const Opening o = opening(c, t);
    return x < o.k || y < o.k || std::hypot(x - o.k, y - o.k) < c - o.k;
  };
  double lo = x, hi = kInnerUnion;
  for (int i = 0; i < 60 && hi - lo > 1e-13; ++i) {
    const double mid = 0.5 * (lo + hi);
    (below(mid) ? hi : lo) = mid;
  }
  const double c = 0.5 * (lo + hi);
  const Opening o = opening(c, t);
  const double d = std::hypot(x - o.k, y - o.k);
  if (d < 1e-12) return {c, 0.5, 0.5};  // the corner (0.7, 0.7)
  // Implicit function theorem on F(C, x, y) = d - (C - k(C)) = 0.
  const double dF_dc = -o.dk * ((x - o.k) + (y - o.k)) / d - (1 - o.dk);
  return {c, -((x - o.k) / d) / dF_dc, -((y - o.k) / d) / dF_dc};
}

bool blendRegionOrdered(double x, double y, double theta) {
  const double t = openingSlope(theta);
  return x < kInnerUnion && y >= opening(x, t).k && t < 1;
}

// The bulge's terms (header comment).
double bulgeQ(double m, double* dq) {
  const double q = (m - 0.5) / 0.2;
  if (std::abs(q) >= 1) {
    *dq = 0;
    return 0;
  }
  const double a = 1 - q * q;
  *dq = -4 * q * a / 0.2;
  return a * a;
}
double bulgeS(double m, double* ds) {
  const double u = (m - 0.1) / 0.4;
  if (u <= 0) {
    *ds = 0;
    return 0;
  }
  if (u >= 1) {
    *ds = 0;
    return 1;
  }
  *ds = 6 * u * (1 - u) / 0.4;
  return u * u * (3 - 2 * u);
}
// g = x + A s Q(x) S(y) for any (x, y): for x >= y the operator, beyond the
// diagonal its smooth continuation.
OperatorValue bulgeBranch(double x, double y, double theta) {
  const double s = 1 - clampTheta(theta) / kThetaUnion;
  double dq = 0, ds = 0;
  const double q = bulgeQ(x, &dq);
  const double sy = bulgeS(y, &ds);
  const double a = kBulgeAmplitude * s;
  return {x + a * q * sy, 1 + a * dq * sy, a * q * ds};
}

// The branch a table stores at (x, y): the operator with x as its larger
// argument, continued smoothly beyond the diagonal.
OperatorValue tableBranch(CompositionOperator op, double x, double y,
                          double theta) {
  if (op == CompositionOperator::kBulge) return bulgeBranch(x, y, theta);
  if (y <= x) return blendOrdered(x, y, theta);
  // Beyond the diagonal: where the blend is smooth across it, the blend
  // itself; else the union's branch, x.
  if (blendRegionOrdered(y, x, theta)) return blendOperator(x, y, theta);
  return {x, 1, 0};
}

// A symmetric operator from its branch with the larger argument first:
// f1, f2 clamped to [0, 1], ordered, and the partials swapped back.
OperatorValue symmetric(OperatorValue (*ordered)(double, double, double),
                        double f1, double f2, double theta) {
  f1 = clamp01(f1);
  f2 = clamp01(f2);
  if (f2 <= f1) return ordered(f1, f2, theta);
  OperatorValue v = ordered(f2, f1, theta);
  std::swap(v.dg_df1, v.dg_df2);
  return v;
}

ThetaController sampledController(double (*theta)(double alpha,
                                                  double parameter),
                                  double parameter) {
  ThetaController c;
  c.theta.resize(kControllerSamples);
  for (int i = 0; i < kControllerSamples; ++i)
    c.theta[i] = static_cast<float>(
        theta(kPi * i / (kControllerSamples - 1), parameter));
  return c;
}

// `count` zeroed floats in `nodes`, on transparent huge pages where the
// kernel offers them on request (THP "madvise"): a table is 32 MiB, and
// faulting it in 4 KiB pages costs more than reading or baking it on some
// virtual machines.
void allocateNodes(std::vector<float>& nodes, size_t count) {
  nodes.clear();
  nodes.shrink_to_fit();
  nodes.reserve(count);  // large: mapped, not yet touched
#ifdef MADV_HUGEPAGE
  constexpr uintptr_t kHuge = uintptr_t{1} << 21;
  const uintptr_t begin = reinterpret_cast<uintptr_t>(nodes.data());
  const uintptr_t end = begin + count * sizeof(float);
  const uintptr_t first = (begin + kHuge - 1) & ~(kHuge - 1);
  const uintptr_t last = end & ~(kHuge - 1);
  if (last > first)
    ::madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
#endif
  nodes.resize(count, 0.f);
}

}  // namespace

const char* compositionOperatorName(CompositionOperator op) {
  switch (op) {
    case CompositionOperator::kUnion:
      return "union";
    case CompositionOperator::kBlend:
      return "blend";
    case CompositionOperator::kBulge:
      return "bulge";
  }
  return "unknown";
}

bool parseCompositionOperator(const std::string& name,
                              CompositionOperator* op) {
  for (CompositionOperator candidate :
       {CompositionOperator::kUnion, CompositionOperator::kBlend,
        CompositionOperator::kBulge}) {
    if (name == compositionOperatorName(candidate)) {
      if (op) *op = candidate;
      return true;
    }
  }
  return false;
}

OperatorValue unionOperator(double f1, double f2) {
  return f1 >= f2 ? OperatorValue{f1, 1, 0} : OperatorValue{f2, 0, 1};
}

OperatorValue blendOperator(double f1, double f2, double theta) {
  return symmetric(blendOrdered, f1, f2, theta);
}

OperatorValue bulgeOperator(double f1, double f2, double theta) {
  return symmetric(bulgeBranch, f1, f2, theta);
}

OperatorValue evaluateOperator(CompositionOperator op, double f1, double f2,
                               double theta) {
  switch (op) {
    case CompositionOperator::kBlend:
      return blendOperator(f1, f2, theta);
    case CompositionOperator::kBulge:
      return bulgeOperator(f1, f2, theta);
    case CompositionOperator::kUnion:
      break;
  }
  return unionOperator(f1, f2);
}

bool inBlendingRegion(CompositionOperator op, double f1, double f2,
                      double theta) {
  const double x = std::max(f1, f2), y = std::min(f1, f2);
  switch (op) {
    case CompositionOperator::kBlend:
      return blendRegionOrdered(x, y, theta);
    case CompositionOperator::kBulge:
      return x > 0.3 && x < kInnerUnion && y > 0.1 &&
             clampTheta(theta) < kThetaUnion;
    case CompositionOperator::kUnion:
      break;
  }
  return false;
}

float ThetaController::at(float alpha) const {
  const int n = static_cast<int>(theta.size());
  if (n == 0) return static_cast<float>(kThetaUnion);
  if (n == 1) return theta[0];
  const float scale = static_cast<float>(n - 1) / static_cast<float>(kPi);
  const float a =
      std::min(std::max(alpha * scale, 0.f), static_cast<float>(n - 1));
  const int i = std::min(static_cast<int>(a), n - 2);
  const float t = a - static_cast<float>(i);
  return theta[i] + t * (theta[i + 1] - theta[i]);
}

ThetaController unionController() {
  return sampledController([](double, double) { return kThetaUnion; }, 0);
}

ThetaController blendController(double theta_blend) {
  return sampledController(
      [](double alpha, double theta_b) {
        if (alpha >= kPi / 2) return kThetaUnion;
        const double s = std::sin(2 * alpha);
        return kThetaUnion - (kThetaUnion - theta_b) * s * s;
      },
      clampTheta(theta_blend));
}

ThetaController bulgeController(double strength) {
  return sampledController(
      [](double alpha, double k) {
        const double s = alpha >= kPi / 2 ? 1.0 : std::sin(alpha);
        return kThetaUnion - k * kThetaUnion * s * s;
      },
      clamp01(strength));
}

ThetaController defaultController(CompositionOperator op) {
  switch (op) {
    case CompositionOperator::kBlend:
      return blendController();
    case CompositionOperator::kBulge:
      return bulgeController();
    case CompositionOperator::kUnion:
      break;
  }
  return unionController();
}

void OperatorTable::sample(float f1, float f2, float theta,
                           float out[3]) const {
  const bool first = f1 >= f2;
  const float x = first ? f1 : f2;
  const float y = first ? f2 : f1;
  const float last = static_cast<float>(resolution - 1);
  const float theta_scale = last / static_cast<float>(kThetaUnion);
  const float u[3] = {std::min(std::max(x, 0.f), 1.f) * last,
                      std::min(std::max(y, 0.f), 1.f) * last,
                      std::min(std::max(theta * theta_scale, 0.f), last)};
  const Eigen::Vector4f value =
      detail::trilinearNodes(nodes.data(), resolution, u);
  out[0] = value[0];
  out[1] = first ? value[1] : value[2];
  out[2] = first ? value[2] : value[1];
}

OperatorTable bakeOperatorTable(CompositionOperator op, int resolution,
                                int threads,
                                const std::function<void(float)>& progress) {
  if (op == CompositionOperator::kUnion)
    throw Error(ErrorCode::kInvalidArgument,
                "bakeOperatorTable: the union is max(f1, f2), it has no table");
  if (resolution < 2 || resolution > 512)
    throw Error(ErrorCode::kInvalidArgument, "bakeOperatorTable: resolution " +
                                                 std::to_string(resolution) +
                                                 " is outside 2..512");
  OperatorTable table;
  table.op = op;
  table.resolution = resolution;
  const size_t n = static_cast<size_t>(resolution);
  allocateNodes(table.nodes, 4 * n * n * n);
  const double last = resolution - 1;
  // One theta slice per work item.
  detail::parallelFor(
      resolution, detail::threadCount(threads),
      [&](int k) {
        const double theta = kThetaUnion * k / last;
        for (size_t j = 0; j < n; ++j) {
          for (size_t i = 0; i < n; ++i) {
            const OperatorValue v = tableBranch(op, i / last, j / last, theta);
            float* node = &table.nodes[4 * (i + n * (j + n * k))];
            node[0] = static_cast<float>(v.g);
            node[1] = static_cast<float>(v.dg_df1);
            node[2] = static_cast<float>(v.dg_df2);
          }
        }
      },
      progress);
  return table;
}

std::shared_ptr<const OperatorTable> sharedOperatorTable(
    CompositionOperator op, int resolution,
    const std::function<void(float)>& progress,
    std::vector<std::string>* warnings) {
  static std::mutex mutex;
  static std::map<std::pair<int, int>, std::shared_ptr<const OperatorTable>>
      cache;
  std::lock_guard<std::mutex> lock(mutex);
  auto& slot = cache[{static_cast<int>(op), resolution}];
  if (!slot) {
    slot = std::make_shared<const OperatorTable>(
        loadOrBakeOperatorTable(op, resolution, operatorTableCacheFolder(), 0,
                                progress, nullptr, warnings));
  } else if (progress) {
    progress(1.f);
  }
  return slot;
}

// ---------------------------------------------------------------------------
// On-disk cache of operator tables.

namespace {

namespace fs = std::filesystem;

// Bump whenever the operator math or the table layout changes: the
// parameter hash, hence the file name, changes with it.
constexpr uint32_t kOperatorBakeVersion = 1;
constexpr detail::CacheFileKind kOperatorTableFile = {
    {'I', 'S', 'K', 'O', 'P', 'T', 'B', 'L'},
    1,  // format version: bumping it orphans every file written
    "an isk operator table",
    detail::ChecksumWords::k32Bit};

// The 48-byte header of a table file; the nodes follow.
struct TableFileHeader {
  detail::CacheFilePreamble preamble;
  uint32_t op;
  uint32_t resolution;
  uint64_t parameter_hash;
  uint64_t float_count;
  uint64_t checksum;  // of the nodes
};
static_assert(sizeof(TableFileHeader) == 48,
              "the header is 48 bytes, unpadded");

// Everything a bake depends on besides (op, resolution).
uint64_t bakeParameterHash(CompositionOperator op, int resolution) {
  char text[256];
  std::snprintf(text, sizeof(text),
                "bake=%u op=%s n=%d theta_u=%.17g inner=%.17g bulge=%.17g "
                "layout=float4(g,dg/dx,dg/dy,0) x>=y",
                kOperatorBakeVersion, compositionOperatorName(op), resolution,
                kThetaUnion, kInnerUnion, kBulgeAmplitude);
  return detail::fnv1a(text, std::strlen(text));
}

size_t nodeFloatCount(int resolution) {
  const size_t n = static_cast<size_t>(resolution);
  return 4 * n * n * n;
}

}  // namespace

std::string operatorTableCacheFolder() {
  if (const char* dir = std::getenv("ISK_CACHE_DIR"); dir && *dir) {
    const std::string value = dir;
    if (value == "off") return "";
    return value;
  }
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg)
    return (fs::path(xdg) / "isk").string();
  if (const char* home = std::getenv("HOME"); home && *home)
    return (fs::path(home) / ".cache" / "isk").string();
  return "";
}

std::string operatorTableCacheFileName(CompositionOperator op, int resolution) {
  return "operator-table-v" +
         std::to_string(kOperatorTableFile.format_version) + "-" +
         compositionOperatorName(op) + "-" + std::to_string(resolution) + "-" +
         detail::hashText(bakeParameterHash(op, resolution)) + ".bin";
}

bool saveOperatorTable(const OperatorTable& table, const std::string& path,
                       std::string* error) {
  if (table.nodes.size() != nodeFloatCount(table.resolution)) {
    if (error)
      *error = "the table holds " + std::to_string(table.nodes.size()) +
               " floats, not 4 * " + std::to_string(table.resolution) + "^3";
    return false;
  }
  const size_t bytes = table.nodes.size() * sizeof(float);
  TableFileHeader header{};
  header.preamble = detail::cacheFilePreamble(kOperatorTableFile);
  header.op = static_cast<uint32_t>(table.op);
  header.resolution = static_cast<uint32_t>(table.resolution);
  header.parameter_hash = bakeParameterHash(table.op, table.resolution);
  header.float_count = table.nodes.size();
  header.checksum =
      detail::cacheFileChecksum(kOperatorTableFile, table.nodes.data(), bytes);
  return detail::writeFileAtomically(
      path, {{&header, sizeof(header)}, {table.nodes.data(), bytes}},
      detail::ParentFolder::kCreate, error);
}

bool loadOperatorTable(const std::string& path, CompositionOperator op,
                       int resolution, OperatorTable* table,
                       std::string* error) {
  auto fail = [&](const std::string& why) {
    if (error) *error = why;
    return false;
  };
  if (resolution < 2 || resolution > 512)
    return fail("resolution " + std::to_string(resolution) +
                " is outside 2..512");
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail("cannot open '" + path + "'");
  const size_t floats = nodeFloatCount(resolution);
  std::error_code ec;
  const uintmax_t size = fs::file_size(path, ec);
  if (ec)
    return fail("cannot read the size of '" + path + "': " + ec.message());
  const uintmax_t expected = sizeof(TableFileHeader) + floats * sizeof(float);
  if (size != expected)
    return fail("'" + path + "' has " + std::to_string(size) +
                " bytes, expected " + std::to_string(expected));
  TableFileHeader header{};
  if (!in.read(reinterpret_cast<char*>(&header), sizeof(header)))
    return fail("cannot read the header of '" + path + "'");
  if (detail::matchCacheFilePreamble(header.preamble, kOperatorTableFile, path,
                                     error) != detail::PreambleMatch::kMatches)
    return false;
  if (header.op != static_cast<uint32_t>(op) ||
      header.resolution != static_cast<uint32_t>(resolution) ||
      header.parameter_hash != bakeParameterHash(op, resolution) ||
      header.float_count != floats)
    return fail("'" + path +
                "' holds another table (operator, resolution or "
                "baking parameters differ)");
  OperatorTable loaded;
  loaded.op = op;
  loaded.resolution = resolution;
  allocateNodes(loaded.nodes, floats);
  if (!in.read(reinterpret_cast<char*>(loaded.nodes.data()),
               static_cast<std::streamsize>(floats * sizeof(float))))
    return fail("cannot read the nodes of '" + path + "'");
  if (!detail::checkCacheFileChecksum(kOperatorTableFile, loaded.nodes.data(),
                                      floats * sizeof(float), header.checksum,
                                      path, error))
    return false;
  *table = std::move(loaded);
  return true;
}

OperatorTable loadOrBakeOperatorTable(
    CompositionOperator op, int resolution, const std::string& folder,
    int threads, const std::function<void(float)>& progress,
    OperatorTableOrigin* origin, std::vector<std::string>* warnings) {
  if (origin) *origin = OperatorTableOrigin::kBaked;
  if (folder.empty() || op == CompositionOperator::kUnion || resolution < 2 ||
      resolution > 512)
    return bakeOperatorTable(op, resolution, threads, progress);
  auto warn = [&](const std::string& warning) {
    if (warnings) warnings->push_back(warning);
  };
  const std::string path =
      (fs::path(folder) / operatorTableCacheFileName(op, resolution)).string();
  std::error_code ec;
  const bool present = fs::exists(fs::symlink_status(path, ec));
  if (present) {
    OperatorTable table;
    std::string why;
    if (loadOperatorTable(path, op, resolution, &table, &why)) {
      if (origin) *origin = OperatorTableOrigin::kLoaded;
      if (progress) progress(1.f);
      return table;
    }
    warn("operator table cache unusable (" + why + "); baking the " +
         compositionOperatorName(op) + " table again");
    if (origin) *origin = OperatorTableOrigin::kRebaked;
  }
  OperatorTable table = bakeOperatorTable(op, resolution, threads, progress);
  std::string why;
  if (!saveOperatorTable(table, path, &why))
    warn("could not write the operator table cache (" + why +
         "); the table will be baked again next time");
  return table;
}

}  // namespace isk
