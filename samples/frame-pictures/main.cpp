// isk-frame-pictures: frames of one pose skinned by several methods (the OBJ
// files isk-skin writes), side by side in one PNG: the whole mesh above, a
// close-up below where the frame of --focus looks worst (its triangle pairs
// that intersect anew against --rest, else its vertex farthest from the
// frame before it). The triangles of new intersecting pairs are orange in
// every panel. quality/run_quality.py draws QUALITY.md's pictures with it.
#include <CLI/CLI.hpp>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "frame_pictures.hpp"
#include "isk/core/error.hpp"
#include "isk/tools/mesh_metrics.hpp"
#include "isk/tools/self_intersection.hpp"
#include "mesh_render.hpp"
#include "slice_image.hpp"

namespace {

namespace fs = std::filesystem;
using isk::samples::Image;
using isk::samples::ObjMesh;
using isk::samples::Rgb;

constexpr Rgb kNewPairColour = {245, 150, 30};

struct Options {
  std::string rest;
  std::string out;
  std::vector<std::string> frames;
  std::vector<std::string> captions;
  std::string title;
  int focus = -1;  // default: the last frame
  int size = 420;
  bool overwrite = false;
};

std::vector<std::pair<int, int>> newPairs(const ObjMesh& frame,
                                          const std::vector<int>& groups,
                                          const ObjMesh& rest) {
  std::vector<std::pair<int, int>> pairs, rest_pairs;
  isk::countSelfIntersections(frame.positions, rest.triangles, &groups, &pairs);
  isk::countSelfIntersections(rest.positions, rest.triangles, &groups,
                              &rest_pairs);
  return isk::newSelfIntersections(pairs, rest_pairs);
}

std::vector<Rgb> pairColours(const ObjMesh& rest,
                             const std::vector<std::pair<int, int>>& pairs) {
  std::vector<Rgb> colours(rest.positions.rows(),
                           isk::samples::RenderStyle{}.front);
  for (const auto& [a, b] : pairs) {
    for (int k = 0; k < 3; ++k) {
      colours[rest.triangles(a, k)] = kNewPairColour;
      colours[rest.triangles(b, k)] = kNewPairColour;
    }
  }
  return colours;
}

void checkTargets(const Options& options) {
  if (options.frames.empty()) {
    throw isk::Error(isk::ErrorCode::kInvalidArgument, "no --frame given");
  }
  if (!options.captions.empty() &&
      options.captions.size() != options.frames.size()) {
    throw isk::Error(isk::ErrorCode::kInvalidArgument,
                     std::to_string(options.captions.size()) +
                         " --caption for " +
                         std::to_string(options.frames.size()) +
                         " --frame: give one a frame, or none");
  }
  if (options.focus >= static_cast<int>(options.frames.size())) {
    throw isk::Error(isk::ErrorCode::kInvalidArgument,
                     "--focus " + std::to_string(options.focus) +
                         ": there are " +
                         std::to_string(options.frames.size()) + " frames");
  }
  std::error_code ec;
  for (const std::string& input : options.frames) {
    if (fs::equivalent(input, options.out, ec)) {
      throw isk::Error(isk::ErrorCode::kIo,
                       options.out +
                           ": is an input frame; choose another "
                           "--out");
    }
  }
  if (fs::exists(options.out, ec) && !options.overwrite) {
    throw isk::Error(isk::ErrorCode::kIo,
                     options.out + ": exists; pass --overwrite to replace it");
  }
}

int run(const Options& options) {
  checkTargets(options);
  const ObjMesh rest = isk::samples::readObjMesh(options.rest);
  const std::vector<int> groups = isk::coincidentVertexGroups(rest.positions);
  std::vector<ObjMesh> frames;
  std::vector<std::vector<std::pair<int, int>>> pairs;
  for (const std::string& path : options.frames) {
    frames.push_back(isk::samples::readObjMesh(path));
    if (frames.back().positions.rows() != rest.positions.rows() ||
        frames.back().triangles != rest.triangles) {
      throw isk::Error(isk::ErrorCode::kInvalidArgument,
                       path + ": not a frame of " + options.rest +
                           " (other vertex count or triangles)");
    }
    pairs.push_back(newPairs(frames.back(), groups, rest));
  }
  const int focus =
      options.focus >= 0 ? options.focus : static_cast<int>(frames.size()) - 1;
  const isk::Matrix3Xf* reference =
      focus > 0 ? &frames[focus - 1].positions : nullptr;
  const float diagonal = isk::boundingBoxDiagonal(rest.positions);
  const isk::samples::FocusView close = isk::samples::worstPlaceView(
      frames[focus], pairs[focus], reference, diagonal);

  std::vector<const isk::Matrix3Xf*> all;
  for (const ObjMesh& frame : frames) all.push_back(&frame.positions);
  const isk::samples::RenderView whole =
      isk::samples::frameViews(all, close.view.direction, close.view.up, 0.06f);
  std::vector<Image> whole_panels, close_panels;
  std::vector<std::string> captions;
  for (size_t i = 0; i < frames.size(); ++i) {
    const std::vector<Rgb> colours = pairColours(rest, pairs[i]);
    isk::samples::RenderStyle style;
    style.vertex_colours = &colours;
    const int small = options.size * 3 / 4;
    whole_panels.push_back(isk::samples::renderMesh(
        frames[i].positions, rest.triangles, whole, small, small, style));
    close_panels.push_back(isk::samples::renderMesh(
        frames[i].positions, rest.triangles, close.view, options.size,
        options.size, style));
    captions.push_back(
        (options.captions.empty() ? fs::path(options.frames[i]).stem().string()
                                  : options.captions[i]) +
        "\n" + std::to_string(pairs[i].size()) + " new pairs (orange)");
  }
  const Image picture = isk::samples::stackVertically(
      {isk::samples::sideBySide(whole_panels, captions, options.title),
       isk::samples::sideBySide(close_panels,
                                std::vector<std::string>(frames.size(), ""),
                                "close-up: " + close.reason)});
  isk::samples::writePng(options.out, picture);
  std::cerr << "isk-frame-pictures: wrote " << options.out << " ("
            << close.reason << ")\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  CLI::App app{
      "Pictures frames of one pose skinned by several methods side by side, "
      "whole and close up where the --focus frame looks worst."};
  app.add_option("--rest", options.rest,
                 "the rest pose as OBJ (isk-skin --clip rest)")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--out", options.out, "the PNG to write")->required();
  app.add_option("--frame", options.frames,
                 "a frame as OBJ (isk-skin --out), one per panel, in order")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--caption", options.captions,
                 "a caption per --frame, in the same order");
  app.add_option("--title", options.title, "a title line above the panels");
  app.add_option("--focus", options.focus,
                 "index of the frame whose worst place the close-up shows "
                 "(default: the last)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--size", options.size, "close-up panel size in pixels")
      ->check(CLI::Range(64, 4096));
  app.add_flag("--overwrite", options.overwrite, "replace --out if it exists");
  CLI11_PARSE(app, argc, argv);
  try {
    return run(options);
  } catch (const std::exception& error) {
    std::cerr << "isk-frame-pictures: error: " << error.what() << "\n";
  }
  return 1;
}
