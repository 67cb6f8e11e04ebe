#include "isk/tools/procedural.hpp"

#include <cmath>
#include <functional>
#include <string>

#include "isk/core/error.hpp"

namespace isk {
namespace {

constexpr float kPi = 3.14159265358979f;

float smoothstep(float edge0, float edge1, float x) {
  const float t = std::clamp((x - edge0) / (edge1 - edge0), 0.f, 1.f);
  return t * t * (3.f - 2.f * t);
}

// A closed tube along +x with joints at `joint_x` (the last one is the tip,
// carrying no weight), elliptical sections of half-axes radii(x) = (y, z),
// flat caps made of concentric rings.
struct TubeSpec {
  std::string name;
  std::vector<float> joint_x;
  std::vector<std::string> joint_names;
  std::function<Eigen::Vector2f(float)> radii;
  int rings = 64;
  int segments = 48;
  float blend_width = 0.25f;  // in lengths of the shorter adjacent bone
  // A sleeve: a closed shell around the tube from x = 0 to sleeve_end (0:
  // none), between sleeve_inner and sleeve_outer times the tube's radii,
  // another mesh part ("sleeve") weighted as the skin under it, as clothes
  // are.
  float sleeve_end = 0.f;
  float sleeve_inner = 1.05f, sleeve_outer = 1.12f;
};

// Appends a closed shell around the tube to positions and triangles: two
// open tubes (outer wound outward, inner inward) joined by annular rims.
void appendSleeve(const TubeSpec& spec, int rings,
                  std::vector<Eigen::Vector3f>& positions,
                  std::vector<Eigen::Vector3i>& triangles) {
  const int segments = spec.segments;
  const int first = static_cast<int>(positions.size());
  for (int layer = 0; layer < 2; ++layer) {
    const float scale = layer == 0 ? spec.sleeve_outer : spec.sleeve_inner;
    for (int i = 0; i < rings; ++i) {
      const float x = spec.sleeve_end * i / (rings - 1);
      const Eigen::Vector2f r = spec.radii(x) * scale;
      for (int s = 0; s < segments; ++s) {
        const float a = 2.f * kPi * s / segments;
        positions.emplace_back(x, r.x() * std::cos(a), r.y() * std::sin(a));
      }
    }
  }
  auto at = [&](int layer, int i, int s) {
    return first + (layer * rings + i) * segments + (s % segments);
  };
  for (int i = 0; i + 1 < rings; ++i) {
    for (int s = 0; s < segments; ++s) {
      // Outer layer as the tube's side (outward); inner layer reversed.
      triangles.emplace_back(at(0, i, s), at(0, i + 1, s + 1), at(0, i + 1, s));
      triangles.emplace_back(at(0, i, s), at(0, i, s + 1), at(0, i + 1, s + 1));
      triangles.emplace_back(at(1, i, s), at(1, i + 1, s), at(1, i + 1, s + 1));
      triangles.emplace_back(at(1, i, s), at(1, i + 1, s + 1), at(1, i, s + 1));
    }
  }
  for (int end = 0; end < 2; ++end) {  // rims, facing -x then +x
    const int i = end == 0 ? 0 : rings - 1;
    for (int s = 0; s < segments; ++s) {
      if (end == 0) {
        triangles.emplace_back(at(0, i, s), at(1, i, s), at(1, i, s + 1));
        triangles.emplace_back(at(0, i, s), at(1, i, s + 1), at(0, i, s + 1));
      } else {
        triangles.emplace_back(at(0, i, s), at(1, i, s + 1), at(1, i, s));
        triangles.emplace_back(at(0, i, s), at(0, i, s + 1), at(1, i, s + 1));
      }
    }
  }
}

Rig makeTubeRig(const TubeSpec& spec) {
  const int bones = static_cast<int>(spec.joint_x.size()) - 1;
  const float length = spec.joint_x.back();
  const int rings = std::max(spec.rings, 2);
  const int segments = std::max(spec.segments, 3);
  const int cap_rings = std::max(2, segments / 8);
  Rig rig;
  rig.source = "builtin:" + spec.name;

  std::vector<Eigen::Vector3f> positions, normals;
  std::vector<Eigen::Vector3i> triangles;
  auto ring_point = [&](float x, int s, float scale) {
    const Eigen::Vector2f r = spec.radii(x) * scale;
    const float a = 2.f * kPi * s / segments;
    return Eigen::Vector3f(x, r.x() * std::cos(a), r.y() * std::sin(a));
  };
  // Side rings; normals from the elliptical section (ignoring the taper's
  // small axial component, recomputed below from the triangles anyway).
  for (int i = 0; i < rings; ++i) {
    const float x = length * i / (rings - 1);
    for (int s = 0; s < segments; ++s)
      positions.push_back(ring_point(x, s, 1.f));
  }
  auto side = [&](int i, int s) { return i * segments + (s % segments); };
  for (int i = 0; i + 1 < rings; ++i) {
    for (int s = 0; s < segments; ++s) {
      triangles.emplace_back(side(i, s), side(i + 1, s + 1), side(i + 1, s));
      triangles.emplace_back(side(i, s), side(i, s + 1), side(i + 1, s + 1));
    }
  }
  // Caps: concentric rings shrinking to a centre vertex. The outer ring is
  // the side's end ring, so the surface stays closed and manifold.
  for (int end = 0; end < 2; ++end) {
    const float x = end == 0 ? 0.f : length;
    const int outer_ring = end == 0 ? 0 : rings - 1;
    std::vector<int> previous(segments);
    for (int s = 0; s < segments; ++s) previous[s] = side(outer_ring, s);
    for (int c = 1; c < cap_rings; ++c) {
      const float scale = 1.f - static_cast<float>(c) / cap_rings;
      std::vector<int> current(segments);
      for (int s = 0; s < segments; ++s) {
        current[s] = static_cast<int>(positions.size());
        positions.push_back(ring_point(x, s, scale));
      }
      for (int s = 0; s < segments; ++s) {
        const int s1 = (s + 1) % segments;
        if (end == 1) {
          triangles.emplace_back(previous[s], previous[s1], current[s1]);
          triangles.emplace_back(previous[s], current[s1], current[s]);
        } else {
          triangles.emplace_back(previous[s], current[s1], previous[s1]);
          triangles.emplace_back(previous[s], current[s], current[s1]);
        }
      }
      previous = current;
    }
    const int centre = static_cast<int>(positions.size());
    positions.emplace_back(x, 0.f, 0.f);
    for (int s = 0; s < segments; ++s) {
      const int s1 = (s + 1) % segments;
      if (end == 1) {
        triangles.emplace_back(previous[s], previous[s1], centre);
      } else {
        triangles.emplace_back(previous[s], centre, previous[s1]);
      }
    }
  }

  const int skin_vertices = static_cast<int>(positions.size());
  const int skin_triangles = static_cast<int>(triangles.size());
  if (spec.sleeve_end > 0.f) {
    const int sleeve_rings =
        std::max(2, static_cast<int>(rings * spec.sleeve_end / length));
    appendSleeve(spec, sleeve_rings, positions, triangles);
  }

  Mesh& mesh = rig.mesh;
  const int n = static_cast<int>(positions.size());
  mesh.positions.resize(n, 3);
  for (int v = 0; v < n; ++v) mesh.positions.row(v) = positions[v];
  mesh.triangles.resize(static_cast<int>(triangles.size()), 3);
  for (size_t f = 0; f < triangles.size(); ++f)
    mesh.triangles.row(f) = triangles[f];
  // Area-weighted normals of the closed surface (outward: caps and sides are
  // wound counter-clockwise seen from outside).
  mesh.normals = Matrix3Xf::Zero(n, 3);
  for (const auto& t : triangles) {
    const Eigen::Vector3f a = positions[t[0]], b = positions[t[1]],
                          c = positions[t[2]];
    const Eigen::Vector3f face = (b - a).cross(c - a);
    for (int k = 0; k < 3; ++k) mesh.normals.row(t[k]) += face.transpose();
  }
  for (int v = 0; v < n; ++v) mesh.normals.row(v).normalize();
  mesh.parts.push_back({spec.name, 0, skin_vertices, 0, skin_triangles});
  if (n > skin_vertices) {
    mesh.parts.push_back({"sleeve", skin_vertices, n - skin_vertices,
                          skin_triangles,
                          static_cast<int>(triangles.size()) - skin_triangles});
  }

  // Skeleton: a chain along +x, identity rotations.
  for (int j = 0; j <= bones; ++j) {
    Joint joint;
    joint.name = spec.joint_names[j];
    joint.parent = j - 1;
    const float offset =
        j == 0 ? spec.joint_x[0] : spec.joint_x[j] - spec.joint_x[j - 1];
    joint.rest_local = Eigen::Translation3f(offset, 0.f, 0.f);
    joint.inverse_bind = Eigen::Translation3f(-spec.joint_x[j], 0.f, 0.f);
    joint.is_skin_joint = j < bones;
    rig.skeleton.joints.push_back(joint);
  }

  // Weights: each bone owns its span; around an inner joint the child's
  // weight rises smoothly over +-half_width.
  std::vector<std::vector<std::pair<int, float>>> lists(n);
  for (int v = 0; v < n; ++v) {
    const float x = positions[v].x();
    int bone = 0;
    while (bone + 1 < bones && x >= spec.joint_x[bone + 1]) ++bone;
    std::vector<float> w(bones, 0.f);
    w[bone] = 1.f;
    for (int k = 1; k < bones; ++k) {
      const float shorter = std::min(spec.joint_x[k] - spec.joint_x[k - 1],
                                     spec.joint_x[k + 1] - spec.joint_x[k]);
      const float h = spec.blend_width * shorter;
      if (std::abs(x - spec.joint_x[k]) < h) {
        const float child =
            smoothstep(spec.joint_x[k] - h, spec.joint_x[k] + h, x);
        std::fill(w.begin(), w.end(), 0.f);
        w[k - 1] = 1.f - child;
        w[k] = child;
      }
    }
    for (int b = 0; b < bones; ++b) {
      if (w[b] > 0.f) lists[v].emplace_back(b, w[b]);
    }
  }
  rig.weights = SkinWeights::fromLists(lists);
  rig.weights.normalize();
  rig.weights.sortByWeight();
  rig.clips.push_back(makeBendClip(rig.skeleton, kPi / 2.f, 1.0));
  rig.validate().throwIfFailed(rig.source);
  return rig;
}

}  // namespace

Rig makeCylinderRig(const CylinderRigOptions& options) {
  if (options.bones < 1 || options.bones > 64 || !(options.radius > 0.f) ||
      !(options.length > 0.f) || options.rings < 2 || options.segments < 3 ||
      !(options.taper >= 0.f && options.taper < 1.f) ||
      !(options.blend_width > 0.f && options.blend_width <= 0.5f)) {
    throw Error(
        ErrorCode::kInvalidArgument,
        "makeCylinderRig: need 1-64 bones, positive radius and length, "
        "rings >= 2, segments >= 3, taper in [0, 1), blend width in (0, 0.5]");
  }
  TubeSpec spec;
  spec.name = "cylinder";
  for (int j = 0; j <= options.bones; ++j) {
    spec.joint_x.push_back(options.length * j / options.bones);
    spec.joint_names.push_back(j < options.bones ? "bone" + std::to_string(j)
                                                 : "tip");
  }
  const float radius = options.radius, taper = options.taper,
              length = options.length;
  spec.radii = [=](float x) {
    const float r = radius * (1.f - taper * x / length);
    return Eigen::Vector2f(r, r);
  };
  spec.rings = options.rings;
  spec.segments = options.segments;
  spec.blend_width = options.blend_width;
  return makeTubeRig(spec);
}

namespace {

// Half-axes (y, z) at control points xs along the tube, blended smoothly
// (smoothstep) between them; kept as they are beyond the last.
std::function<Eigen::Vector2f(float)> controlPointRadii(std::vector<float> xs,
                                                        std::vector<float> ry,
                                                        std::vector<float> rz) {
  return [xs = std::move(xs), ry = std::move(ry), rz = std::move(rz)](float x) {
    const size_t last = xs.size() - 1;
    size_t i = 0;
    while (i + 1 < last && x > xs[i + 1]) ++i;
    const float a = smoothstep(xs[i], xs[i + 1], x);
    return Eigen::Vector2f((1 - a) * ry[i] + a * ry[i + 1],
                           (1 - a) * rz[i] + a * rz[i + 1]);
  };
}

TubeSpec armSpec(int rings_per_unit, int segments) {
  TubeSpec spec;
  spec.name = "arm";
  spec.joint_x = {0.f, 3.f, 5.6f, 7.4f};
  spec.joint_names = {"shoulder", "elbow", "wrist", "hand_tip"};
  // A round upper arm and forearm, a narrow wrist and a flat hand.
  spec.radii =
      controlPointRadii({0.f, 1.5f, 3.f, 4.0f, 5.6f, 6.4f, 7.4f},
                        {0.60f, 0.52f, 0.42f, 0.45f, 0.28f, 0.42f, 0.30f},
                        {0.60f, 0.52f, 0.42f, 0.42f, 0.22f, 0.14f, 0.10f});
  spec.rings = static_cast<int>(7.4f * rings_per_unit) + 1;
  spec.segments = segments;
  spec.blend_width = 0.2f;
  return spec;
}

}  // namespace

Rig makeArmRig(int rings_per_unit, int segments) {
  if (rings_per_unit < 1 || segments < 3) {
    throw Error(ErrorCode::kInvalidArgument,
                "makeArmRig: need rings_per_unit >= 1 and segments >= 3");
  }
  return makeTubeRig(armSpec(rings_per_unit, segments));
}

Rig makeSleevedArmRig(int rings_per_unit, int segments) {
  if (rings_per_unit < 1 || segments < 3) {
    throw Error(
        ErrorCode::kInvalidArgument,
        "makeSleevedArmRig: need rings_per_unit >= 1 and segments >= 3");
  }
  TubeSpec spec = armSpec(rings_per_unit, segments);
  spec.name = "sleeved-arm";
  spec.sleeve_end = 4.6f;  // past the elbow, to the middle of the forearm
  return makeTubeRig(spec);
}

Rig makeLegRig(int rings_per_unit, int segments) {
  if (rings_per_unit < 1 || segments < 3) {
    throw Error(ErrorCode::kInvalidArgument,
                "makeLegRig: need rings_per_unit >= 1 and segments >= 3");
  }
  TubeSpec spec;
  spec.name = "leg";
  spec.joint_x = {0.f, 4.5f, 8.5f, 10.3f};
  spec.joint_names = {"hip", "knee", "ankle", "toe_tip"};
  // A thick thigh narrowing to the knee, a calf, a narrow ankle and a flat
  // foot (flattened as the arm's hand).
  spec.radii =
      controlPointRadii({0.f, 2.0f, 4.5f, 5.8f, 8.5f, 9.3f, 10.3f},
                        {0.95f, 0.80f, 0.55f, 0.62f, 0.33f, 0.45f, 0.35f},
                        {0.95f, 0.80f, 0.55f, 0.60f, 0.30f, 0.22f, 0.14f});
  spec.rings = static_cast<int>(10.3f * rings_per_unit) + 1;
  spec.segments = segments;
  spec.blend_width = 0.2f;
  return makeTubeRig(spec);
}

std::vector<std::string> builtinRigNames() {
  return {"cylinder", "finger", "arm", "sleeved-arm", "leg"};
}

Rig makeBuiltinRig(const std::string& name) {
  if (name == "cylinder") return makeCylinderRig();
  if (name == "finger") {
    TubeSpec spec;
    spec.name = "finger";
    spec.joint_x = {0.f, 3.5f, 6.f, 8.f};
    spec.joint_names = {"proximal", "middle", "distal", "tip"};
    spec.radii = [](float x) {
      const float r = 0.9f - 0.3f * x / 8.f;
      return Eigen::Vector2f(r, r);
    };
    spec.rings = 80;
    spec.segments = 40;
    spec.blend_width = 0.2f;
    return makeTubeRig(spec);
  }
  if (name == "arm") return makeArmRig();
  if (name == "sleeved-arm") return makeSleevedArmRig();
  if (name == "leg") return makeLegRig();
  std::string names;
  for (const std::string& n : builtinRigNames())
    names += (names.empty() ? "" : ", ") + n;
  throw Error(
      ErrorCode::kInvalidArgument,
      "unknown builtin rig '" + name + "' (builtin rigs: " + names + ")");
}

}  // namespace isk
