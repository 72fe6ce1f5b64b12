// The on-disk BLAS cache (accstruc/bvh_cache.h): a second run loads what the
// first one stored and gets the very same hierarchy; every kind of bad file
// (truncated, flipped bytes, another format version, another mesh's file) is
// rejected and rebuilt, after which hits still match Embree; and the default
// location is the user's cache directory, never the source tree.
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>

#include "accstruc_test_util.h"
#include "scenes/procedural_scenes.h"
#include "tests/test_temp_dir.h"

namespace tandem {
namespace {

using namespace accstruc_test;
namespace fs = std::filesystem;

// Sets (or unsets, with nullptr) an environment variable for one scope.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    if (value)
      ::setenv(name, value, 1);
    else
      ::unsetenv(name);
  }
  ~ScopedEnv() {
    if (old_)
      ::setenv(name_, old_->c_str(), 1);
    else
      ::unsetenv(name_);
  }

 private:
  const char* name_;
  std::optional<std::string> old_;
};

AccelSettings cache_settings(const fs::path& dir) {
  AccelSettings s;
  s.cache.enabled = true;
  s.cache.directory = dir.string();
  s.cache.min_triangles = 1;  // cache every mesh, however small
  return s;
}

// A full build of the traced scene's meshes by a fresh AccelStructure using
// the cache in `dir`, on a copy of the kernel arrays.
struct CachedBuild {
  KernelScene ks;
  AccelStructure accel;
  AccelUpdate up;
  CachedBuild(const KernelScene& from, const fs::path& dir) : ks(from), accel(cache_settings(dir)) {
    SceneDelta full;
    full.full = true;
    up = accel.update(ks, full);
  }
  KernelData kd() const { return ks.view(); }
};

// Hits of a cached build against Embree, in both layouts.
void expect_hits_match_embree(const TracedScene& s, const CachedBuild& b, const char* what) {
  const KernelData kd = b.kd();
  const DistanceTolerance tol = distance_tolerance(s.bounds);
  const auto rays = primary_rays(s, 3000, 41);
  for (uint32_t layout = 0; layout < 2; ++layout) {
    const Agreement a = compare_closest(
        kd, tol, rays,
        [&](const RaySample& r) { return bvh_intersect(kd, r.ray, r.alpha_key, layout); },
        [&](const RaySample& r) { return s.embree.intersect(r.ray, r.alpha_key); });
    EXPECT_GE(a.fraction(), 0.999) << what << " " << layout_name(layout) << ": " << a.summary();
    EXPECT_GT(a.hits, 300u) << what;
  }
}

std::vector<fs::path> cache_files(const fs::path& dir) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir))
    files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

std::vector<char> read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_file(const fs::path& p, const std::vector<char>& bytes) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), std::streamsize(bytes.size()));
}

// The file layout of bvh_cache.cpp's FileHeader: its size and where the
// binary tree's SAH cost sits (after magic, version, size, key, four counts,
// depth, reserved and six floats of bounds).
constexpr size_t kHeaderSize = 112;
constexpr size_t kSahOffset = 72;

// A few meshes (grass tufts, rocks, towers, cards) of a few thousand
// triangles each: quick to build, every one cached.
TracedScene& shared_scene() {
  static TracedScene s(make_procedural_scene(20000, 29));
  return s;
}

TEST(BvhCache, SecondRunLoadsTheSameHierarchy) {
  TempDir dir("tandem_bvh_cache");
  const TracedScene& s = shared_scene();
  const uint32_t meshes = uint32_t(s.ks.meshes.size());
  ASSERT_GE(meshes, 2u);

  CachedBuild first(s.ks, dir.path());
  EXPECT_EQ(first.up.blas_built, meshes);
  EXPECT_EQ(first.up.blas_loaded, 0u);
  // One file per distinct mesh geometry, and no temporary left behind.
  const auto files = cache_files(dir.path());
  EXPECT_GE(files.size(), 1u);
  EXPECT_LE(files.size(), meshes);
  for (const fs::path& f : files)
    EXPECT_EQ(f.extension(), ".bvh") << f;

  CachedBuild second(s.ks, dir.path());
  EXPECT_EQ(second.up.blas_loaded, meshes);
  EXPECT_EQ(second.up.blas_built, 0u);
  EXPECT_TRUE(same_bytes(first.ks.bvh_nodes, second.ks.bvh_nodes));
  EXPECT_TRUE(same_bytes(first.ks.bvh_prim_indices, second.ks.bvh_prim_indices));
  EXPECT_TRUE(same_bytes(first.ks.bvh_wide_nodes, second.ks.bvh_wide_nodes));
  EXPECT_TRUE(same_bytes(first.ks.bvh_wide_prim_indices, second.ks.bvh_wide_prim_indices));
  for (uint32_t m = 0; m < meshes; ++m) {
    EXPECT_EQ(first.accel.blas(m).sah_cost, second.accel.blas(m).sah_cost);
    EXPECT_EQ(first.accel.blas(m).depth, second.accel.blas(m).depth);
  }
  expect_hits_match_embree(s, second, "loaded from cache");

  // Below min_triangles nothing is read or written.
  TempDir empty("tandem_bvh_cache_empty");
  AccelSettings big = cache_settings(empty.path());
  big.cache.min_triangles = 1u << 30;
  AccelStructure small(big);
  KernelScene ks = s.ks;
  SceneDelta full;
  full.full = true;
  EXPECT_EQ(small.update(ks, full).blas_loaded, 0u);
  EXPECT_TRUE(cache_files(empty.path()).empty());
}

// Every damaged variant of every file is rejected (load() says why), the
// BLAS is rebuilt with correct hits, and the rebuilt file replaces it.
TEST(BvhCache, BadFilesAreRejectedAndRebuilt) {
  TempDir dir("tandem_bvh_cache");
  const TracedScene& s = shared_scene();
  const uint32_t meshes = uint32_t(s.ks.meshes.size());
  { CachedBuild seed(s.ks, dir.path()); }
  const auto files = cache_files(dir.path());
  ASSERT_GE(files.size(), 2u);
  std::vector<std::vector<char>> good;
  for (const fs::path& f : files)
    good.push_back(read_file(f));

  struct Damage {
    const char* name;
    const char* why;  // expected in load()'s reason
    std::function<std::vector<char>(size_t file)> bytes;
  };
  const std::vector<Damage> damages = {
      {"truncated payload", "size",
       [&](size_t f) { return std::vector<char>(good[f].begin(), good[f].end() - 7); }},
      {"truncated header", "truncated",
       [&](size_t f) { return std::vector<char>(good[f].begin(), good[f].begin() + 40); }},
      {"empty", "truncated", [&](size_t) { return std::vector<char>(); }},
      {"flipped payload byte", "corrupt payload",
       [&](size_t f) {
         auto b = good[f];
         b[kHeaderSize + (b.size() - kHeaderSize) / 2] ^= 0x10;
         return b;
       }},
      {"flipped header byte", "corrupt header",
       [&](size_t f) {
         auto b = good[f];
         b[20] ^= 0x01;  // inside the key
         return b;
       }},
      {"not a cache file", "not a Tandem",
       [&](size_t f) {
         auto b = good[f];
         b[0] = 'X';
         return b;
       }},
      // Another mesh's (valid) file under this mesh's name: a stale entry.
      {"another mesh's file", "another mesh",
       [&](size_t f) { return good[(f + 1) % good.size()]; }},
  };
  for (const Damage& d : damages) {
    SCOPED_TRACE(d.name);
    for (size_t f = 0; f < files.size(); ++f)
      write_file(files[f], d.bytes(f));
    // What load() says about the first file.
    const BvhCache cache(dir.path());
    const uint64_t key = std::stoull(files[0].stem().string(), nullptr, 16);
    BvhLayouts out;
    std::string why;
    EXPECT_EQ(cache.load(key, 1u << 30, &out, &why), BvhCache::LoadResult::kRejected);
    EXPECT_NE(why.find(d.why), std::string::npos) << why;
    EXPECT_NE(why.find(files[0].filename().string()), std::string::npos) << why;

    CachedBuild rebuilt(s.ks, dir.path());
    EXPECT_EQ(rebuilt.up.blas_loaded, 0u);
    EXPECT_EQ(rebuilt.up.blas_built, meshes);
    expect_hits_match_embree(s, rebuilt, d.name);
    // The rebuild stored the same hierarchy again. Only the header's SAH
    // costs (and so its checksum) may differ, in the last bits: sah_cost()
    // sums over the build's node storage order, which the parallel build
    // does not fix.
    for (size_t f = 0; f < files.size(); ++f) {
      const std::vector<char> now = read_file(files[f]);
      ASSERT_EQ(now.size(), good[f].size()) << files[f];
      EXPECT_TRUE(std::equal(now.begin(), now.begin() + kSahOffset, good[f].begin())) << files[f];
      EXPECT_TRUE(std::equal(now.begin() + kHeaderSize, now.end(), good[f].begin() + kHeaderSize))
          << files[f];
      double sah_now, sah_good;
      std::memcpy(&sah_now, now.data() + kSahOffset, sizeof(double));
      std::memcpy(&sah_good, good[f].data() + kSahOffset, sizeof(double));
      EXPECT_NEAR(sah_now, sah_good, 1e-12 * sah_good) << files[f];
    }
  }
}

// A reader of another format version rejects our files (and ours theirs).
TEST(BvhCache, OtherFormatVersionIsRejected) {
  TempDir dir("tandem_bvh_cache");
  const TracedScene& s = shared_scene();
  { CachedBuild seed(s.ks, dir.path()); }
  const auto files = cache_files(dir.path());
  ASSERT_FALSE(files.empty());
  const uint64_t key = std::stoull(files[0].stem().string(), nullptr, 16);
  BvhLayouts out;
  std::string why;
  const BvhCache newer(dir.path(), kBvhCacheFormatVersion + 1);
  EXPECT_EQ(newer.load(key, 1u << 30, &out, &why), BvhCache::LoadResult::kRejected);
  EXPECT_NE(why.find("format version"), std::string::npos) << why;
  EXPECT_EQ(BvhCache(dir.path()).load(key, 1u << 30, &out), BvhCache::LoadResult::kHit);

  // Files a newer version wrote are rebuilt by this one.
  for (const fs::path& f : files) {
    BvhLayouts l;
    const uint64_t k = std::stoull(f.stem().string(), nullptr, 16);
    ASSERT_EQ(BvhCache(dir.path()).load(k, 1u << 30, &l), BvhCache::LoadResult::kHit);
    ASSERT_TRUE(newer.store(k, l));
  }
  CachedBuild rebuilt(s.ks, dir.path());
  EXPECT_EQ(rebuilt.up.blas_loaded, 0u);
  EXPECT_EQ(rebuilt.up.blas_built, uint32_t(s.ks.meshes.size()));
  expect_hits_match_embree(s, rebuilt, "after a newer version's files");
}

// Editing a mesh changes its key: the old entry is not used for the new
// geometry (the stale file stays, harmlessly, under its old name).
TEST(BvhCache, EditedMeshGetsANewKey) {
  const TracedScene& s = shared_scene();
  const MeshGeometry g = mesh_geometry(s.ks, 0);
  const BuildSettings bs;
  const uint64_t key = blas_cache_key(g, bs, 3);
  std::vector<Vec3> moved(g.positions, g.positions + g.vertex_count);
  moved[g.vertex_count / 2].y = std::nextafter(moved[g.vertex_count / 2].y, 1e30f);
  MeshGeometry edited = g;
  edited.positions = moved.data();
  EXPECT_NE(blas_cache_key(edited, bs, 3), key);
  BuildSettings other = bs;
  other.bins = bs.bins + 1;
  EXPECT_NE(blas_cache_key(g, other, 3), key);
  EXPECT_NE(blas_cache_key(g, bs, 1), key);
  EXPECT_EQ(blas_cache_key(g, bs, 3), key);
}

// The default directory is per user, can be turned off, and tests' own
// settings never point into the source tree.
TEST(BvhCache, DefaultDirectoryIsTheUserCache) {
  {
    ScopedEnv a("TANDEM_BVH_CACHE", nullptr), b("XDG_CACHE_HOME", "/tmp/xdg"), c("HOME", "/h");
    EXPECT_EQ(BvhCache::default_directory(), fs::path("/tmp/xdg/tandem/bvh"));
  }
  {
    ScopedEnv a("TANDEM_BVH_CACHE", nullptr), b("XDG_CACHE_HOME", nullptr), c("HOME", "/h");
    EXPECT_EQ(BvhCache::default_directory(), fs::path("/h/.cache/tandem/bvh"));
  }
  {
    ScopedEnv a("TANDEM_BVH_CACHE", "/tmp/mine"), b("HOME", "/h");
    EXPECT_EQ(BvhCache::default_directory(), fs::path("/tmp/mine"));
  }
  for (const char* off : {"off", "0"}) {
    ScopedEnv a("TANDEM_BVH_CACHE", off), b("HOME", "/h");
    EXPECT_TRUE(BvhCache::default_directory().empty());
    EXPECT_EQ(AccelStructure(AccelSettings{}).cache(), nullptr);
  }
  {
    ScopedEnv a("TANDEM_BVH_CACHE", nullptr), b("XDG_CACHE_HOME", nullptr), c("HOME", nullptr);
    EXPECT_TRUE(BvhCache::default_directory().empty());  // nowhere safe to write
  }
  {
    // Relative XDG/HOME paths are invalid (XDG base directory spec): they
    // would put the cache under whatever directory tandem runs in.
    ScopedEnv a("TANDEM_BVH_CACHE", nullptr), b("XDG_CACHE_HOME", "cache"), c("HOME", "/h");
    EXPECT_EQ(BvhCache::default_directory(), fs::path("/h/.cache/tandem/bvh"));
    ScopedEnv d("HOME", "home");
    EXPECT_TRUE(BvhCache::default_directory().empty());
  }
  EXPECT_EQ(AccelStructure(test_settings()).cache(), nullptr);
  // Whatever this environment says, the default is not inside the sources.
  const fs::path dir = BvhCache::default_directory();
  if (!dir.empty()) {
    const std::string src = fs::weakly_canonical(TANDEM_SOURCE_DIR).string();
    EXPECT_NE(fs::weakly_canonical(dir).string().rfind(src, 0), 0u) << dir;
  }
}

}  // namespace
}  // namespace tandem
