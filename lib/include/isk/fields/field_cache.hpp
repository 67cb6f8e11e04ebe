// On-disk cache of a character's built implicit fields (the expensive part
// of isk::buildImplicitFields: Poisson-disk samples, HRBF fits and the baked
// N^3 grids), so that a second start skips them. The composition (operator
// tables come from their own cache) and the per-vertex iso values are
// recomputed from the loaded grids on every build: they depend on the
// operators, which a user tunes, and cost a few milliseconds.
//
// Folder: the operator tables' (operatorTableCacheFolder(): $ISK_CACHE_DIR,
// "off" disabling every cache, else $XDG_CACHE_HOME/isk or ~/.cache/isk) or
// ImplicitFieldsOptions::cache_folder. One file per rig source and build
// parameters: "fields-v<format>-<hash of Rig::source>-<hash of the
// parameters>.bin". A file starts with a 64-byte header (magic, format
// version, byte order, hashes of the mesh (positions, normals, triangles),
// of the skin weights, of the skeleton (names, parents, rest locals, inverse
// binds), of the build parameters (sampling options, per-joint sample
// counts, grid resolution, a build version bumped whenever the fitting or
// baking changes), payload size and a checksum of the payload). A file
// whose mesh, weights or skeleton hash differs from the rig's is stale: it
// is reported (ImplicitFields::cache_note and a warning naming what
// changed), rebuilt and replaced, never used. A file that fails its size,
// header, checksum or payload checks is reported as corrupt and rebuilt.
// Files are written to a temporary file beside the target and renamed (the
// same atomic write as the operator tables'), so a reader never sees a
// partial file. The cache never makes a build fail.
#pragma once

#include <string>

#include "isk/fields/implicit_fields.hpp"
#include "isk/rig/rig.hpp"

namespace isk {

// The cache file's name (no folder) of `rig` built with `options`.
std::string fieldCacheFileName(const Rig& rig,
                               const ImplicitFieldsOptions& options);

// Writes the samples, fits, grids and their warnings of `fields` (built
// from `rig` with `options`) to `path` atomically. False with *error on
// failure; never throws for I/O.
bool saveFieldCache(const ImplicitFields& fields, const Rig& rig,
                    const ImplicitFieldsOptions& options,
                    const std::string& path, std::string* error = nullptr);

// Reads `path` into fields->samples, fields, grids and warnings after
// checking it against `rig` and `options`. False with *error (missing,
// stale: "the mesh changed", "the skin weights changed", ...; corrupt);
// *stale tells a stale file from a corrupt one. Never throws for I/O.
bool loadFieldCache(const std::string& path, const Rig& rig,
                    const ImplicitFieldsOptions& options,
                    ImplicitFields* fields, std::string* error = nullptr,
                    bool* stale = nullptr);

}  // namespace isk
