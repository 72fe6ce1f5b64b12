// On-disk cache of built BLAS, keyed by a content hash of the geometry and
// of everything that shapes the build (builder version and settings).
//
// A file is <directory>/<key as 16 hex digits>.bvh: a header (magic, format
// version, key, array sizes, payload size and checksum, header checksum)
// followed by the four arrays of a BvhLayouts as raw little-endian PODs; it
// is a machine-local cache, not an interchange format. Nothing read is
// trusted: a file that is truncated, corrupt, from another format version, for
// another key, or structurally invalid (validate_layouts) is rejected and the
// caller rebuilds. Files are written to a temporary name and renamed, so a
// reader never sees a half-written file.
//
// Default directory: $TANDEM_BVH_CACHE if set (the value "off" or "0"
// disables the cache), else $XDG_CACHE_HOME/tandem/bvh, else
// $HOME/.cache/tandem/bvh (relative XDG_CACHE_HOME / HOME are ignored).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "accstruc/bvh_builder.h"
#include "accstruc/bvh_layouts.h"
#include "core/kernel/types.h"

namespace tandem {

// Bump when the file layout changes.
constexpr uint32_t kBvhCacheFormatVersion = 1;
// Bump when the builder or the layouts change the hierarchy they produce for
// the same input (part of the key, so old entries are simply not found).
constexpr uint32_t kBvhBuilderVersion = 2;  // 2: spatial splits

struct BvhCacheSettings {
  bool enabled = true;
  std::string directory;  // empty: default_directory()
  // Meshes below this size build faster than a file is read and checked.
  uint32_t min_triangles = 16384;
};

// The geometry of one mesh as the builder sees it.
struct MeshGeometry {
  const Vec3* positions = nullptr;
  uint32_t vertex_count = 0;
  const KTriangle* triangles = nullptr;  // indices relative to positions
  uint32_t triangle_count = 0;
};

// Key of a mesh's BLAS: positions, triangle indices (not materials), builder
// version and settings.
uint64_t blas_cache_key(const MeshGeometry& mesh, const BuildSettings& settings,
                        uint32_t wide_leaf_prims);

class BvhCache {
 public:
  enum class LoadResult { kHit, kMissing, kRejected };

  // format_version is only overridden by tests (to simulate a newer reader).
  explicit BvhCache(std::filesystem::path directory,
                    uint32_t format_version = kBvhCacheFormatVersion);

  // $TANDEM_BVH_CACHE / $XDG_CACHE_HOME / $HOME as documented above; an
  // empty path when the cache is disabled or no home directory is known.
  static std::filesystem::path default_directory();

  // Reads the BLAS for `key` of a mesh with prim_count triangles. On
  // kRejected, *why says what was wrong with the file.
  LoadResult load(uint64_t key, uint32_t prim_count, BvhLayouts* out,
                  std::string* why = nullptr) const;
  // Writes atomically; returns false (and logs a warning once) on I/O errors.
  bool store(uint64_t key, const BvhLayouts& layouts) const;

  std::filesystem::path path_for(uint64_t key) const;
  const std::filesystem::path& directory() const { return directory_; }

 private:
  std::filesystem::path directory_;
  uint32_t format_version_;
};

}  // namespace tandem
