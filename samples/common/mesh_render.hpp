// A small software rasterizer for the samples: a triangle mesh seen through
// an orthographic camera, flat-shaded with a z-buffer, and panels of such
// pictures side by side with captions (stb_easy_font), so the demo can show a
// character deformed by several skinning methods at one pose.
//
// What the colours of renderMesh mean:
//  - background (RenderStyle::background, light grey): no triangle there;
//  - front (light grey-blue, shaded): skin seen from outside, darker where it
//    turns away from the light, so folds show as bands of different shade;
//  - back (red, shaded): skin seen from inside, i.e. a triangle turned
//    inside out or skin pushed through other skin so its inner side faces
//    the viewer;
//  - vertex_colours, when given: the per-vertex colour replaces `front`
//    (interpolated across each triangle, shaded the same way), e.g. to mark
//    contact vertices; back faces stay `back`;
//  - dark outlines (RenderStyle::outlines): silhouettes and places where one
//    part of the skin lies in front of another (a fold over skin), found as
//    depth jumps in the z-buffer, and creases where neighbouring pixels show
//    faces turned more than ~50 degrees apart (a sharp fold, skin pressed
//    against skin, skin passing through skin);
//  - darkened triangle edges (RenderStyle::edges): the wireframe overlay.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "isk/core/types.hpp"
#include "slice_image.hpp"

namespace isk::samples {

// Orthographic camera.
struct RenderView {
  // Model point at the picture's centre.
  Eigen::Vector3f target = Eigen::Vector3f::Zero();
  // From the target towards the viewer (made unit when rendering).
  Eigen::Vector3f direction = Eigen::Vector3f(0, 0, 1);
  // Model direction shown upwards (its part along `direction` is ignored).
  Eigen::Vector3f up = Eigen::Vector3f(0, 1, 0);
  float half_height = 1;  // model units visible above the centre
};

// A view that frames all `positions` (#V by 3), seen from `direction` with
// `up`: the target is the centre of their projected bounding rectangle and
// half_height leaves `margin` (a fraction of the half extent) around them in
// a picture of `aspect` = width / height. Throws isk::Error
// (kInvalidArgument) for no positions, non-finite positions, a zero
// direction, an `up` parallel to it, a negative margin or aspect <= 0.
RenderView frameView(const Matrix3Xf& positions,
                     const Eigen::Vector3f& direction,
                     const Eigen::Vector3f& up, float margin = 0.05f,
                     float aspect = 1.f);

// Same, framing several meshes at once (so side-by-side panels share one
// scale). Null entries are rejected; empty meshes are skipped, but at least
// one vertex must remain.
RenderView frameViews(const std::vector<const Matrix3Xf*>& meshes,
                      const Eigen::Vector3f& direction,
                      const Eigen::Vector3f& up, float margin = 0.05f,
                      float aspect = 1.f);

// The colours of renderMesh; see the top of this file for their meaning.
struct RenderStyle {
  Rgb front = {200, 200, 205};  // front faces (lit)
  Rgb back = {200, 40, 40};     // back faces: skin seen from inside (pushed
                                // through other skin)
  bool edges = false;           // darken triangle edges (wireframe overlay)
  // Optional per-vertex colour of front faces (e.g. contact vertices), one
  // per vertex.
  const std::vector<Rgb>* vertex_colours = nullptr;
  Rgb background = {236, 236, 240};  // pixels no triangle covers
  bool outlines = true;  // darken silhouettes, depth jumps and creases
};

// Renders the triangles (#F by 3, counter-clockwise seen from outside) with a
// z-buffer and Lambert shading from a light near the viewer (plus ambient);
// flat shading by face normal shows folds crisply. Pixels not covered keep
// style.background. Pixel (x, y) samples the point at its centre; a triangle
// covers the pixels whose centres lie inside it or on its edges. Throws
// isk::Error (kInvalidArgument) naming the problem for a picture size outside
// 1..16384, non-finite positions, a triangle index out of range, vertex
// colours of the wrong count, or a bad view (non-finite, zero direction, up
// parallel to direction, half_height <= 0).
Image renderMesh(const Matrix3Xf& positions, const TriangleMatrix& triangles,
                 const RenderView& view, int width, int height,
                 const RenderStyle& style = {});

// Gap in pixels between neighbouring panels of sideBySide.
constexpr int kPanelGap = 8;
// Text of sideBySide is stb_easy_font scaled by this (12-pixel lines become
// 24 pixels).
constexpr int kTextScale = 2;

// Panels side by side on white, left to right with kPanelGap between them
// (width = sum of panel widths + kPanelGap * (count - 1)), each with its
// caption drawn in dark grey centred above it (clipped to the panel's
// width), and an optional title line centred above everything. Captions and
// the title may hold several lines ('\n'); characters outside printable ASCII
// print as '?'. Throws isk::Error (kInvalidArgument) for no panels, a caption
// count different from the panel count, empty panels or panels of different
// heights.
Image sideBySide(const std::vector<Image>& panels,
                 const std::vector<std::string>& captions,
                 const std::string& title = "");

}  // namespace isk::samples
