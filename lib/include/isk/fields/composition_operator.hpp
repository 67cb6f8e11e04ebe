// Binary composition operators of implicit skinning (Vaillant et al. 2013,
// section 4.2, Figures 5-7 and Appendix A; Gourmel et al. 2013): union,
// gradient-based blend and bulge-in-contact, their theta(alpha) controllers,
// and their baked 3D lookup tables.
//
// Conventions (DESIGN.md section 2): field values in [0, 1], the surface at
// 0.5, inside > 0.5. Every operator g(f1, f2, theta) is symmetric in (f1, f2),
// stays in [0, 1], is at least max(f1, f2) and equals it outside its
// blending region. theta lies in [0, kThetaUnion]; theta = kThetaUnion is the
// union for every operator.
//
// Gradient-based blend (Appendix A). With t = tan(theta) and the opening
//   k(C) = t C                                for C <= 0.5,
//   k(C) = (7 - 5 t) C / 2 + 7 (t - 1) / 4    for 0.5 < C < 0.7,
//   k(C) = C                                  for C >= 0.7,
// g = max(f1, f2) when f1 or f2 > 0.7, or when min(f1, f2) < k(max(f1, f2));
// otherwise g is the C solving eq. 8,
//   sqrt((f1 - k(C))^2 + (f2 - k(C))^2) = C - k(C),
// found by bisection in C (its iso-curves are quarter circles centred on the
// diagonal that meet the union's lines f = C tangentially at the opening).
// The paper picks the branch of k by the point's values (f1, f2 <= 0.5); we
// pick it by C: both branches meet at C = 0.5 (k = 0.5 t), so g is
// continuous across the 0.5 band, whereas choosing by the point jumps there
// (by up to 0.09 at theta = 0). theta = 0 is the strongest blend
// (k = 0: a circle around the origin below 0.5).
//
// Bulge-in-contact (ours, after Gourmel et al.'s contact bulge: the paper
// gives no formula). With M = max(f1, f2), m = min(f1, f2):
//   g = M + A s(theta) Q(M) S(m),   s = 1 - theta / kThetaUnion,
//   Q(M) = (1 - q^2)^2, q = (M - 0.5) / 0.2 (0 when |q| >= 1),
//   S(m) = smoothstep of (m - 0.1) / 0.4,   A = kBulgeAmplitude.
// The surface of one part swells outward (by up to A in field units) where
// the other part's field is high, i.e. around their contact; g keeps the
// crease of the max on f1 = f2 (the contact surface where vertices stop) and
// equals max where M <= 0.3, M >= 0.7 or m <= 0.1. A = 0.1 keeps g strictly
// increasing in both fields. The bulge strength of a joint scales s through
// its controller (bulgeController).
//
// Tables: G(x, y, theta) for x >= y (the operator with its larger argument
// first), sampled at N^3 nodes over x, y in [0, 1] and theta in
// [0, kThetaUnion], storing G, dG/dx and dG/dy. Nodes with y > x hold the
// smooth continuation of that branch (x where the operator is a union near
// the diagonal), so a cell that straddles the diagonal interpolates one
// smooth function and the max's crease stays exact: at run time
// x = max(f1, f2), y = min(f1, f2), and the partials go back to f1 and f2 by
// that order. A union region, G = x, is reproduced exactly by trilinear
// interpolation.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace isk {

// How two bones' fields combine at their joint: max (union), the
// gradient-based blend (a fillet in the fold) or the bulge-in-contact.
enum class CompositionOperator { kUnion, kBlend, kBulge };

// "union", "blend", "bulge".
const char* compositionOperatorName(CompositionOperator op);
// Parses one of the names above; false for anything else.
bool parseCompositionOperator(const std::string& name, CompositionOperator* op);

// theta at which every operator is the union, radians.
constexpr double kThetaUnion = 0.78539816339744830962;  // pi / 4
// A of the bulge: its largest swelling, in field units.
constexpr double kBulgeAmplitude = 0.1;

// An operator's value and its partial derivatives.
struct OperatorValue {
  double g = 0, dg_df1 = 0, dg_df2 = 0;
};

// The operators evaluated directly (the blend solved by bisection to 1e-12);
// f1, f2 clamped to [0, 1], theta to [0, kThetaUnion]. The derivatives are
// analytic (implicit function theorem on eq. 8 for the blend).
OperatorValue unionOperator(double f1, double f2);
OperatorValue blendOperator(double f1, double f2, double theta);
OperatorValue bulgeOperator(double f1, double f2, double theta);
OperatorValue evaluateOperator(CompositionOperator op, double f1, double f2,
                               double theta);
// Whether (f1, f2, theta) lies where the operator may differ from max
// (always false for the union).
bool inBlendingRegion(CompositionOperator op, double f1, double f2,
                      double theta);

// theta as a function of the angle alpha between the two fields' gradients,
// sampled uniformly over alpha in [0, pi] (Figure 7). Sampled into a 1D
// table on the device, linearly interpolated.
struct ThetaController {
  std::vector<float> theta;  // at alpha = pi * i / (size - 1), size >= 2

  // Linear interpolation at alpha (clamped to [0, pi]).
  float at(float alpha) const;
};

// Samples of the controllers below over alpha in [0, pi].
constexpr int kControllerSamples = 65;  // pi/4 and pi/2 fall on samples

// theta = kThetaUnion everywhere.
ThetaController unionController();
// Figure 7(a), elbows and knees: union at alpha = 0, theta_blend at pi/4,
// union again from pi/2 on; theta = theta_u - (theta_u - theta_blend)
// sin^2(2 alpha) in between (smooth at both ends). theta_blend in
// [0, kThetaUnion]; 0 is the strongest blend.
ThetaController blendController(double theta_blend = 0);
// Figure 7(b), fingers: union at alpha = 0, bulge growing to its maximum at
// pi/2 and staying there; theta = theta_u - strength theta_u sin^2(alpha)
// up to pi/2. strength in [0, 1] scales the bulge (0: a union).
ThetaController bulgeController(double strength = 1);
// The default controller of an operator (the two above with their
// defaults; unionController for the union).
ThetaController defaultController(CompositionOperator op);

// An operator baked over (x, y, theta) (see the header comment).
struct OperatorTable {
  CompositionOperator op = CompositionOperator::kBlend;
  int resolution = 128;  // nodes per axis
  // resolution^3 float4 (G, dG/dx, dG/dy, 0); node (i, j, k) at
  // x = i / (N - 1), y = j / (N - 1), theta = kThetaUnion * k / (N - 1),
  // index i + N * (j + N * k).
  std::vector<float> nodes;

  // Size of `nodes` in bytes (4 * resolution^3 floats).
  size_t bytes() const { return nodes.size() * sizeof(float); }
  // g, dg/df1 and dg/df2 at (f1, f2, theta) from the table: the order of
  // (f1, f2) picks the branch (f1 >= f2: x = f1), then trilinear
  // interpolation in float. The kernels' buffer path does exactly this.
  void sample(float f1, float f2, float theta, float out[3]) const;
};

// Bakes `op` (kBlend or kBulge) at resolution^3 nodes (2..512) on `threads`
// threads (0: all hardware threads); progress(fraction) from the calling
// thread. Throws isk::Error(kInvalidArgument) for the union (nothing to bake)
// or a bad resolution.
OperatorTable bakeOperatorTable(
    CompositionOperator op, int resolution = 128, int threads = 0,
    const std::function<void(float)>& progress = nullptr);

// The table of (op, resolution), made once per process and shared: loaded
// from the on-disk cache below when a valid file is there, else baked and
// written to it (loading a table costs far less than baking it). What the
// cache could not do (a bad file re-baked, a file that could not be
// written) is appended to *warnings, by the call that made the table.
std::shared_ptr<const OperatorTable> sharedOperatorTable(
    CompositionOperator op, int resolution = 128,
    const std::function<void(float)>& progress = nullptr,
    std::vector<std::string>* warnings = nullptr);

// On-disk cache of baked operator tables.
//
// Folder: $ISK_CACHE_DIR when set and not empty ("off" disables the cache),
// else $XDG_CACHE_HOME/isk, else $HOME/.cache/isk; created when first
// written. One file per table, named by its key: format version, operator,
// resolution and a hash of everything the bake depends on (the operator
// constants and a bake version bumped whenever the operator math changes),
// e.g. "operator-table-v1-blend-128-0123456789abcdef.bin". A file holds a
// 48-byte header (magic, format version, byte order, operator, resolution,
// parameter hash, float count, checksum of the floats) and the nodes.
// Files are written to a temporary file in the same folder and renamed, so
// a reader never sees a partial file; nothing but the table's own file is
// ever replaced. A file that cannot be read or fails validation (size,
// header, key, checksum) is reported as a warning and the table is re-baked
// and rewritten: the cache never makes a table fail.

// The cache folder as described above; empty when the cache is disabled or
// no folder can be named (no HOME).
std::string operatorTableCacheFolder();
// The file name (no folder) of (op, resolution): the key.
std::string operatorTableCacheFileName(CompositionOperator op, int resolution);
// Writes `table` to `path` atomically (temporary file + rename); creates the
// parent folder. Returns false and sets *error when anything fails (the
// temporary file is then removed); never throws for I/O.
bool saveOperatorTable(const OperatorTable& table, const std::string& path,
                       std::string* error = nullptr);
// Reads the table of (op, resolution) from `path` and validates it. Returns
// false and sets *error (missing file, short file, wrong header, key or
// checksum); never throws for I/O.
bool loadOperatorTable(const std::string& path, CompositionOperator op,
                       int resolution, OperatorTable* table,
                       std::string* error = nullptr);

// Where loadOrBakeOperatorTable got its table.
enum class OperatorTableOrigin {
  kBaked,    // no cache folder, or no file yet (written now when possible)
  kLoaded,   // a valid cache file
  kRebaked,  // the cache file was bad: re-baked, reported, rewritten
};

// The table of (op, resolution) from the cache folder `folder` (empty: no
// cache, nothing is read or written), else baked on `threads` threads and
// written there. A bad cache file ("operator table cache unusable (<why>);
// baking the blend table again") or a failed write ("could not write the
// operator table cache (<why>); ...") is appended to *warnings; the library
// prints nothing. Throws like bakeOperatorTable for a bad operator or
// resolution, never for the cache.
OperatorTable loadOrBakeOperatorTable(
    CompositionOperator op, int resolution, const std::string& folder,
    int threads = 0, const std::function<void(float)>& progress = nullptr,
    OperatorTableOrigin* origin = nullptr,
    std::vector<std::string>* warnings = nullptr);

}  // namespace isk
