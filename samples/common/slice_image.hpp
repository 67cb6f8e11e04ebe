// Pictures of a field slice: the palette of Vaillant et al. 2013 (Figure
// 2f, 3c), iso lines, the mesh's section and joint dots, written as PNG.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "slice_plane.hpp"

namespace isk::samples {

using Rgb = std::array<uint8_t, 3>;

// The palette, also used by the tests to classify pixels.
namespace palette {
constexpr Rgb kOutsideSupport = {255, 255, 255};  // f = 0: white
constexpr Rgb kOutsideNear0 = {205, 218, 255};    // f just above 0: pale blue
constexpr Rgb kOutsideNearIso = {25, 60, 205};    // f just below 0.5: blue
constexpr Rgb kInsideNearIso = {255, 155, 135};   // f just above 0.5
constexpr Rgb kInsideDeep = {150, 0, 0};          // f = 1: dark red
constexpr Rgb kIsoLine = {0, 0, 0};               // the 0.5 iso line
constexpr Rgb kMeshSection = {0, 205, 0};         // the mesh cut by the plane
constexpr Rgb kJoint = {255, 215, 0};             // joints projected
}  // namespace palette

struct Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;  // row-major, top row first, 3 bytes a pixel

  Image(int w, int h) : width(w), height(h), rgb(size_t(w) * h * 3, 255) {}
  void set(int x, int y, const Rgb& c);
  Rgb get(int x, int y) const;
};

// Colour of a field value: white outside the support (f <= 0), blue from
// pale to deep as f grows to 0.5, red from light to dark as f grows to 1.
Rgb fieldColour(float f);

// Field values of one picture (width * height, row-major) and what the
// picture shows of them.
struct SliceStats {
  float min = 0, max = 0;
  double inside = 0;   // fraction of pixels with f > 0.5
  double support = 0;  // fraction of pixels with f > 0
};
SliceStats sliceStats(const std::vector<float>& values);

// Paints `values` with fieldColour, darkens faint contours every 0.1 (a
// pixel whose value and a 4-neighbour's straddle k/10), draws the 0.5 iso
// line in black over both pixels that straddle it (2 pixels wide), then the
// mesh section (1 pixel wide, 2 from 768 pixels on) and the joints.
Image renderSlice(const std::vector<float>& values, int width, int height,
                  const std::vector<Segment2>& section,
                  const std::vector<Eigen::Vector2d>& joints);

// PNG bytes of `image` (stb_image_write).
std::string encodePng(const Image& image);

// Writes `image` as PNG to `path` through a temporary file renamed when
// complete (isk::writeTextFile's convention). Throws isk::Error(kIo).
void writePng(const std::string& path, const Image& image);

}  // namespace isk::samples
