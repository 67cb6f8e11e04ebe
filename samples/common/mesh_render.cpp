#include "mesh_render.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <sstream>

#include "isk/core/error.hpp"

// stb_easy_font: every function is static (v1.1), so this copy cannot clash
// with another.
#include <stb/stb_easy_font.h>

namespace isk::samples {
namespace {

constexpr int kMaxPictureSide = 16384;
// Lambert shading: intensity = kAmbient + kDiffuse * max(0, n . light).
constexpr float kAmbient = 0.35f;
constexpr float kDiffuse = 0.65f;
// Pixels closer than this to a triangle edge are darkened (style.edges).
constexpr float kEdgePixels = 0.75f;
constexpr float kEdgeDarken = 0.55f;
// A neighbouring pixel farther than the plane of the face at a pixel
// predicts, by more than this many pixel sizes, draws an outline on the
// nearer pixel (style.outlines): a depth jump, not a steep surface.
constexpr float kOutlineJumpPixels = 3.f;
// Neighbouring pixels of faces whose normals differ by more than ~50 degrees
// draw an outline too: a sharp fold, or two surfaces meeting (contact, skin
// passing through skin), which the depth alone does not show.
constexpr float kCreaseCosine = 0.64f;
constexpr float kOutlineDarken = 0.35f;
constexpr Rgb kPageColour = {255, 255, 255};
constexpr Rgb kTextColour = {25, 25, 30};
constexpr int kTextPadding = 6;  // above and below each text band

[[noreturn]] void invalid(const std::string& message) {
  throw Error(ErrorCode::kInvalidArgument, message);
}

std::string describe(const Eigen::Vector3f& v) {
  std::ostringstream out;
  out << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return out.str();
}

// Orthonormal camera axes: right, up and towards the viewer.
struct Basis {
  Eigen::Vector3f right, up, toward;
};

Basis viewBasis(const Eigen::Vector3f& direction, const Eigen::Vector3f& up,
                const std::string& where) {
  if (!direction.allFinite() || !(direction.norm() > 0)) {
    invalid(where + ": the view direction " + describe(direction) +
            " is not a finite non-zero vector");
  }
  if (!up.allFinite()) {
    invalid(where + ": the up vector " + describe(up) + " is not finite");
  }
  Basis b;
  b.toward = direction.normalized();
  const Eigen::Vector3f right = up.cross(b.toward);
  // Relative test: an up within ~0.06 degrees of the direction is parallel.
  if (!(right.norm() > 1e-3f * up.norm())) {
    invalid(where + ": the up vector " + describe(up) +
            " is zero or parallel to the view direction " +
            describe(direction));
  }
  b.right = right.normalized();
  b.up = b.toward.cross(b.right);
  return b;
}

void checkFinite(const Matrix3Xf& positions, const std::string& where) {
  if (positions.allFinite()) return;
  for (Eigen::Index v = 0; v < positions.rows(); ++v) {
    if (!positions.row(v).allFinite()) {
      invalid(where + ": vertex " + std::to_string(v) +
              " has a non-finite position");
    }
  }
}

Rgb scaled(const Rgb& c, float factor) {
  Rgb out;
  for (int k = 0; k < 3; ++k) {
    out[k] =
        static_cast<uint8_t>(std::clamp(std::lround(c[k] * factor), 0L, 255L));
  }
  return out;
}

// Pixel range [first, last] whose centres (i + 0.5) may lie in [lo, hi],
// clamped to [0, size - 1]; empty when first > last. Clamping in float
// first keeps far-away coordinates from overflowing the int conversion.
void pixelRange(float lo, float hi, int size, int& first, int& last) {
  lo = std::clamp(lo - 0.5f, -1.f, static_cast<float>(size));
  hi = std::clamp(hi - 0.5f, -1.f, static_cast<float>(size));
  first = std::max(0, static_cast<int>(std::ceil(lo)));
  last = std::min(size - 1, static_cast<int>(std::floor(hi)));
}

// One edge of a triangle being rasterized: its edge function evaluated from
// the lexicographically smaller end point, so the two triangles sharing the
// edge compute bitwise the same value with opposite signs and inclusive
// tests leave no cracks between them.
struct Edge {
  float ax, ay, dx, dy, sign, inverse_length;

  Edge(float x0, float y0, float x1, float y1) {
    sign = 1;
    if (std::make_pair(x1, y1) < std::make_pair(x0, y0)) {
      std::swap(x0, x1);
      std::swap(y0, y1);
      sign = -1;
    }
    ax = x0;
    ay = y0;
    dx = x1 - x0;
    dy = y1 - y0;
    inverse_length = 1.f / std::sqrt(dx * dx + dy * dy);
  }
  // Twice the signed area of (start, end, p): >= 0 inside the triangle.
  float at(float px, float py) const {
    return sign * (dx * (py - ay) - dy * (px - ax));
  }
};

// Text quads of stb_easy_font for `text` (printable ASCII and '\n'), in
// font units from the top-left corner of the first line.
struct TextQuad {
  float x0, y0, x1, y1;
};

std::string printable(const std::string& text) {
  std::string out = text;
  for (char& c : out) {
    const auto u = static_cast<unsigned char>(c);
    if (c != '\n' && (u < 32 || u > 126)) c = '?';
  }
  return out;
}

std::vector<TextQuad> textQuads(std::string text) {
  // stb_easy_font uses at most ~270 bytes (about four 64-byte quads) per
  // character; 1 KiB a character never truncates.
  std::vector<char> buffer(text.size() * 1024 + 64);
  const int count =
      stb_easy_font_print(0, 0, text.data(), nullptr, buffer.data(),
                          static_cast<int>(buffer.size()));
  std::vector<TextQuad> quads;
  quads.reserve(count);
  for (int q = 0; q < count; ++q) {
    TextQuad quad{std::numeric_limits<float>::max(),
                  std::numeric_limits<float>::max(),
                  std::numeric_limits<float>::lowest(),
                  std::numeric_limits<float>::lowest()};
    for (int corner = 0; corner < 4; ++corner) {
      float xy[2];
      // Vertices are 16 bytes: x, y, z floats and a colour.
      std::memcpy(xy, buffer.data() + q * 64 + corner * 16, sizeof xy);
      quad.x0 = std::min(quad.x0, xy[0]);
      quad.x1 = std::max(quad.x1, xy[0]);
      quad.y0 = std::min(quad.y0, xy[1]);
      quad.y1 = std::max(quad.y1, xy[1]);
    }
    quads.push_back(quad);
  }
  return quads;
}

struct TextSize {
  int width = 0, height = 0;  // pixels at kTextScale
};

TextSize textSize(std::string text) {
  if (text.empty()) return {};
  return {stb_easy_font_width(text.data()) * kTextScale,
          stb_easy_font_height(text.data()) * kTextScale};
}

// Draws `text` at kTextScale with its top-left corner at (x, y), keeping to
// columns [clip_x0, clip_x1) of the image.
void drawText(Image& image, const std::string& text, int x, int y, int clip_x0,
              int clip_x1) {
  clip_x0 = std::max(clip_x0, 0);
  clip_x1 = std::min(clip_x1, image.width);
  for (const TextQuad& q : textQuads(text)) {
    const int px0 = std::max(clip_x0, x + static_cast<int>(q.x0) * kTextScale);
    const int px1 = std::min(clip_x1, x + static_cast<int>(q.x1) * kTextScale);
    const int py0 = std::max(0, y + static_cast<int>(q.y0) * kTextScale);
    const int py1 =
        std::min(image.height, y + static_cast<int>(q.y1) * kTextScale);
    for (int py = py0; py < py1; ++py) {
      for (int px = px0; px < px1; ++px) image.set(px, py, kTextColour);
    }
  }
}

// Height of a band holding the tallest of `texts` (0 when all are empty).
int bandHeight(const std::vector<std::string>& texts) {
  int tallest = 0;
  for (const std::string& t : texts) {
    tallest = std::max(tallest, textSize(t).height);
  }
  return tallest > 0 ? tallest + 2 * kTextPadding : 0;
}

// Draws `text` centred in columns [x0, x1) (left-aligned when wider),
// starting at row y.
void drawCentred(Image& image, const std::string& text, int x0, int x1, int y) {
  const int width = textSize(text).width;
  const int x = x0 + std::max(0, (x1 - x0 - width) / 2);
  drawText(image, text, x, y, x0, x1);
}

}  // namespace

RenderView frameViews(const std::vector<const Matrix3Xf*>& meshes,
                      const Eigen::Vector3f& direction,
                      const Eigen::Vector3f& up, float margin, float aspect) {
  const std::string where = "frameView";
  if (!(margin >= 0) || !std::isfinite(margin)) {
    invalid(where + ": margin " + std::to_string(margin) +
            " is not a finite number >= 0");
  }
  if (!(aspect > 0) || !std::isfinite(aspect)) {
    invalid(where + ": aspect " + std::to_string(aspect) +
            " is not a finite number > 0");
  }
  const Basis b = viewBasis(direction, up, where);
  Eigen::Vector3f lo =
      Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  Eigen::Vector3f hi = -lo;
  Eigen::Index count = 0;
  for (size_t m = 0; m < meshes.size(); ++m) {
    if (!meshes[m]) invalid(where + ": mesh " + std::to_string(m) + " is null");
    const Matrix3Xf& positions = *meshes[m];
    checkFinite(positions, where + " (mesh " + std::to_string(m) + ")");
    for (Eigen::Index v = 0; v < positions.rows(); ++v) {
      const Eigen::Vector3f p = positions.row(v).transpose();
      const Eigen::Vector3f q(p.dot(b.right), p.dot(b.up), p.dot(b.toward));
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
    count += positions.rows();
  }
  if (count == 0) invalid(where + ": no positions to frame");
  const Eigen::Vector3f centre = 0.5f * (lo + hi);
  RenderView view;
  view.target =
      centre.x() * b.right + centre.y() * b.up + centre.z() * b.toward;
  view.direction = b.toward;
  view.up = b.up;
  float half = std::max((hi.y() - lo.y()) / 2, (hi.x() - lo.x()) / 2 / aspect);
  // A single point (or points on the view axis) has no extent: show a unit.
  if (!(half > 0)) half = 1;
  view.half_height = half * (1 + margin);
  return view;
}

RenderView frameView(const Matrix3Xf& positions,
                     const Eigen::Vector3f& direction,
                     const Eigen::Vector3f& up, float margin, float aspect) {
  return frameViews({&positions}, direction, up, margin, aspect);
}

Image renderMesh(const Matrix3Xf& positions, const TriangleMatrix& triangles,
                 const RenderView& view, int width, int height,
                 const RenderStyle& style) {
  const std::string where = "renderMesh";
  if (width < 1 || height < 1 || width > kMaxPictureSide ||
      height > kMaxPictureSide) {
    invalid(where + ": picture size " + std::to_string(width) + "x" +
            std::to_string(height) + " is outside 1.." +
            std::to_string(kMaxPictureSide));
  }
  if (!view.target.allFinite()) {
    invalid(where + ": the view target " + describe(view.target) +
            " is not finite");
  }
  if (!(view.half_height > 0) || !std::isfinite(view.half_height)) {
    invalid(where + ": the view half_height " +
            std::to_string(view.half_height) + " is not a finite number > 0");
  }
  const Basis b = viewBasis(view.direction, view.up, where);
  checkFinite(positions, where);
  const Eigen::Index vertex_count = positions.rows();
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int v = triangles(f, k);
      if (v < 0 || v >= vertex_count) {
        invalid(where + ": triangle " + std::to_string(f) + " corner " +
                std::to_string(k) + " has vertex index " + std::to_string(v) +
                ", outside [0, " + std::to_string(vertex_count) + ")");
      }
    }
  }
  if (style.vertex_colours &&
      static_cast<Eigen::Index>(style.vertex_colours->size()) != vertex_count) {
    invalid(where + ": " + std::to_string(style.vertex_colours->size()) +
            " vertex colours for " + std::to_string(vertex_count) +
            " vertices");
  }

  // Screen coordinates: x right, y down, pixel centres at i + 0.5; depth
  // grows towards the viewer.
  const float scale = height / (2 * view.half_height);
  std::vector<float> sx(vertex_count), sy(vertex_count), sz(vertex_count);
  for (Eigen::Index v = 0; v < vertex_count; ++v) {
    const Eigen::Vector3f d = positions.row(v).transpose() - view.target;
    sx[v] = 0.5f * width + d.dot(b.right) * scale;
    sy[v] = 0.5f * height - d.dot(b.up) * scale;
    sz[v] = d.dot(b.toward);
  }
  // Near the viewer, a little above and to the left, so faces turned
  // towards the viewer differ in shade by how they turn.
  const Eigen::Vector3f light =
      (b.toward + 0.3f * b.up - 0.2f * b.right).normalized();

  Image image(width, height);
  const size_t pixels = static_cast<size_t>(width) * height;
  for (size_t i = 0; i < pixels; ++i) {
    std::memcpy(&image.rgb[3 * i], style.background.data(), 3);
  }
  std::vector<float> depth(pixels, -std::numeric_limits<float>::infinity());
  // For the outlines: the face drawn at each pixel (-1: none), each face's
  // outward unit normal and its depth change per pixel along x and y.
  std::vector<int32_t> face_at;
  std::vector<Eigen::Vector3f> outward;
  std::vector<Eigen::Vector2f> slope;
  if (style.outlines) {
    face_at.assign(pixels, -1);
    outward.resize(triangles.rows());
    slope.resize(triangles.rows());
  }

  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    int i[3] = {triangles(f, 0), triangles(f, 1), triangles(f, 2)};
    // Twice the signed screen area; counter-clockwise in the model's view
    // (a front face) is clockwise, negative, with y down.
    const float area = (sx[i[1]] - sx[i[0]]) * (sy[i[2]] - sy[i[0]]) -
                       (sy[i[1]] - sy[i[0]]) * (sx[i[2]] - sx[i[0]]);
    if (!(std::abs(area) > 1e-12f)) continue;  // edge-on or degenerate
    const bool front = area < 0;
    if (front) std::swap(i[1], i[2]);  // positive area: inside is w >= 0

    const Eigen::Vector3f p0 = positions.row(i[0]).transpose();
    const Eigen::Vector3f p1 = positions.row(i[1]).transpose();
    const Eigen::Vector3f p2 = positions.row(i[2]).transpose();
    // After the swap the screen winding is the same for front and back
    // faces, so this normal always faces the viewer (outward for front
    // faces, inward for back faces): the lit side either way.
    Eigen::Vector3f normal = (p2 - p0).cross(p1 - p0);
    const float length = normal.norm();
    normal = length > 0 ? Eigen::Vector3f(normal / length) : b.toward;
    const float shade = kAmbient + kDiffuse * std::max(0.f, normal.dot(light));
    if (style.outlines) {
      outward[f] = front ? normal : Eigen::Vector3f(-normal);
      const float ex1 = sx[i[1]] - sx[i[0]], ey1 = sy[i[1]] - sy[i[0]];
      const float ex2 = sx[i[2]] - sx[i[0]], ey2 = sy[i[2]] - sy[i[0]];
      const float ez1 = sz[i[1]] - sz[i[0]], ez2 = sz[i[2]] - sz[i[0]];
      const float positive_area = std::abs(area);
      slope[f] = Eigen::Vector2f((ez1 * ey2 - ez2 * ey1) / positive_area,
                                 (ez2 * ex1 - ez1 * ex2) / positive_area);
    }
    const Rgb face_colour = scaled(front ? style.front : style.back, shade);
    const bool tinted = front && style.vertex_colours;

    const Edge edges[3] = {Edge(sx[i[1]], sy[i[1]], sx[i[2]], sy[i[2]]),
                           Edge(sx[i[2]], sy[i[2]], sx[i[0]], sy[i[0]]),
                           Edge(sx[i[0]], sy[i[0]], sx[i[1]], sy[i[1]])};
    int x_first, x_last, y_first, y_last;
    pixelRange(std::min({sx[i[0]], sx[i[1]], sx[i[2]]}),
               std::max({sx[i[0]], sx[i[1]], sx[i[2]]}), width, x_first,
               x_last);
    pixelRange(std::min({sy[i[0]], sy[i[1]], sy[i[2]]}),
               std::max({sy[i[0]], sy[i[1]], sy[i[2]]}), height, y_first,
               y_last);
    for (int y = y_first; y <= y_last; ++y) {
      const float py = y + 0.5f;
      for (int x = x_first; x <= x_last; ++x) {
        const float px = x + 0.5f;
        const float w0 = edges[0].at(px, py);
        const float w1 = edges[1].at(px, py);
        const float w2 = edges[2].at(px, py);
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const float sum = w0 + w1 + w2;
        if (!(sum > 0)) continue;
        const float b0 = w0 / sum, b1 = w1 / sum, b2 = 1 - b0 - b1;
        const float z = b0 * sz[i[0]] + b1 * sz[i[1]] + b2 * sz[i[2]];
        const size_t pixel = static_cast<size_t>(y) * width + x;
        if (!(z > depth[pixel])) continue;
        depth[pixel] = z;
        if (style.outlines) face_at[pixel] = static_cast<int32_t>(f);
        Rgb c = face_colour;
        if (tinted) {
          const std::vector<Rgb>& vc = *style.vertex_colours;
          for (int k = 0; k < 3; ++k) {
            const float mixed =
                b0 * vc[i[0]][k] + b1 * vc[i[1]][k] + b2 * vc[i[2]][k];
            c[k] = static_cast<uint8_t>(
                std::clamp(std::lround(mixed * shade), 0L, 255L));
          }
        }
        if (style.edges) {
          const float nearest = std::min({w0 * edges[0].inverse_length,
                                          w1 * edges[1].inverse_length,
                                          w2 * edges[2].inverse_length});
          if (nearest < kEdgePixels) c = scaled(c, kEdgeDarken);
        }
        std::memcpy(&image.rgb[3 * pixel], c.data(), 3);
      }
    }
  }

  if (style.outlines) {
    // A covered pixel whose 4-neighbour (inside the picture) is uncovered
    // or much farther lies on an occluding contour; one whose right or lower
    // neighbour shows a face turned much differently lies on a crease.
    // Darken both.
    const float jump = kOutlineJumpPixels / scale;
    std::vector<uint8_t> outline(pixels, 0);
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        const size_t pixel = static_cast<size_t>(y) * width + x;
        const float z = depth[pixel];
        if (z == -std::numeric_limits<float>::infinity()) continue;
        const Eigen::Vector2f& gradient = slope[face_at[pixel]];
        // Uncovered neighbours have depth -infinity: always farther.
        auto farther = [&](int dx, int dy) {
          const int nx = x + dx, ny = y + dy;
          if (nx < 0 || ny < 0 || nx >= width || ny >= height) return false;
          const float predicted = z + dx * gradient.x() + dy * gradient.y();
          return depth[static_cast<size_t>(ny) * width + nx] < predicted - jump;
        };
        auto crease = [&](int nx, int ny) {
          if (nx >= width || ny >= height) return false;
          const int other = face_at[static_cast<size_t>(ny) * width + nx];
          return other >= 0 && other != face_at[pixel] &&
                 outward[other].dot(outward[face_at[pixel]]) < kCreaseCosine;
        };
        outline[pixel] = farther(-1, 0) || farther(1, 0) || farther(0, -1) ||
                         farther(0, 1) || crease(x + 1, y) || crease(x, y + 1);
      }
    }
    for (size_t pixel = 0; pixel < pixels; ++pixel) {
      if (!outline[pixel]) continue;
      for (int k = 0; k < 3; ++k) {
        image.rgb[3 * pixel + k] = static_cast<uint8_t>(
            std::lround(image.rgb[3 * pixel + k] * kOutlineDarken));
      }
    }
  }
  return image;
}

Image sideBySide(const std::vector<Image>& panels,
                 const std::vector<std::string>& captions,
                 const std::string& title) {
  const std::string where = "sideBySide";
  if (panels.empty()) invalid(where + ": no panels");
  if (captions.size() != panels.size()) {
    invalid(where + ": " + std::to_string(captions.size()) + " captions for " +
            std::to_string(panels.size()) + " panels");
  }
  const int panel_height = panels[0].height;
  int width = 0;
  for (size_t p = 0; p < panels.size(); ++p) {
    const Image& panel = panels[p];
    if (panel.width < 1 || panel.height < 1 ||
        panel.rgb.size() !=
            static_cast<size_t>(panel.width) * panel.height * 3) {
      invalid(where + ": panel " + std::to_string(p) + " (" +
              std::to_string(panel.width) + "x" + std::to_string(panel.height) +
              ") is empty or malformed");
    }
    if (panel.height != panel_height) {
      invalid(where + ": panel " + std::to_string(p) + " is " +
              std::to_string(panel.height) + " pixels high, panel 0 is " +
              std::to_string(panel_height));
    }
    width += panel.width + (p > 0 ? kPanelGap : 0);
  }
  const std::string title_text = printable(title);
  std::vector<std::string> caption_texts;
  for (const std::string& c : captions) caption_texts.push_back(printable(c));
  const int title_band = bandHeight({title_text});
  const int caption_band = bandHeight(caption_texts);

  Image image(width, title_band + caption_band + panel_height);
  for (size_t i = 0; i < image.rgb.size(); i += 3) {
    std::memcpy(&image.rgb[i], kPageColour.data(), 3);
  }
  if (title_band > 0) drawCentred(image, title_text, 0, width, kTextPadding);
  int x = 0;
  for (size_t p = 0; p < panels.size(); ++p) {
    const Image& panel = panels[p];
    if (!caption_texts[p].empty()) {
      drawCentred(image, caption_texts[p], x, x + panel.width,
                  title_band + kTextPadding);
    }
    for (int y = 0; y < panel_height; ++y) {
      std::memcpy(
          &image.rgb[(static_cast<size_t>(title_band + caption_band + y) *
                          width +
                      x) *
                     3],
          &panel.rgb[static_cast<size_t>(y) * panel.width * 3],
          static_cast<size_t>(panel.width) * 3);
    }
    x += panel.width + kPanelGap;
  }
  return image;
}

}  // namespace isk::samples
