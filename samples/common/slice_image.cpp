#include "slice_image.hpp"

#include <algorithm>
#include <cmath>

#include "isk/core/error.hpp"
#include "isk/io/export.hpp"

// The one translation unit holding stb_image_write's implementation, kept
// static so it never clashes with another copy.
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_WRITE_STATIC
#include <stb/stb_image_write.h>

namespace isk::samples {
namespace {

Rgb mix(const Rgb& a, const Rgb& b, float t) {
  t = std::clamp(t, 0.f, 1.f);
  Rgb out;
  for (int c = 0; c < 3; ++c) {
    out[c] = static_cast<uint8_t>(std::lround((1 - t) * a[c] + t * b[c]));
  }
  return out;
}

Rgb darken(const Rgb& c, float factor) {
  return {static_cast<uint8_t>(c[0] * factor),
          static_cast<uint8_t>(c[1] * factor),
          static_cast<uint8_t>(c[2] * factor)};
}

// True when a and b lie on different sides of `level` (level counts as
// below: f > level is inside).
bool straddles(float a, float b, float level) {
  return (a > level) != (b > level);
}

void plot(Image& image, int x, int y, const Rgb& c) {
  if (x >= 0 && y >= 0 && x < image.width && y < image.height) {
    image.set(x, y, c);
  }
}

// A line `width` pixels wide (1 or 2: a second pixel below or right).
void drawSegment(Image& image, const Segment2& s, int width, const Rgb& c) {
  const Eigen::Vector2d d = s.b - s.a;
  const int steps = static_cast<int>(std::ceil(d.cwiseAbs().maxCoeff())) + 1;
  const bool steep = std::abs(d.y()) > std::abs(d.x());
  for (int i = 0; i <= steps; ++i) {
    const Eigen::Vector2d p = s.a + d * (static_cast<double>(i) / steps);
    const int x = static_cast<int>(std::floor(p.x()));
    const int y = static_cast<int>(std::floor(p.y()));
    plot(image, x, y, c);
    if (width > 1) plot(image, steep ? x + 1 : x, steep ? y : y + 1, c);
  }
}

void drawDot(Image& image, const Eigen::Vector2d& centre, double radius,
             const Rgb& c) {
  const int x0 = static_cast<int>(std::floor(centre.x() - radius));
  const int x1 = static_cast<int>(std::ceil(centre.x() + radius));
  const int y0 = static_cast<int>(std::floor(centre.y() - radius));
  const int y1 = static_cast<int>(std::ceil(centre.y() + radius));
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      if ((Eigen::Vector2d(x + 0.5, y + 0.5) - centre).norm() <= radius) {
        plot(image, x, y, c);
      }
    }
  }
}

void appendBytes(void* context, void* data, int size) {
  static_cast<std::string*>(context)->append(static_cast<const char*>(data),
                                             static_cast<size_t>(size));
}

}  // namespace

void Image::set(int x, int y, const Rgb& c) {
  uint8_t* p = &rgb[(static_cast<size_t>(y) * width + x) * 3];
  p[0] = c[0];
  p[1] = c[1];
  p[2] = c[2];
}

Rgb Image::get(int x, int y) const {
  const uint8_t* p = &rgb[(static_cast<size_t>(y) * width + x) * 3];
  return {p[0], p[1], p[2]};
}

Rgb fieldColour(float f) {
  if (!(f > 0)) return palette::kOutsideSupport;
  if (f <= 0.5f) {
    return mix(palette::kOutsideNear0, palette::kOutsideNearIso,
               std::pow(f / 0.5f, 0.8f));
  }
  return mix(palette::kInsideNearIso, palette::kInsideDeep, (f - 0.5f) / 0.5f);
}

SliceStats sliceStats(const std::vector<float>& values) {
  SliceStats s;
  if (values.empty()) return s;
  s.min = *std::min_element(values.begin(), values.end());
  s.max = *std::max_element(values.begin(), values.end());
  size_t inside = 0, support = 0;
  for (float f : values) {
    inside += f > 0.5f;
    support += f > 0.f;
  }
  s.inside = static_cast<double>(inside) / values.size();
  s.support = static_cast<double>(support) / values.size();
  return s;
}

Image renderSlice(const std::vector<float>& values, int width, int height,
                  const std::vector<Segment2>& section,
                  const std::vector<Eigen::Vector2d>& joints) {
  Image image(width, height);
  auto at = [&](int x, int y) { return values[size_t(y) * width + x]; };
  // Whether (x, y) and one of its 4-neighbours straddle `level`.
  auto onLevel = [&](int x, int y, float level) {
    const float f = at(x, y);
    return (x > 0 && straddles(f, at(x - 1, y), level)) ||
           (x + 1 < width && straddles(f, at(x + 1, y), level)) ||
           (y > 0 && straddles(f, at(x, y - 1), level)) ||
           (y + 1 < height && straddles(f, at(x, y + 1), level));
  };
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      Rgb c = fieldColour(at(x, y));
      if (onLevel(x, y, 0.5f)) {
        c = palette::kIsoLine;
      } else {
        for (int k = 1; k < 10; ++k) {
          if (k != 5 && onLevel(x, y, 0.1f * k)) {
            c = darken(c, 0.8f);
            break;
          }
        }
      }
      image.set(x, y, c);
    }
  }
  const int longest = std::max(width, height);
  const int line_width = longest >= 768 ? 2 : 1;
  for (const Segment2& s : section) {
    drawSegment(image, s, line_width, palette::kMeshSection);
  }
  const double radius = std::max(2.0, longest / 180.0);
  for (const Eigen::Vector2d& j : joints) {
    drawDot(image, j, radius, palette::kJoint);
  }
  return image;
}

std::string encodePng(const Image& image) {
  std::string bytes;
  if (!stbi_write_png_to_func(appendBytes, &bytes, image.width, image.height, 3,
                              image.rgb.data(), image.width * 3)) {
    throw Error(ErrorCode::kInternal, "PNG encoding failed");
  }
  return bytes;
}

void writePng(const std::string& path, const Image& image) {
  writeTextFile(path, encodePng(image));
}

}  // namespace isk::samples
