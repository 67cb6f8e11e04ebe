#include "isk/tools/self_intersection.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <string>

#include "isk/core/error.hpp"

namespace isk {
namespace {

// ---------------------------------------------------------------------------
// Exact orientation predicates on float coordinates.
//
// Each predicate first evaluates its determinant in double with Shewchuk's
// error bound. When the bound cannot decide (in practice: the determinant is
// exactly 0, which structured meshes produce by the million, such as
// generator lines of a cylinder or rings skinned by one transform), it
// evaluates the determinant exactly: from the coordinate differences when
// those were exact in double (nearly always; exact zeros among them then drop
// whole monomials), else from the monomials of the coordinates themselves (a
// product of two floats is exact in double).

constexpr double kEpsilon = 1.1102230246251565e-16;  // 2^-53
constexpr double kOrient2dBound = (3.0 + 16.0 * kEpsilon) * kEpsilon;
constexpr double kOrient3dBound = (7.0 + 56.0 * kEpsilon) * kEpsilon;

int signOf(double x) { return (x > 0.0) - (x < 0.0); }

// Error-free sum: sum + error == a + b exactly (Knuth's Two-Sum).
void twoSum(double a, double b, double& sum, double& error) {
  sum = a + b;
  const double b_virtual = sum - a;
  const double a_virtual = sum - b_virtual;
  error = (a - a_virtual) + (b - b_virtual);
}

// Error-free product: high + low == a * b exactly (no underflow: products of
// float-sized values stay far from it).
void twoProduct(double a, double b, double& high, double& low) {
  high = a * b;
  low = std::fma(a, b, -high);
}

// Whether diff == a - b exactly (Shewchuk's Two-Diff tail is 0).
bool isExactDifference(double a, double b, double diff) {
  const double b_virtual = a - diff;
  const double a_virtual = diff + b_virtual;
  return (a - a_virtual) + (b_virtual - b) == 0.0;
}

// Shewchuk's Fast-Expansion-Sum with zero elimination (Two-Sum throughout):
// e and f are expansions (non-overlapping components of increasing
// magnitude, zeros dropped); h receives their exact sum as one, of at most
// elen + flen components. Returns its length.
int expansionSum(const double* e, int elen, const double* f, int flen,
                 double* h) {
  int ei = 0, fi = 0, length = 0;
  // Merges the components by increasing magnitude.
  auto next = [&] {
    const bool take_e =
        fi == flen || (ei < elen && std::abs(e[ei]) <= std::abs(f[fi]));
    return take_e ? e[ei++] : f[fi++];
  };
  const int total = elen + flen;
  if (total == 0) return 0;
  double q = next();
  for (int k = 1; k < total; ++k) {
    double error;
    twoSum(q, next(), q, error);
    if (error != 0.0) h[length++] = error;
  }
  if (q != 0.0) h[length++] = q;
  return length;
}

// The exact sign of a sum of products of three doubles. Each product is kept
// as up to two exact (low, high) pairs from Two-Product, and the pairs are
// added in a balanced tree of expansion sums (linear cost per level).
class ExactSum {
 public:
  // Adds x * y * z.
  void addProduct(double x, double y, double z) {
    if (x == 0.0 || y == 0.0 || z == 0.0) return;
    double xy_high, xy_low;
    twoProduct(x, y, xy_high, xy_low);
    push(xy_high, z);
    if (xy_low != 0.0) push(xy_low, z);  // never for floats x and y
  }
  int sign() const {
    if (count_ == 0) return 0;
    double sum[2 * kMaxTerms];
    const int length = sumOf(0, count_, sum);
    return length == 0 ? 0 : signOf(sum[length - 1]);
  }

 private:
  static constexpr int kMaxTerms = 48;

  void push(double a, double b) {
    double high, low;
    twoProduct(a, b, high, low);
    terms_[count_++] = {low, high};
  }

  int sumOf(int begin, int end, double* out) const {
    if (end - begin == 1) {
      int length = 0;
      for (double part : terms_[begin]) {
        if (part != 0.0) out[length++] = part;
      }
      return length;
    }
    const int middle = (begin + end) / 2;
    double left[2 * kMaxTerms], right[2 * kMaxTerms];
    const int left_length = sumOf(begin, middle, left);
    const int right_length = sumOf(middle, end, right);
    return expansionSum(left, left_length, right, right_length, out);
  }

  // (low, high): increasing magnitude, non-adjacent (round to even), as
  // Fast-Expansion-Sum requires.
  std::array<std::array<double, 2>, kMaxTerms> terms_;
  int count_ = 0;
};

// A point of a projection onto a coordinate plane.
struct Point2 {
  float u, v;
};

// Sign of det[a - c; b - c]: > 0 when a, b, c turn counter-clockwise.
int orient2d(Point2 a, Point2 b, Point2 c) {
  const double acu = static_cast<double>(a.u) - c.u;
  const double acv = static_cast<double>(a.v) - c.v;
  const double bcu = static_cast<double>(b.u) - c.u;
  const double bcv = static_cast<double>(b.v) - c.v;
  const double left = acu * bcv, right = acv * bcu;
  const double det = left - right;
  const double bound = kOrient2dBound * (std::abs(left) + std::abs(right));
  if (det > bound || -det > bound) return signOf(det);
  // Both products round to 0 only when a factor is exactly 0.
  if (left == 0.0 && right == 0.0) return 0;
  ExactSum sum;
  if (isExactDifference(a.u, c.u, acu) && isExactDifference(a.v, c.v, acv) &&
      isExactDifference(b.u, c.u, bcu) && isExactDifference(b.v, c.v, bcv)) {
    sum.addProduct(acu, bcv, 1.0);
    sum.addProduct(-acv, bcu, 1.0);
  } else {
    // a.u b.v - a.u c.v - a.v b.u + a.v c.u + b.u c.v - b.v c.u.
    sum.addProduct(a.u, b.v, 1.0);
    sum.addProduct(-a.u, c.v, 1.0);
    sum.addProduct(-a.v, b.u, 1.0);
    sum.addProduct(a.v, c.u, 1.0);
    sum.addProduct(b.u, c.v, 1.0);
    sum.addProduct(-b.v, c.u, 1.0);
  }
  return sum.sign();
}

// Adds the six monomials of det[p; q; r] (rows of floats) times `sign`.
void addDet3(ExactSum& sum, double sign, const float* p, const float* q,
             const float* r) {
  sum.addProduct(sign * p[0], q[1], r[2]);
  sum.addProduct(-sign * p[0], q[2], r[1]);
  sum.addProduct(-sign * p[1], q[0], r[2]);
  sum.addProduct(sign * p[1], q[2], r[0]);
  sum.addProduct(sign * p[2], q[0], r[1]);
  sum.addProduct(-sign * p[2], q[1], r[0]);
}

// Sign of det[a - d; b - d; c - d] for points of 3 floats: > 0 when d lies
// below the plane of a, b, c seen with a, b, c counter-clockwise (Shewchuk's
// orient3d).
int orient3d(const float* a, const float* b, const float* c, const float* d) {
  const double adx = static_cast<double>(a[0]) - d[0];
  const double ady = static_cast<double>(a[1]) - d[1];
  const double adz = static_cast<double>(a[2]) - d[2];
  const double bdx = static_cast<double>(b[0]) - d[0];
  const double bdy = static_cast<double>(b[1]) - d[1];
  const double bdz = static_cast<double>(b[2]) - d[2];
  const double cdx = static_cast<double>(c[0]) - d[0];
  const double cdy = static_cast<double>(c[1]) - d[1];
  const double cdz = static_cast<double>(c[2]) - d[2];
  const double bdxcdy = bdx * cdy, cdxbdy = cdx * bdy;
  const double cdxady = cdx * ady, adxcdy = adx * cdy;
  const double adxbdy = adx * bdy, bdxady = bdx * ady;
  const double det = adz * (bdxcdy - cdxbdy) + bdz * (cdxady - adxcdy) +
                     cdz * (adxbdy - bdxady);
  const double permanent =
      (std::abs(bdxcdy) + std::abs(cdxbdy)) * std::abs(adz) +
      (std::abs(cdxady) + std::abs(adxcdy)) * std::abs(bdz) +
      (std::abs(adxbdy) + std::abs(bdxady)) * std::abs(cdz);
  const double bound = kOrient3dBound * permanent;
  if (det > bound || -det > bound) return signOf(det);
  // Every monomial has an exactly-zero difference as a factor (coincident
  // points, axis-aligned planes): the determinant is exactly 0.
  if (permanent == 0.0) return 0;
  ExactSum sum;
  bool exact = true;
  for (int k = 0; k < 3 && exact; ++k) {
    exact = isExactDifference(a[k], d[k], static_cast<double>(a[k]) - d[k]) &&
            isExactDifference(b[k], d[k], static_cast<double>(b[k]) - d[k]) &&
            isExactDifference(c[k], d[k], static_cast<double>(c[k]) - d[k]);
  }
  if (exact) {
    sum.addProduct(adz, bdx, cdy);
    sum.addProduct(-adz, cdx, bdy);
    sum.addProduct(bdz, cdx, ady);
    sum.addProduct(-bdz, adx, cdy);
    sum.addProduct(cdz, adx, bdy);
    sum.addProduct(-cdz, bdx, ady);
  } else {
    // The 4 by 4 determinant with a column of ones, expanded along it.
    addDet3(sum, 1.0, a, b, c);
    addDet3(sum, -1.0, a, b, d);
    addDet3(sum, 1.0, a, c, d);
    addDet3(sum, -1.0, b, c, d);
  }
  return sum.sign();
}

Point2 project(const float* p, int drop_axis) {
  return {p[(drop_axis + 1) % 3], p[(drop_axis + 2) % 3]};
}

// Exactly zero area: the triangle's projections on the three coordinate
// planes all have zero area.
bool isDegenerate(const float* a, const float* b, const float* c) {
  for (int axis = 0; axis < 3; ++axis) {
    if (orient2d(project(a, axis), project(b, axis), project(c, axis)) != 0)
      return false;
  }
  return true;
}

// ---------------------------------------------------------------------------
// Triangle-triangle test. Triangles are closed, non-degenerate, given as three
// pointers to 3 floats.

using Corners = std::array<const float*, 3>;

// Collinear p on the closed segment [a, b].
bool onSegment(Point2 a, Point2 b, Point2 p) {
  return std::min(a.u, b.u) <= p.u && p.u <= std::max(a.u, b.u) &&
         std::min(a.v, b.v) <= p.v && p.v <= std::max(a.v, b.v);
}

// Closed segments [a, b] and [c, d], neither reduced to a point.
bool segmentsMeet(Point2 a, Point2 b, Point2 c, Point2 d) {
  const int d1 = orient2d(c, d, a), d2 = orient2d(c, d, b);
  const int d3 = orient2d(a, b, c), d4 = orient2d(a, b, d);
  if (d1 * d2 < 0 && d3 * d4 < 0) return true;
  return (d1 == 0 && onSegment(c, d, a)) || (d2 == 0 && onSegment(c, d, b)) ||
         (d3 == 0 && onSegment(a, b, c)) || (d4 == 0 && onSegment(a, b, d));
}

// p in the closed triangle t of orientation `turn` (+-1).
bool insideTriangle(const std::array<Point2, 3>& t, int turn, Point2 p) {
  return orient2d(t[0], t[1], p) * turn >= 0 &&
         orient2d(t[1], t[2], p) * turn >= 0 &&
         orient2d(t[2], t[0], p) * turn >= 0;
}

// A coordinate axis along which the non-degenerate triangle t projects to a
// triangle (not a segment): the projection is then one-to-one on t's plane,
// so incidences of points of that plane are decided in 2D. Tries the axes by
// decreasing size of t's normal (approximate, in double); the exact area
// checks pick another axis if rounding erred.
int projectionAxis(const Corners& t) {
  double normal[3];
  {
    double e1[3], e2[3];
    for (int k = 0; k < 3; ++k) {
      e1[k] = static_cast<double>(t[1][k]) - t[0][k];
      e2[k] = static_cast<double>(t[2][k]) - t[0][k];
    }
    normal[0] = std::abs(e1[1] * e2[2] - e1[2] * e2[1]);
    normal[1] = std::abs(e1[2] * e2[0] - e1[0] * e2[2]);
    normal[2] = std::abs(e1[0] * e2[1] - e1[1] * e2[0]);
  }
  std::array<int, 3> axes = {0, 1, 2};
  std::sort(axes.begin(), axes.end(),
            [&](int i, int j) { return normal[i] > normal[j]; });
  for (int axis : axes) {
    if (orient2d(project(t[0], axis), project(t[1], axis),
                 project(t[2], axis)) != 0)
      return axis;
  }
  return axes[0];  // unreachable for non-degenerate triangles
}

// Both triangles in one plane: compare them in a projection onto a coordinate
// plane where that plane does not collapse.
bool coplanarTrianglesMeet(const Corners& a, const Corners& b) {
  const int axis = projectionAxis(b);
  std::array<Point2, 3> pa, pb;
  for (int c = 0; c < 3; ++c) {
    pa[c] = project(a[c], axis);
    pb[c] = project(b[c], axis);
  }
  const int turn_a = orient2d(pa[0], pa[1], pa[2]);
  const int turn_b = orient2d(pb[0], pb[1], pb[2]);
  if (turn_a == 0 || turn_b == 0) return false;  // unreachable (degenerate)
  for (int c = 0; c < 3; ++c) {
    if (insideTriangle(pb, turn_b, pa[c])) return true;
    if (insideTriangle(pa, turn_a, pb[c])) return true;
  }
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (segmentsMeet(pa[i], pa[(i + 1) % 3], pb[j], pb[(j + 1) % 3]))
        return true;
    }
  }
  return false;
}

// Whether edge [p, q] of one triangle meets the closed triangle t, given the
// sides of p and q relative to t's plane (orient3d signs). An edge lying in
// t's plane is skipped: when the triangles are not coplanar, whatever it
// touches is also touched by the other edges (see trianglesMeet).
bool edgeMeetsTriangle(const float* p, const float* q, int side_p, int side_q,
                       const Corners& t) {
  if (side_p == side_q) return false;  // same side, or both in the plane
  // The line pq crosses t's plane once, inside the edge; it passes through
  // the closed triangle iff its orientations with t's edges do not disagree.
  const int s0 = orient3d(p, q, t[0], t[1]);
  const int s1 = orient3d(p, q, t[1], t[2]);
  if (s0 * s1 < 0) return false;
  const int s2 = orient3d(p, q, t[2], t[0]);
  return s0 * s2 >= 0 && s1 * s2 >= 0;
}

// Closed non-degenerate triangles a and b. When they are not coplanar, their
// intersection is a segment of the line where the planes meet, and each
// triangle's part of that line ends on its edges: the triangles meet iff an
// edge of one meets the other. An edge lying on that line is its triangle's
// whole part of the line; its ends are vertices whose other edges leave the
// plane, so those edges find whatever the in-plane edge would.
bool trianglesMeet(const Corners& a, const Corners& b) {
  int side_a[3], side_b[3];
  for (int i = 0; i < 3; ++i) side_a[i] = orient3d(b[0], b[1], b[2], a[i]);
  if (side_a[0] == side_a[1] && side_a[1] == side_a[2]) {
    if (side_a[0] != 0) return false;  // a strictly on one side of b's plane
    return coplanarTrianglesMeet(a, b);
  }
  for (int i = 0; i < 3; ++i) side_b[i] = orient3d(a[0], a[1], a[2], b[i]);
  if (side_b[0] == side_b[1] && side_b[1] == side_b[2] && side_b[0] != 0)
    return false;
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3;
    if (edgeMeetsTriangle(a[i], a[j], side_a[i], side_a[j], b)) return true;
    if (edgeMeetsTriangle(b[i], b[j], side_b[i], side_b[j], a)) return true;
  }
  return false;
}

// Closed segment [p, q] (p != q) and closed non-degenerate triangle t, the
// segment lying in t's plane or not (CGAL's do_intersect(Triangle_3,
// Segment_3)).
bool segmentMeetsTriangle(const float* p, const float* q, const Corners& t) {
  const int side_p = orient3d(t[0], t[1], t[2], p);
  const int side_q = orient3d(t[0], t[1], t[2], q);
  if (side_p != 0 || side_q != 0) {
    return edgeMeetsTriangle(p, q, side_p, side_q, t);
  }
  // In t's plane: an end inside t, or the segment crossing an edge of t.
  const int axis = projectionAxis(t);
  std::array<Point2, 3> pt;
  for (int c = 0; c < 3; ++c) pt[c] = project(t[c], axis);
  const int turn = orient2d(pt[0], pt[1], pt[2]);
  const Point2 pp = project(p, axis), pq = project(q, axis);
  if (insideTriangle(pt, turn, pp) || insideTriangle(pt, turn, pq)) return true;
  for (int i = 0; i < 3; ++i) {
    if (segmentsMeet(pp, pq, pt[i], pt[(i + 1) % 3])) return true;
  }
  return false;
}

// Triangles a and b sharing exactly the corner a[ia] == b[ib] (one welded
// vertex): they intersect iff the edge of either opposite the shared vertex
// meets the other (CGAL's do_faces_intersect, shared vertex).
bool vertexNeighboursMeet(const Corners& a, int ia, const Corners& b, int ib) {
  return segmentMeetsTriangle(b[(ib + 1) % 3], b[(ib + 2) % 3], a) ||
         segmentMeetsTriangle(a[(ia + 1) % 3], a[(ia + 2) % 3], b);
}

// Triangles (u, v, r) and (u, v, s) sharing the edge u v (two welded
// vertices): they intersect iff they are coplanar and r and s lie on the
// same side of u v, folded flat onto each other (CGAL's do_faces_intersect,
// shared edge: coplanar and coplanar_orientation(u, v, r, s) == POSITIVE).
bool edgeNeighboursMeet(const float* u, const float* v, const float* r,
                        const float* s) {
  if (orient3d(u, v, r, s) != 0) return false;
  const int axis = projectionAxis({u, v, r});
  const Point2 pu = project(u, axis), pv = project(v, axis);
  return orient2d(pu, pv, project(r, axis)) *
             orient2d(pu, pv, project(s, axis)) >
         0;
}

// ---------------------------------------------------------------------------
// Bounding-volume hierarchy over the triangles' boxes, traversed against
// itself: every pair of triangles whose boxes overlap is visited once.

struct Box {
  float lo[3], hi[3];
};

// Closed boxes: touching boxes overlap, so touching triangles are found.
bool overlap(const Box& a, const Box& b) {
  return a.lo[0] <= b.hi[0] && b.lo[0] <= a.hi[0] && a.lo[1] <= b.hi[1] &&
         b.lo[1] <= a.hi[1] && a.lo[2] <= b.hi[2] && b.lo[2] <= a.hi[2];
}

void grow(Box& box, const Box& other) {
  for (int k = 0; k < 3; ++k) {
    box.lo[k] = std::min(box.lo[k], other.lo[k]);
    box.hi[k] = std::max(box.hi[k], other.hi[k]);
  }
}

// One non-degenerate triangle, stored in the hierarchy's leaf order.
struct Primitive {
  Box box;
  int triangle;
  std::array<int, 3> groups;  // welded vertex of each corner, all distinct
  Corners corners;            // at the welded vertices' positions
};

// Leaf: count > 0 primitives from `first`; inner: count == 0, children at
// `first` and `first + 1`.
struct Node {
  Box box;
  int first;
  int count;
};

constexpr int kLeafSize = 4;

class SelfIntersectionSearch {
 public:
  explicit SelfIntersectionSearch(std::vector<Primitive> primitives)
      : primitives_(std::move(primitives)) {
    if (primitives_.empty()) return;
    nodes_.reserve(2 * primitives_.size() / kLeafSize + 2);
    nodes_.push_back({});
    build(0, 0, static_cast<int>(primitives_.size()));
  }

  std::vector<std::pair<int, int>> run() {
    if (!nodes_.empty()) selfTraverse(0);
    return std::move(pairs_);
  }

 private:
  // Top-down, median split of the centroids along their longest extent.
  void build(int node, int begin, int end) {
    Box box = primitives_[begin].box;
    Box centroids;
    for (int k = 0; k < 3; ++k) {
      centroids.lo[k] = centroids.hi[k] = centre(primitives_[begin], k);
    }
    for (int i = begin + 1; i < end; ++i) {
      grow(box, primitives_[i].box);
      for (int k = 0; k < 3; ++k) {
        const float c = centre(primitives_[i], k);
        centroids.lo[k] = std::min(centroids.lo[k], c);
        centroids.hi[k] = std::max(centroids.hi[k], c);
      }
    }
    if (end - begin <= kLeafSize) {
      nodes_[node] = {box, begin, end - begin};
      return;
    }
    int axis = 0;
    for (int k = 1; k < 3; ++k) {
      if (centroids.hi[k] - centroids.lo[k] >
          centroids.hi[axis] - centroids.lo[axis])
        axis = k;
    }
    const int middle = begin + (end - begin) / 2;
    std::nth_element(primitives_.begin() + begin, primitives_.begin() + middle,
                     primitives_.begin() + end,
                     [axis](const Primitive& a, const Primitive& b) {
                       return centre(a, axis) < centre(b, axis);
                     });
    const int children = static_cast<int>(nodes_.size());
    nodes_.push_back({});
    nodes_.push_back({});
    nodes_[node] = {box, children, 0};
    build(children, begin, middle);
    build(children + 1, middle, end);
  }

  // Twice the centre (no halving needed to compare).
  static float centre(const Primitive& p, int axis) {
    return p.box.lo[axis] + p.box.hi[axis];
  }

  void selfTraverse(int node) {
    const Node& n = nodes_[node];
    if (n.count > 0) {
      for (int i = n.first; i < n.first + n.count; ++i) {
        for (int j = i + 1; j < n.first + n.count; ++j) test(i, j);
      }
      return;
    }
    selfTraverse(n.first);
    selfTraverse(n.first + 1);
    crossTraverse(n.first, n.first + 1);
  }

  void crossTraverse(int a, int b) {
    const Node& na = nodes_[a];
    const Node& nb = nodes_[b];
    if (!overlap(na.box, nb.box)) return;
    if (na.count > 0 && nb.count > 0) {
      for (int i = na.first; i < na.first + na.count; ++i) {
        for (int j = nb.first; j < nb.first + nb.count; ++j) test(i, j);
      }
      return;
    }
    // Descend the larger box (or the only inner node).
    if (nb.count > 0 ||
        (na.count == 0 && halfPerimeter(na.box) >= halfPerimeter(nb.box))) {
      crossTraverse(na.first, b);
      crossTraverse(na.first + 1, b);
    } else {
      crossTraverse(a, nb.first);
      crossTraverse(a, nb.first + 1);
    }
  }

  static float halfPerimeter(const Box& box) {
    return (box.hi[0] - box.lo[0]) + (box.hi[1] - box.lo[1]) +
           (box.hi[2] - box.lo[2]);
  }

  void test(int i, int j) {
    const Primitive& a = primitives_[i];
    const Primitive& b = primitives_[j];
    if (!overlap(a.box, b.box)) return;
    // The corners of a and b at a shared welded vertex (a triangle's groups
    // are distinct: it would be degenerate otherwise).
    int shared = 0, shared_a[3], shared_b[3];
    for (int ca = 0; ca < 3; ++ca) {
      for (int cb = 0; cb < 3; ++cb) {
        if (a.groups[ca] == b.groups[cb]) {
          shared_a[shared] = ca;
          shared_b[shared] = cb;
          ++shared;
        }
      }
    }
    bool meet = false;
    switch (shared) {
      case 0:
        meet = trianglesMeet(a.corners, b.corners);
        break;
      case 1:
        meet = vertexNeighboursMeet(a.corners, shared_a[0], b.corners,
                                    shared_b[0]);
        break;
      case 2: {
        // The corner of each triangle off the shared edge.
        const int ra = 3 - shared_a[0] - shared_a[1];
        const int rb = 3 - shared_b[0] - shared_b[1];
        meet =
            edgeNeighboursMeet(a.corners[shared_a[0]], a.corners[shared_a[1]],
                               a.corners[ra], b.corners[rb]);
        break;
      }
      default:  // the same face twice
        meet = true;
    }
    if (!meet) return;
    pairs_.emplace_back(std::min(a.triangle, b.triangle),
                        std::max(a.triangle, b.triangle));
  }

  std::vector<Primitive> primitives_;
  std::vector<Node> nodes_;
  std::vector<std::pair<int, int>> pairs_;
};

}  // namespace

int countSelfIntersections(const Matrix3Xf& positions,
                           const TriangleMatrix& triangles,
                           const std::vector<int>* vertex_groups,
                           std::vector<std::pair<int, int>>* pairs,
                           int* degenerate_triangles) {
  const Eigen::Index vertex_count = positions.rows();
  if (vertex_groups &&
      static_cast<Eigen::Index>(vertex_groups->size()) != vertex_count) {
    throw Error(ErrorCode::kInvalidArgument,
                "countSelfIntersections: vertex_groups has " +
                    std::to_string(vertex_groups->size()) + " entries for " +
                    std::to_string(vertex_count) + " vertices");
  }
  for (Eigen::Index v = 0; v < vertex_count; ++v) {
    if (!positions.row(v).allFinite()) {
      throw Error(ErrorCode::kInvalidArgument,
                  "countSelfIntersections: vertex " + std::to_string(v) +
                      " has a non-finite position (" +
                      std::to_string(positions(v, 0)) + ", " +
                      std::to_string(positions(v, 1)) + ", " +
                      std::to_string(positions(v, 2)) + ")");
    }
    if (vertex_groups) {
      const int group = (*vertex_groups)[v];
      if (group < 0 || group >= vertex_count) {
        throw Error(ErrorCode::kInvalidArgument,
                    "countSelfIntersections: vertex_groups gives vertex " +
                        std::to_string(v) + " the group " +
                        std::to_string(group) + ", not a vertex of " +
                        std::to_string(vertex_count));
      }
    }
  }
  // Row-major #V by 3: vertex v's coordinates are 3 consecutive floats.
  const float* xyz = positions.data();
  std::vector<Primitive> primitives;
  primitives.reserve(static_cast<size_t>(triangles.rows()));
  int degenerate = 0;
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    Primitive p;
    for (int c = 0; c < 3; ++c) {
      const int32_t index = triangles(f, c);
      if (index < 0 || index >= vertex_count) {
        throw Error(ErrorCode::kInvalidArgument,
                    "countSelfIntersections: triangle " + std::to_string(f) +
                        " refers to vertex " + std::to_string(index) + " of " +
                        std::to_string(vertex_count));
      }
      // The welded vertex: the group's representative, at its position.
      p.groups[c] = vertex_groups ? (*vertex_groups)[index] : index;
      p.corners[c] = xyz + 3 * static_cast<Eigen::Index>(p.groups[c]);
    }
    // Collinear corners (two welded into one included): CGAL reports the
    // face alone, as (f, f), and tests it against no other.
    if (isDegenerate(p.corners[0], p.corners[1], p.corners[2])) {
      ++degenerate;
      continue;
    }
    p.triangle = static_cast<int>(f);
    for (int k = 0; k < 3; ++k) {
      p.box.lo[k] =
          std::min({p.corners[0][k], p.corners[1][k], p.corners[2][k]});
      p.box.hi[k] =
          std::max({p.corners[0][k], p.corners[1][k], p.corners[2][k]});
    }
    primitives.push_back(p);
  }
  std::vector<std::pair<int, int>> found =
      SelfIntersectionSearch(std::move(primitives)).run();
  const int count = static_cast<int>(found.size());
  if (pairs) {
    std::sort(found.begin(), found.end());
    *pairs = std::move(found);
  }
  if (degenerate_triangles) *degenerate_triangles = degenerate;
  return count;
}

std::vector<std::pair<int, int>> newSelfIntersections(
    const std::vector<std::pair<int, int>>& frame_pairs,
    const std::vector<std::pair<int, int>>& rest_pairs) {
  std::vector<std::pair<int, int>> frame = frame_pairs, rest = rest_pairs;
  std::sort(frame.begin(), frame.end());
  frame.erase(std::unique(frame.begin(), frame.end()), frame.end());
  std::sort(rest.begin(), rest.end());
  std::vector<std::pair<int, int>> fresh;
  std::set_difference(frame.begin(), frame.end(), rest.begin(), rest.end(),
                      std::back_inserter(fresh));
  return fresh;
}

std::vector<int> coincidentVertexGroups(const Matrix3Xf& positions) {
  const int vertex_count = static_cast<int>(positions.rows());
  // Sort by the position's bits, then by index: each run of equal bits
  // starts with its smallest index.
  struct Key {
    std::array<uint32_t, 3> bits;
    int vertex;
  };
  std::vector<Key> keys(vertex_count);
  for (int v = 0; v < vertex_count; ++v) {
    for (int k = 0; k < 3; ++k) {
      const float x = positions(v, k);
      std::memcpy(&keys[v].bits[k], &x, sizeof(float));
    }
    keys[v].vertex = v;
  }
  std::sort(keys.begin(), keys.end(), [](const Key& a, const Key& b) {
    return a.bits != b.bits ? a.bits < b.bits : a.vertex < b.vertex;
  });
  std::vector<int> groups(vertex_count);
  for (int i = 0; i < vertex_count; ++i) {
    const bool starts_run = i == 0 || keys[i].bits != keys[i - 1].bits;
    groups[keys[i].vertex] =
        starts_run ? keys[i].vertex : groups[keys[i - 1].vertex];
  }
  return groups;
}

}  // namespace isk
