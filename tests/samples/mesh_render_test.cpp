// The samples' software rasterizer (samples/common/mesh_render.hpp): pixel
// coverage of a quad facing the camera, front and back colours, the
// z-buffer, flat shading of a fold, outlines and edges, framing a
// procedural cylinder, side-by-side panels with captions (decoded back from
// PNG) and errors for bad input.
#include "mesh_render.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "isk/core/error.hpp"
#include "isk/rig/rig.hpp"
#include "isk/tools/procedural.hpp"
#include "slice_image.hpp"
#include "test_support.hpp"

namespace isk {
namespace {

using samples::Image;
using samples::RenderStyle;
using samples::RenderView;
using samples::Rgb;

// A square of side `size` centred at (cx, cy) in the plane z, counter-
// clockwise seen from +z (the default view's viewer).
struct Quad {
  Matrix3Xf positions;
  TriangleMatrix triangles;
};

Quad square(float cx, float cy, float z, float size) {
  const float h = size / 2;
  Quad q;
  q.positions.resize(4, 3);
  q.positions << cx - h, cy - h, z,  //
      cx + h, cy - h, z,             //
      cx + h, cy + h, z,             //
      cx - h, cy + h, z;
  q.triangles.resize(2, 3);
  q.triangles << 0, 1, 2,  //
      0, 2, 3;
  return q;
}

bool isBackground(const Image& image, int x, int y,
                  const RenderStyle& style = {}) {
  return image.get(x, y) == style.background;
}

// Covered pixels and their bounding box.
struct Coverage {
  long count = 0;
  int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
  bool touchesBorder = false;
};

Coverage coverage(const Image& image, const RenderStyle& style = {}) {
  Coverage c;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      if (isBackground(image, x, y, style)) continue;
      ++c.count;
      c.x0 = std::min(c.x0, x);
      c.x1 = std::max(c.x1, x);
      c.y0 = std::min(c.y0, y);
      c.y1 = std::max(c.y1, y);
      if (x == 0 || y == 0 || x == image.width - 1 || y == image.height - 1) {
        c.touchesBorder = true;
      }
    }
  }
  return c;
}

std::string describe(const Rgb& c) {
  return "(" + std::to_string(c[0]) + ", " + std::to_string(c[1]) + ", " +
         std::to_string(c[2]) + ")";
}

// The front colour family: a light neutral grey, blue a little above red.
bool isFrontFamily(const Rgb& c) {
  return c[0] >= 100 && std::abs(int(c[0]) - int(c[1])) <= 8 && c[2] >= c[0] &&
         c[2] - c[0] <= 15;
}
// The back colour family: red well above green and blue.
bool isBackFamily(const Rgb& c) {
  return c[0] >= 100 && c[0] - c[1] >= 80 && c[0] - c[2] >= 80;
}

int brightness(const Rgb& c) { return int(c[0]) + c[1] + c[2]; }

TEST(MeshRender, QuadFacingTheCameraCoversItsAreaInTheFrontColour) {
  // A unit square at the centre of a view 2 units high, 100 pixels: it
  // covers pixel columns and rows 25..74.
  const Quad q = square(0, 0, 0, 1);
  const Image image =
      samples::renderMesh(q.positions, q.triangles, RenderView{}, 100, 100);
  ASSERT_EQ(image.width, 100);
  ASSERT_EQ(image.height, 100);
  const Coverage c = coverage(image);
  EXPECT_NEAR(c.x0, 25, 1);
  EXPECT_NEAR(c.x1, 74, 1);
  EXPECT_NEAR(c.y0, 25, 1);
  EXPECT_NEAR(c.y1, 74, 1);
  EXPECT_GE(c.count, 49 * 49);
  EXPECT_LE(c.count, 51 * 51);
  // Every pixel of the interior is the front colour (the boundary holds the
  // darker outline).
  for (int y = 27; y <= 72; ++y) {
    for (int x = 27; x <= 72; ++x) {
      ASSERT_TRUE(isFrontFamily(image.get(x, y)))
          << "pixel (" << x << ", " << y << ") is "
          << describe(image.get(x, y));
    }
  }
  // Lit from near the viewer: a face turned to the viewer is bright.
  EXPECT_GE(image.get(50, 50)[0], 160) << describe(image.get(50, 50));
  // The outline darkens the silhouette.
  EXPECT_LT(brightness(image.get(25, 50)), brightness(image.get(50, 50)) / 2)
      << describe(image.get(25, 50));
}

TEST(MeshRender, ClockwiseQuadShowsTheBackColour) {
  Quad q = square(0, 0, 0, 1);
  q.triangles.col(1).swap(q.triangles.col(2));
  const Image image =
      samples::renderMesh(q.positions, q.triangles, RenderView{}, 100, 100);
  const Coverage c = coverage(image);
  EXPECT_GE(c.count, 49 * 49);
  EXPECT_LE(c.count, 51 * 51);
  EXPECT_TRUE(isBackFamily(image.get(50, 50))) << describe(image.get(50, 50));
  EXPECT_FALSE(isFrontFamily(image.get(50, 50)));
  // Back faces are shaded too (the same as the front face would be).
  EXPECT_GE(image.get(50, 50)[0], 160) << describe(image.get(50, 50));
}

TEST(MeshRender, NearerQuadWinsWhateverTheDrawOrder) {
  // Near (z = 0.5, green) at lower left, far (z = -0.5, blue) at upper
  // right; they overlap around the centre.
  const Quad near_quad = square(-0.16f, -0.16f, 0.5f, 0.8f);
  const Quad far_quad = square(0.15f, 0.15f, -0.5f, 0.8f);
  Matrix3Xf positions(8, 3);
  positions << near_quad.positions, far_quad.positions;
  const std::vector<Rgb> colours = {{40, 200, 40}, {40, 200, 40}, {40, 200, 40},
                                    {40, 200, 40}, {40, 40, 200}, {40, 40, 200},
                                    {40, 40, 200}, {40, 40, 200}};
  TriangleMatrix near_first(4, 3), far_first(4, 3);
  const TriangleMatrix far_shifted = (far_quad.triangles.array() + 4).matrix();
  near_first << near_quad.triangles, far_shifted;
  far_first << far_shifted, near_quad.triangles;
  RenderStyle style;
  style.vertex_colours = &colours;
  auto green = [](const Rgb& c) {
    return c[1] > c[0] + 80 && c[1] > c[2] + 80;
  };
  auto blue = [](const Rgb& c) { return c[2] > c[0] + 80 && c[2] > c[1] + 80; };
  for (const TriangleMatrix* triangles : {&near_first, &far_first}) {
    SCOPED_TRACE(triangles == &near_first ? "near drawn first"
                                          : "far drawn first");
    const Image image = samples::renderMesh(positions, *triangles, RenderView{},
                                            100, 100, style);
    // Model (0, 0), in both quads: pixel (50, 50).
    EXPECT_TRUE(green(image.get(50, 50))) << describe(image.get(50, 50));
    // Model (-0.4, -0.4), only the near one; (0.4, 0.4), only the far one.
    EXPECT_TRUE(green(image.get(30, 70))) << describe(image.get(30, 70));
    EXPECT_TRUE(blue(image.get(70, 30))) << describe(image.get(70, 30));
    // The near quad's edge over the far quad (model x = 0.24, between pixel
    // columns 61 and 62) is outlined: a depth jump.
    EXPECT_TRUE(blue(image.get(62, 45))) << describe(image.get(62, 45));
    EXPECT_LT(brightness(image.get(61, 45)), brightness(image.get(57, 45)) / 2)
        << describe(image.get(61, 45)) << " vs " << describe(image.get(57, 45));
  }
  // Without outlines that pixel is the near quad's plain green.
  style.outlines = false;
  const Image plain =
      samples::renderMesh(positions, near_first, RenderView{}, 100, 100, style);
  EXPECT_EQ(plain.get(61, 45), plain.get(57, 45));
}

// A roof along y over [-0.5, 0.5]^2: two faces meeting at x = 0, each
// tilted `degrees` towards the viewer (+z).
Quad roof(float degrees) {
  const float t = std::tan(degrees * 3.14159265f / 180.f) * 0.5f;
  Quad q;
  q.positions.resize(6, 3);
  q.positions << -0.5f, -0.5f, -t,  //
      0, -0.5f, 0,                  //
      0.5f, -0.5f, -t,              //
      -0.5f, 0.5f, -t,              //
      0, 0.5f, 0,                   //
      0.5f, 0.5f, -t;
  q.triangles.resize(4, 3);
  q.triangles << 0, 1, 4,  //
      0, 4, 3,             //
      1, 2, 5,             //
      1, 5, 4;
  return q;
}

TEST(MeshRender, FlatShadingAndCreaseLinesShowAFold) {
  // Faces 70 degrees apart. The light comes from the upper left, so the
  // halves differ in shade.
  const Quad sharp = roof(35);
  RenderStyle style;
  style.outlines = false;
  const Image image = samples::renderMesh(sharp.positions, sharp.triangles,
                                          RenderView{}, 100, 100, style);
  const Rgb left = image.get(37, 50), right = image.get(63, 50);
  EXPECT_TRUE(isFrontFamily(left)) << describe(left);
  EXPECT_TRUE(isFrontFamily(right)) << describe(right);
  EXPECT_GT(brightness(left), brightness(right) + 45)
      << describe(left) << " vs " << describe(right);
  // Each half is flat: one shade across it, up to the ridge.
  EXPECT_EQ(image.get(30, 40), left);
  EXPECT_EQ(image.get(49, 60), left);
  EXPECT_EQ(image.get(70, 60), right);
  EXPECT_EQ(image.get(50, 40), right);
  // The wireframe overlay darkens the triangle edges (the diagonal of the
  // left half passes through model (-0.25, 0): pixel (37, 50)).
  style.edges = true;
  const Image wire = samples::renderMesh(sharp.positions, sharp.triangles,
                                         RenderView{}, 100, 100, style);
  EXPECT_LT(brightness(wire.get(37, 50)), brightness(left) * 0.7)
      << describe(wire.get(37, 50));
  EXPECT_EQ(wire.get(30, 40), left);
  // Outlines draw the ridge (between pixel columns 49 and 50) as a line.
  style = RenderStyle{};
  const Image lined = samples::renderMesh(sharp.positions, sharp.triangles,
                                          RenderView{}, 100, 100, style);
  for (int y = 30; y < 70; y += 7) {
    EXPECT_LT(
        std::min(brightness(lined.get(49, y)), brightness(lined.get(50, y))),
        brightness(right) / 2)
        << "row " << y;
    EXPECT_EQ(lined.get(45, y), left) << "row " << y;
    EXPECT_EQ(lined.get(54, y), right) << "row " << y;
  }
  // A gentle fold (20 degrees) is no crease: no line at its ridge.
  const Quad gentle = roof(10);
  const Image smooth = samples::renderMesh(gentle.positions, gentle.triangles,
                                           RenderView{}, 100, 100, style);
  for (int x = 27; x <= 72; ++x) {
    EXPECT_TRUE(smooth.get(x, 50) == smooth.get(27, 50) ||
                smooth.get(x, 50) == smooth.get(72, 50))
        << "pixel (" << x << ", 50) is " << describe(smooth.get(x, 50));
  }
}

TEST(MeshRender, FrameViewFramesACylinder) {
  const Rig rig = makeCylinderRig();  // radius 1, length 8 along +x
  const Matrix3Xf& positions = rig.mesh.positions;
  struct Case {
    Eigen::Vector3f direction, up;
    int width, height;
  };
  const Case cases[] = {
      {{0, 0, 1}, {0, 1, 0}, 200, 120},  // side view, wider than high
      {{0, 1, 0}, {1, 0, 0}, 80, 200},   // the cylinder upright
      {{1, 1, 1}, {0, 0, 1}, 150, 150},  // oblique
      {{1, 0, 0}, {0, 1, 0}, 100, 100},  // along the axis: a disc
  };
  for (const Case& k : cases) {
    SCOPED_TRACE("direction (" + std::to_string(k.direction.x()) + ", " +
                 std::to_string(k.direction.y()) + ", " +
                 std::to_string(k.direction.z()) + ")");
    const RenderView view = samples::frameView(
        positions, k.direction, k.up, 0.05f, float(k.width) / k.height);
    const Image image = samples::renderMesh(positions, rig.mesh.triangles, view,
                                            k.width, k.height);
    const Coverage c = coverage(image);
    EXPECT_FALSE(c.touchesBorder);
    const double fraction = double(c.count) / (k.width * k.height);
    EXPECT_GT(fraction, 0.15);
    EXPECT_LT(fraction, 0.8);
    // Framed tightly: along the limiting side the mesh spans the picture
    // less the margin (5% of the half extent on each side, ~1 pixel more).
    const double spanned = std::max(double(c.x1 - c.x0 + 1) / k.width,
                                    double(c.y1 - c.y0 + 1) / k.height);
    EXPECT_GT(spanned, 0.92);
    // Centred.
    EXPECT_NEAR(c.x0 + c.x1 + 1, k.width, 3);
    EXPECT_NEAR(c.y0 + c.y1 + 1, k.height, 3);
  }
  // Along the axis the view sees the cap at x = 8 from outside: front
  // colour, not back.
  const RenderView axial = samples::frameView(positions, {1, 0, 0}, {0, 1, 0});
  const Image cap =
      samples::renderMesh(positions, rig.mesh.triangles, axial, 100, 100);
  EXPECT_TRUE(isFrontFamily(cap.get(50, 50))) << describe(cap.get(50, 50));
}

TEST(MeshRender, FrameViewsGivesPanelsOneScale) {
  const Rig rig = makeCylinderRig();
  const Matrix3Xf& a = rig.mesh.positions;
  Matrix3Xf b = a;
  b.col(1).array() += 6;  // the same cylinder, 6 units higher
  const Eigen::Vector3f direction(0, 0, 1), up(0, 1, 0);
  const RenderView both = samples::frameViews({&a, &b}, direction, up);
  const RenderView only_a = samples::frameView(a, direction, up);
  EXPECT_NEAR(both.half_height, only_a.half_height, 1e-4f);  // width limits
  EXPECT_NEAR(both.target.y(), 3, 1e-4f);
  // Each mesh lies inside the shared view: nothing on the border, a at the
  // bottom half, b at the top half.
  const Image image_a =
      samples::renderMesh(a, rig.mesh.triangles, both, 120, 120);
  const Image image_b =
      samples::renderMesh(b, rig.mesh.triangles, both, 120, 120);
  const Coverage ca = coverage(image_a), cb = coverage(image_b);
  EXPECT_FALSE(ca.touchesBorder);
  EXPECT_FALSE(cb.touchesBorder);
  EXPECT_GT(ca.y0, 60);
  EXPECT_LT(cb.y1, 60);
  EXPECT_NEAR(ca.count, cb.count, 0.05 * ca.count);
}

std::vector<uint8_t> decodePng(const std::string& bytes, int& width,
                               int& height) {
  test::DecodedPng png = test::decodePng(bytes, "the encoded PNG");
  width = png.width;
  height = png.height;
  return std::move(png.rgb);
}

bool isText(const Rgb& c) { return brightness(c) < 150; }

// Text pixels in columns [x0, x1) and rows [y0, y1).
long textPixels(const Image& image, int x0, int x1, int y0, int y1) {
  long count = 0;
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) count += isText(image.get(x, y));
  }
  return count;
}

Image filled(int width, int height, const Rgb& colour) {
  Image image(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) image.set(x, y, colour);
  }
  return image;
}

TEST(MeshRender, SideBySidePlacesPanelsUnderTheirCaptions) {
  const std::vector<Rgb> colours = {
      {200, 40, 40}, {40, 200, 40}, {40, 40, 200}};
  const std::vector<int> widths = {90, 70, 110};
  std::vector<Image> panels;
  for (size_t p = 0; p < colours.size(); ++p) {
    panels.push_back(filled(widths[p], 50, colours[p]));
  }
  // The last caption holds UTF-8 (printed as '?') and is wider than its
  // panel: it is clipped to the panel's columns.
  const std::vector<std::string> captions = {
      "LBS", "DQS", "implicit \xc3\xa9 with a long caption"};
  const Image image = samples::sideBySide(panels, captions);
  ASSERT_EQ(image.width, 90 + 70 + 110 + 2 * samples::kPanelGap);
  ASSERT_GT(image.height, 50 + 12 * samples::kTextScale);
  const int top = image.height - 50;
  int x = 0;
  for (size_t p = 0; p < panels.size(); ++p) {
    SCOPED_TRACE("panel " + std::to_string(p));
    // The panel is copied at the bottom, its caption is above it.
    EXPECT_EQ(image.get(x, top), colours[p]);
    EXPECT_EQ(image.get(x + widths[p] - 1, image.height - 1), colours[p]);
    EXPECT_GT(textPixels(image, x, x + widths[p], 0, top), 20);
    if (p > 0) {  // the gap before it is blank
      EXPECT_EQ(textPixels(image, x - samples::kPanelGap, x, 0, image.height),
                0);
      EXPECT_EQ(image.get(x - 1, image.height - 1), Rgb({255, 255, 255}));
    }
    x += widths[p] + samples::kPanelGap;
  }
  // A title adds a band of text above the captions.
  const Image titled = samples::sideBySide(panels, captions, "Bent elbow");
  EXPECT_EQ(titled.width, image.width);
  const int band = titled.height - image.height;
  ASSERT_GE(band, 12 * samples::kTextScale);
  EXPECT_GT(textPixels(titled, 0, titled.width, 0, band), 20);
  EXPECT_EQ(textPixels(image, 0, image.width, 0, 3), 0);

  // PNG round trip.
  int width = 0, height = 0;
  const std::vector<uint8_t> decoded =
      decodePng(samples::encodePng(titled), width, height);
  EXPECT_EQ(width, titled.width);
  EXPECT_EQ(height, titled.height);
  EXPECT_TRUE(decoded == titled.rgb);
}

template <typename F>
void expectInvalidArgument(F&& f, const std::string& expected_text) {
  try {
    f();
    ADD_FAILURE() << "no isk::Error; expected one saying '" << expected_text
                  << "'";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument) << e.what();
    EXPECT_NE(std::string(e.what()).find(expected_text), std::string::npos)
        << e.what();
  }
}

TEST(MeshRender, BadInputThrowsInvalidArgument) {
  const Quad q = square(0, 0, 0, 1);
  const RenderView view;
  auto render = [&](const Matrix3Xf& positions, const TriangleMatrix& triangles,
                    const RenderView& v, int width, int height,
                    const RenderStyle& style = {}) {
    (void)samples::renderMesh(positions, triangles, v, width, height, style);
  };
  expectInvalidArgument([&] { render(q.positions, q.triangles, view, 0, 10); },
                        "picture size 0x10");
  expectInvalidArgument([&] { render(q.positions, q.triangles, view, 10, -3); },
                        "picture size 10x-3");
  TriangleMatrix bad = q.triangles;
  bad(1, 2) = 4;
  expectInvalidArgument([&] { render(q.positions, bad, view, 10, 10); },
                        "triangle 1 corner 2 has vertex index 4, outside [0, "
                        "4)");
  bad(1, 2) = -1;
  expectInvalidArgument([&] { render(q.positions, bad, view, 10, 10); },
                        "vertex index -1");
  Matrix3Xf nan = q.positions;
  nan(2, 1) = std::nanf("");
  expectInvalidArgument([&] { render(nan, q.triangles, view, 10, 10); },
                        "vertex 2 has a non-finite position");
  nan(2, 1) = INFINITY;
  expectInvalidArgument([&] { render(nan, q.triangles, view, 10, 10); },
                        "vertex 2 has a non-finite position");
  const std::vector<Rgb> three(3, Rgb{1, 2, 3});
  RenderStyle style;
  style.vertex_colours = &three;
  expectInvalidArgument(
      [&] { render(q.positions, q.triangles, view, 10, 10, style); },
      "3 vertex colours for 4 vertices");
  RenderView broken;
  broken.half_height = 0;
  expectInvalidArgument(
      [&] { render(q.positions, q.triangles, broken, 10, 10); }, "half_height");
  broken = RenderView{};
  broken.direction.setZero();
  expectInvalidArgument(
      [&] { render(q.positions, q.triangles, broken, 10, 10); },
      "view direction");
  broken = RenderView{};
  broken.up = Eigen::Vector3f(0, 0, -2);
  expectInvalidArgument(
      [&] { render(q.positions, q.triangles, broken, 10, 10); },
      "parallel to the view direction");
  broken = RenderView{};
  broken.target.x() = NAN;
  expectInvalidArgument(
      [&] { render(q.positions, q.triangles, broken, 10, 10); }, "view target");

  const Eigen::Vector3f z(0, 0, 1), y(0, 1, 0);
  expectInvalidArgument([&] { (void)samples::frameView(Matrix3Xf(), z, y); },
                        "no positions");
  expectInvalidArgument([&] { (void)samples::frameView(nan, z, y); },
                        "vertex 2 has a non-finite position");
  expectInvalidArgument([&] { (void)samples::frameView(q.positions, z, z); },
                        "parallel");
  expectInvalidArgument(
      [&] { (void)samples::frameView(q.positions, z, y, -0.1f); }, "margin");
  expectInvalidArgument(
      [&] { (void)samples::frameView(q.positions, z, y, 0.05f, 0); }, "aspect");
  expectInvalidArgument(
      [&] {
        (void)samples::frameViews({&q.positions, nullptr}, z, y);
      },
      "mesh 1 is null");

  const std::vector<Image> panels = {Image(10, 8), Image(12, 8)};
  expectInvalidArgument([&] { (void)samples::sideBySide({}, {}); },
                        "no panels");
  expectInvalidArgument([&] { (void)samples::sideBySide(panels, {"a"}); },
                        "1 captions for 2 panels");
  expectInvalidArgument(
      [&] {
        (void)samples::sideBySide({Image(10, 8), Image(10, 9)}, {"a", "b"});
      },
      "panel 1 is 9 pixels high, panel 0 is 8");
  expectInvalidArgument(
      [&] { (void)samples::sideBySide({Image(0, 8)}, {"a"}); },
      "panel 0 (0x8) is empty");
}

}  // namespace
}  // namespace isk
