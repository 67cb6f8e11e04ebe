#include "frame_pictures.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "isk/core/error.hpp"

namespace isk::samples {

namespace {

[[noreturn]] void badLine(const std::string& path, int line,
                          const std::string& why) {
  throw Error(ErrorCode::kIo, path + ":" + std::to_string(line) + ": " + why);
}

// The vertex index of an OBJ face corner ("7", "7/2", "7//3", "-1").
int cornerIndex(const std::string& token, int vertex_count,
                const std::string& path, int line) {
  const std::string index_text = token.substr(0, token.find('/'));
  char* end = nullptr;
  const long index = std::strtol(index_text.c_str(), &end, 10);
  if (index_text.empty() || *end != '\0' || index == 0) {
    badLine(path, line, "bad face corner '" + token + "'");
  }
  const long zero_based = index > 0 ? index - 1 : vertex_count + index;
  if (zero_based < 0 || zero_based >= vertex_count) {
    badLine(path, line,
            "face corner '" + token + "' refers to a vertex out of 1.." +
                std::to_string(vertex_count));
  }
  return static_cast<int>(zero_based);
}

Eigen::Vector3f centroid(const ObjMesh& mesh, int f) {
  Eigen::Vector3f c = Eigen::Vector3f::Zero();
  for (int k = 0; k < 3; ++k)
    c += mesh.positions.row(mesh.triangles(f, k)).transpose();
  return c / 3.f;
}

Eigen::Vector3f areaNormal(const ObjMesh& mesh, int f) {
  const Eigen::Vector3f a = mesh.positions.row(mesh.triangles(f, 0));
  const Eigen::Vector3f b = mesh.positions.row(mesh.triangles(f, 1));
  const Eigen::Vector3f c = mesh.positions.row(mesh.triangles(f, 2));
  return (b - a).cross(c - a);
}

}  // namespace

ObjMesh readObjMesh(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(ErrorCode::kIo, path + ": cannot open the file");
  std::vector<Eigen::Vector3f> points;
  std::vector<Eigen::Vector3i> faces;
  std::string text;
  int line = 0;
  while (std::getline(in, text)) {
    ++line;
    std::istringstream words(text);
    std::string kind;
    words >> kind;
    if (kind == "v") {
      Eigen::Vector3f p;
      if (!(words >> p.x() >> p.y() >> p.z()) || !p.allFinite()) {
        badLine(path, line, "a vertex needs three finite coordinates");
      }
      points.push_back(p);
    } else if (kind == "f") {
      std::vector<std::string> corners;
      for (std::string token; words >> token;) corners.push_back(token);
      if (corners.size() != 3) {
        badLine(path, line,
                "a face of " + std::to_string(corners.size()) +
                    " corners (only triangles are read)");
      }
      Eigen::Vector3i face;
      for (int k = 0; k < 3; ++k) {
        face[k] = cornerIndex(corners[k], static_cast<int>(points.size()), path,
                              line);
      }
      faces.push_back(face);
    }
  }
  if (in.bad()) throw Error(ErrorCode::kIo, path + ": read error");
  ObjMesh mesh;
  mesh.positions.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (size_t v = 0; v < points.size(); ++v)
    mesh.positions.row(v) = points[v].transpose();
  mesh.triangles.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f)
    mesh.triangles.row(f) = faces[f].transpose();
  return mesh;
}

FocusView worstPlaceView(const ObjMesh& frame,
                         const std::vector<std::pair<int, int>>& pairs,
                         const Matrix3Xf* reference, float diagonal,
                         float close_fraction) {
  FocusView focus;
  focus.view.half_height = std::max(close_fraction * diagonal, 1e-6f);
  std::vector<int> triangles;
  for (const auto& [a, b] : pairs) {
    triangles.push_back(a);
    triangles.push_back(b);
  }
  std::sort(triangles.begin(), triangles.end());
  triangles.erase(std::unique(triangles.begin(), triangles.end()),
                  triangles.end());
  Eigen::Vector3f target = Eigen::Vector3f::Zero();
  Eigen::Vector3f normal = Eigen::Vector3f::Zero();
  if (!triangles.empty()) {
    // The triangle with the most others within the close-up's radius.
    std::vector<Eigen::Vector3f> centres;
    for (const int f : triangles) centres.push_back(centroid(frame, f));
    const float radius2 = focus.view.half_height * focus.view.half_height;
    size_t best = 0;
    int best_count = -1;
    for (size_t i = 0; i < centres.size(); ++i) {
      int count = 0;
      for (const Eigen::Vector3f& c : centres)
        count += (c - centres[i]).squaredNorm() <= radius2;
      if (count > best_count) best_count = count, best = i;
    }
    int used = 0;
    for (size_t i = 0; i < centres.size(); ++i) {
      if ((centres[i] - centres[best]).squaredNorm() > radius2) continue;
      target += centres[i];
      normal += areaNormal(frame, triangles[i]);
      ++used;
    }
    target /= static_cast<float>(used);
    focus.reason = std::to_string(pairs.size()) +
                   " new intersecting pairs; close-up on " +
                   std::to_string(used) + " of their triangles";
  } else {
    int worst = 0;
    float worst_distance = -1;
    if (reference && reference->rows() == frame.positions.rows()) {
      for (Eigen::Index v = 0; v < frame.positions.rows(); ++v) {
        const float d = (frame.positions.row(v) - reference->row(v)).norm();
        if (d > worst_distance) worst_distance = d, worst = static_cast<int>(v);
      }
    }
    target = frame.positions.row(worst).transpose();
    for (Eigen::Index f = 0; f < frame.triangles.rows(); ++f) {
      for (int k = 0; k < 3; ++k)
        if (frame.triangles(f, k) == worst) normal += areaNormal(frame, f);
    }
    focus.reason = worst_distance >= 0
                       ? "no new intersecting pair; close-up on the vertex "
                         "farthest from the reference frame"
                       : "no new intersecting pair";
  }
  focus.view.target = target;
  focus.view.direction = normal.norm() > 0
                             ? Eigen::Vector3f(normal.normalized())
                             : Eigen::Vector3f(0, 0, 1);
  // Up: model +y unless the view looks along it.
  focus.view.up = std::abs(focus.view.direction.y()) > 0.95f
                      ? Eigen::Vector3f(0, 0, 1)
                      : Eigen::Vector3f(0, 1, 0);
  return focus;
}

Image stackVertically(const std::vector<Image>& rows) {
  if (rows.empty()) {
    throw Error(ErrorCode::kInvalidArgument, "stackVertically: no picture");
  }
  int width = 0, height = 0;
  for (const Image& row : rows) {
    width = std::max(width, row.width);
    height += row.height;
  }
  height += kPanelGap * static_cast<int>(rows.size() - 1);
  Image out(width, height);
  int y0 = 0;
  for (const Image& row : rows) {
    const int x0 = (width - row.width) / 2;
    for (int y = 0; y < row.height; ++y)
      for (int x = 0; x < row.width; ++x)
        out.set(x0 + x, y0 + y, row.get(x, y));
    y0 += row.height + kPanelGap;
  }
  return out;
}

}  // namespace isk::samples
