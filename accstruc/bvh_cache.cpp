#include "accstruc/bvh_cache.h"

#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <vector>

#include "accstruc/content_hash.h"
#include "core/util/log.h"

namespace tandem {

namespace {

constexpr char kMagic[8] = {'T', 'N', 'D', 'M', 'B', 'V', 'H', '\0'};

struct FileHeader {
  char magic[8];
  uint32_t format_version;
  uint32_t header_size;
  uint64_t key;
  uint32_t node_count, prim_count, wide_node_count, wide_prim_count;
  uint32_t depth;
  uint32_t reserved;
  float bounds[6];
  double sah_cost, wide_sah_cost;
  uint64_t payload_size;
  uint64_t payload_checksum;
  uint64_t header_checksum;  // of every byte above
};
static_assert(sizeof(FileHeader) == 112, "cache file header layout");

constexpr uint64_t kChecksumSeed = 0x7461'6e64'656d'4276ull;  // "tandemBv"

uint64_t header_checksum(const FileHeader& h) {
  return content_hash(&h, offsetof(FileHeader, header_checksum), kChecksumSeed);
}

uint64_t payload_bytes(uint64_t nodes, uint64_t prims, uint64_t wide_nodes, uint64_t wide_prims) {
  return nodes * sizeof(KBvhNode) + prims * sizeof(uint32_t) + wide_nodes * sizeof(KWideBvhNode) +
         wide_prims * sizeof(uint32_t);
}

template <class T>
void append_array(std::vector<uint8_t>& buf, const std::vector<T>& v) {
  const size_t at = buf.size();
  buf.resize(at + v.size() * sizeof(T));
  if (!v.empty()) std::memcpy(buf.data() + at, v.data(), v.size() * sizeof(T));
}

template <class T>
const uint8_t* read_array(const uint8_t* p, uint32_t count, std::vector<T>& v) {
  v.resize(count);
  if (count) std::memcpy(v.data(), p, size_t(count) * sizeof(T));
  return p + size_t(count) * sizeof(T);
}

bool set_why(std::string* why, const std::string& reason) {
  if (why) *why = reason;
  return false;
}

}  // namespace

uint64_t blas_cache_key(const MeshGeometry& mesh, const BuildSettings& s,
                        uint32_t wide_leaf_prims) {
  ContentHasher h(0x626c6173ull);  // "blas"
  h.update_value(kBvhBuilderVersion);
  h.update_value(uint32_t(s.method));
  h.update_value(s.bins);
  h.update_value(uint32_t(s.all_axes));
  h.update_value(s.max_leaf_size);
  h.update_value(s.traversal_cost);
  h.update_value(s.intersection_cost);
  h.update_value(s.spatial_split_budget);
  h.update_value(s.spatial_split_alpha);
  h.update_value(wide_leaf_prims);
  h.update_value(mesh.vertex_count);
  h.update_value(mesh.triangle_count);
  if (mesh.vertex_count) h.update(mesh.positions, size_t(mesh.vertex_count) * sizeof(Vec3));
  // Indices only: materials do not shape the hierarchy.
  constexpr uint32_t kChunk = 4096;
  uint32_t idx[3 * kChunk];
  for (uint32_t t0 = 0; t0 < mesh.triangle_count; t0 += kChunk) {
    const uint32_t n = std::min(kChunk, mesh.triangle_count - t0);
    for (uint32_t i = 0; i < n; ++i) {
      const KTriangle& t = mesh.triangles[t0 + i];
      idx[3 * i] = t.v0;
      idx[3 * i + 1] = t.v1;
      idx[3 * i + 2] = t.v2;
    }
    h.update(idx, size_t(n) * 3 * sizeof(uint32_t));
  }
  return h.finish();
}

BvhCache::BvhCache(std::filesystem::path directory, uint32_t format_version)
    : directory_(std::move(directory)), format_version_(format_version) {}

std::filesystem::path BvhCache::default_directory() {
  if (const char* v = std::getenv("TANDEM_BVH_CACHE"); v && *v) {
    const std::string s(v);
    if (s == "off" || s == "0") return {};
    return std::filesystem::path(s);
  }
  // Relative values are ignored, as the XDG base directory spec asks: they
  // would scatter caches over whatever directory tandem runs in (a source
  // tree, say).
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg == '/') {
    return std::filesystem::path(xdg) / "tandem" / "bvh";
  }
  if (const char* home = std::getenv("HOME"); home && *home == '/') {
    return std::filesystem::path(home) / ".cache" / "tandem" / "bvh";
  }
  return {};
}

std::filesystem::path BvhCache::path_for(uint64_t key) const {
  char name[32];
  std::snprintf(name, sizeof name, "%016llx.bvh", static_cast<unsigned long long>(key));
  return directory_ / name;
}

BvhCache::LoadResult BvhCache::load(uint64_t key, uint32_t prim_count, BvhLayouts* out,
                                    std::string* why) const {
  const std::filesystem::path path = path_for(key);
  std::error_code ec;
  const uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) return LoadResult::kMissing;
  auto reject = [&](const std::string& reason) {
    set_why(why, path.string() + ": " + reason);
    return LoadResult::kRejected;
  };
  if (size < sizeof(FileHeader)) return reject("truncated header");
  // A file claiming more than a few GiB cannot be a BLAS we wrote.
  if (size > (uintmax_t(1) << 34)) return reject("implausibly large");
  std::vector<uint8_t> buf(size);
  {
    std::ifstream in(path, std::ios::binary);
    if (!in.read(reinterpret_cast<char*>(buf.data()), std::streamsize(size))) {
      return reject("read error");
    }
  }
  FileHeader h;
  std::memcpy(&h, buf.data(), sizeof h);
  if (std::memcmp(h.magic, kMagic, sizeof kMagic) != 0)
    return reject("not a Tandem BVH cache file");
  if (h.format_version != format_version_) {
    return reject("format version " + std::to_string(h.format_version) + ", expected " +
                  std::to_string(format_version_));
  }
  if (h.header_size != sizeof(FileHeader) || h.header_checksum != header_checksum(h)) {
    return reject("corrupt header");
  }
  if (h.key != key) return reject("written for another mesh");
  const uint64_t expected =
      payload_bytes(h.node_count, h.prim_count, h.wide_node_count, h.wide_prim_count);
  if (h.payload_size != expected || size != sizeof(FileHeader) + expected) {
    return reject("truncated or wrong size");
  }
  const uint8_t* p = buf.data() + sizeof(FileHeader);
  if (content_hash(p, expected, kChecksumSeed) != h.payload_checksum)
    return reject("corrupt payload");
  BvhLayouts l;
  p = read_array(p, h.node_count, l.nodes);
  p = read_array(p, h.prim_count, l.prims);
  p = read_array(p, h.wide_node_count, l.wide_nodes);
  read_array(p, h.wide_prim_count, l.wide_prims);
  l.bounds.lo = {h.bounds[0], h.bounds[1], h.bounds[2]};
  l.bounds.hi = {h.bounds[3], h.bounds[4], h.bounds[5]};
  l.depth = h.depth;
  l.sah_cost = h.sah_cost;
  l.wide_sah_cost = h.wide_sah_cost;
  if (!validate_layouts(l, prim_count) || (!l.empty() && !aabb_valid(l.bounds))) {
    return reject("invalid hierarchy");
  }
  *out = std::move(l);
  return LoadResult::kHit;
}

bool BvhCache::store(uint64_t key, const BvhLayouts& l) const {
  static std::atomic<bool> warned{false};
  auto fail = [&](const std::string& what) {
    if (!warned.exchange(true)) {
      log_warning("BVH cache: cannot write " + directory_.string() + " (" + what +
                  "); continuing without caching");
    }
    return false;
  };
  std::error_code ec;
  std::filesystem::create_directories(directory_, ec);
  if (ec) return fail(ec.message());

  std::vector<uint8_t> buf(sizeof(FileHeader));
  append_array(buf, l.nodes);
  append_array(buf, l.prims);
  append_array(buf, l.wide_nodes);
  append_array(buf, l.wide_prims);
  FileHeader h{};
  std::memcpy(h.magic, kMagic, sizeof kMagic);
  h.format_version = format_version_;
  h.header_size = sizeof(FileHeader);
  h.key = key;
  h.node_count = uint32_t(l.nodes.size());
  h.prim_count = uint32_t(l.prims.size());
  h.wide_node_count = uint32_t(l.wide_nodes.size());
  h.wide_prim_count = uint32_t(l.wide_prims.size());
  h.depth = l.depth;
  const float b[6] = {l.bounds.lo.x, l.bounds.lo.y, l.bounds.lo.z,
                      l.bounds.hi.x, l.bounds.hi.y, l.bounds.hi.z};
  std::memcpy(h.bounds, b, sizeof b);
  h.sah_cost = l.sah_cost;
  h.wide_sah_cost = l.wide_sah_cost;
  h.payload_size = buf.size() - sizeof(FileHeader);
  h.payload_checksum = content_hash(buf.data() + sizeof(FileHeader), h.payload_size, kChecksumSeed);
  h.header_checksum = header_checksum(h);
  std::memcpy(buf.data(), &h, sizeof h);

  // Unique temporary name per process and write, then an atomic rename.
  static std::atomic<uint64_t> counter{0};
  const std::filesystem::path final_path = path_for(key);
  std::filesystem::path tmp = final_path;
  tmp += ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter.fetch_add(1));
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(buf.data()), std::streamsize(buf.size()));
    out.close();
    if (!out) {
      std::filesystem::remove(tmp, ec);
      return fail("write error");
    }
  }
  std::filesystem::rename(tmp, final_path, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    return fail(ec.message());
  }
  return true;
}

}  // namespace tandem
