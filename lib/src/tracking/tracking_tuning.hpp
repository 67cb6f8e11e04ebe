// The tracking's speed-only switches, kept out of the public API: the same
// frames whichever way they are set (the tests compare them bit for bit);
// the benchmarks switch each off to measure what it buys
// (docs/performance.md). SurfaceTrackingOptions::tuning holds them.
#pragma once

#include <memory>

#include "isk/tracking/surface_tracking.hpp"

namespace isk::detail {

struct TrackingTuning {
  // Sample a vertex's home field neighbourhood instead of every field while
  // it is in its home field's box (FieldNeighbourhoods).
  bool field_neighbourhoods = true;
  // OpenCL: march the vertices in TrackingMesh::march_order rather than by
  // index.
  bool march_order = true;
  // OpenCL: skip the grid loads of cells that are zero at all 8 nodes
  // (occupiedCells).
  bool occupied_cells = true;
  // OpenCL, projection: skip the fields whose value bound in the cell shows
  // they can change nothing at the point (cellValueBounds: below the home
  // field's value and the best so far).
  bool value_bounds = true;
  // OpenCL, projection, with value_bounds: a blend or bulge pair one of
  // whose fields value_bounds skipped is not composed where its operator's
  // bound over the two fields' values (or bounds) does not exceed the
  // composed value so far (the operator table's bound nodes,
  // field_evaluation.cpp), instead of sampling that field again.
  bool pair_bounds = true;
  // OpenCL, with field_neighbourhoods: each home field's box cut into this
  // many cells per axis, a vertex sampling only the fields that can be
  // non-zero in its cell (splitNeighbourhoodsIntoCells); 1: the whole box;
  // 0: the device's choice (detail::neighbourhoodCellsPerAxis). 0..16.
  int neighbourhood_cells = 0;
  // OpenCL on a CPU device, with field_neighbourhoods: the projection tests
  // the fields listed in a vertex's cell (their bounding spheres and grid
  // boxes) eight at a time, in float8 lanes over each home field's
  // neighbourhood, rather than one by one; other devices keep the loop (a
  // GPU runs vector types lane by lane).
  bool lane_tests = true;
  // OpenCL: the relaxation launches skip the stopped vertices, the diffusion
  // and Laplacian launches the vertices out of reach of every contact and
  // crease vertex (each step pushes its reach to the vertices whose rows
  // list it), instead of copying them.
  bool active_vertices = true;
};

// The options' switches, or the defaults when they hold none.
inline const TrackingTuning& tuningOf(const SurfaceTrackingOptions& options) {
  static const TrackingTuning defaults;
  return options.tuning ? *options.tuning : defaults;
}

// A copy of `options` whose switches are `tuning`.
inline SurfaceTrackingOptions withTuning(SurfaceTrackingOptions options,
                                         const TrackingTuning& tuning) {
  options.tuning = std::make_shared<const TrackingTuning>(tuning);
  return options;
}

}  // namespace isk::detail
