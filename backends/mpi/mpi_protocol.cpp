#include "backends/mpi/mpi_protocol.h"

#include <algorithm>

namespace tandem::mpi {

namespace {

constexpr uint32_t kEndOfArrays = 0xffffffffu;
enum ArrayEncoding : uint8_t { kWhole = 1, kRange = 2 };

template <class T>
void encode_array(WireWriter& w, uint32_t id, const std::vector<T>& v, const ArrayChange& c,
                  bool full, uint32_t& receiver_count) {
  const uint32_t n = uint32_t(v.size());
  if (full || c.reallocated || n != receiver_count) {
    w.put(id);
    w.put(uint8_t(kWhole));
    w.put(n);
    w.put_bytes(v.data(), size_t(n) * sizeof(T));
    receiver_count = n;
    return;
  }
  const uint32_t end = std::min(c.end, n);
  if (end <= c.begin) return;
  w.put(id);
  w.put(uint8_t(kRange));
  w.put(c.begin);
  w.put(end);
  w.put_bytes(v.data() + c.begin, size_t(end - c.begin) * sizeof(T));
}

template <class T>
void decode_array(WireReader& r, std::vector<T>& v, ArrayChange& change, const char* name) {
  const uint8_t encoding = r.get<uint8_t>();
  if (encoding == kWhole) {
    const uint32_t n = r.get<uint32_t>();
    r.need(size_t(n) * sizeof(T));  // before allocating what the message claims
    v.resize(n);
    r.get_bytes(v.data(), size_t(n) * sizeof(T));
    change.reallocated = true;
  } else if (encoding == kRange) {
    const uint32_t begin = r.get<uint32_t>(), end = r.get<uint32_t>();
    if (begin >= end || end > v.size())
      r.fail(std::string("range of ") + name + " outside the array");
    r.get_bytes(v.data() + begin, size_t(end - begin) * sizeof(T));
    change.mark(begin, end);
  } else {
    r.fail(std::string("unknown encoding of ") + name);
  }
}

void put_indices(WireWriter& w, const std::vector<uint32_t>& v) {
  w.put(uint32_t(v.size()));
  w.put_bytes(v.data(), v.size() * sizeof(uint32_t));
}

std::vector<uint32_t> get_indices(WireReader& r) {
  const uint32_t n = r.get<uint32_t>();
  r.need(size_t(n) * sizeof(uint32_t));
  std::vector<uint32_t> v(n);
  r.get_bytes(v.data(), v.size() * sizeof(uint32_t));
  return v;
}

void put_tiles(WireWriter& w, const std::vector<Tile>& tiles) {
  w.put(uint32_t(tiles.size()));
  w.put_bytes(tiles.data(), tiles.size() * sizeof(Tile));
}

std::vector<Tile> get_tiles(WireReader& r) {
  const uint32_t n = r.get<uint32_t>();
  r.need(size_t(n) * sizeof(Tile));
  std::vector<Tile> tiles(n);
  r.get_bytes(tiles.data(), tiles.size() * sizeof(Tile));
  for (const Tile& t : tiles)
    if (t.x1 <= t.x0 || t.y1 <= t.y0) r.fail("empty tile");
  return tiles;
}

}  // namespace

std::string build_fingerprint() {
  std::string s = "tandem 0.1.0, protocol " + std::to_string(kProtocolVersion) + ",";
#define TANDEM_FINGERPRINT_ARRAY(T, name) s += " " #name ":" + std::to_string(sizeof(T));
  TANDEM_KERNEL_ARRAYS(TANDEM_FINGERPRINT_ARRAY)
#undef TANDEM_FINGERPRINT_ARRAY
  s += " constants:" + std::to_string(sizeof(KernelConstants)) +
       " bvh:" + std::to_string(sizeof(KBvhConstants)) + " tile:" + std::to_string(sizeof(Tile));
  return s;
}

void encode_scene(const KernelScene& ks, const SceneDelta& delta, ArrayCounts& receiver,
                  WireWriter& w) {
  w.put(uint8_t(delta.full));
  w.put(uint8_t(delta.constants || delta.full));
  w.put(uint8_t(delta.bvh_constants || delta.full));
  put_indices(w, delta.meshes_rebuilt);
  put_indices(w, delta.meshes_refit);
  put_indices(w, delta.instances_moved);
  if (delta.constants || delta.full) w.put(ks.constants);
  // The BVH updater's own record (TLAS roots, layout), sent like the
  // compiler's constants.
  if (delta.bvh_constants || delta.full) w.put(ks.bvh);
  uint32_t id = 0;
#define TANDEM_ENCODE_ARRAY(T, name) \
  encode_array(w, id, ks.name, delta.name, delta.full, receiver[id]), ++id;
  TANDEM_KERNEL_ARRAYS(TANDEM_ENCODE_ARRAY)
#undef TANDEM_ENCODE_ARRAY
  w.put(kEndOfArrays);
}

SceneDelta decode_scene(WireReader& r, KernelScene& ks) {
  SceneDelta delta;
  delta.full = r.get<uint8_t>() != 0;
  delta.constants = r.get<uint8_t>() != 0;
  delta.bvh_constants = r.get<uint8_t>() != 0;
  delta.meshes_rebuilt = get_indices(r);
  delta.meshes_refit = get_indices(r);
  delta.instances_moved = get_indices(r);
  if (delta.constants) ks.constants = r.get<KernelConstants>();
  if (delta.bvh_constants) ks.bvh = r.get<KBvhConstants>();
  for (uint32_t previous = 0, first = 1;; first = 0) {
    const uint32_t id = r.get<uint32_t>();
    if (id == kEndOfArrays) break;
    if (id >= kKernelArrayTotal || (!first && id <= previous)) r.fail("bad kernel array id");
    previous = id;
    uint32_t k = 0;
#define TANDEM_DECODE_ARRAY(T, name) \
  if (id == k++) decode_array(r, ks.name, delta.name, #name);
    TANDEM_KERNEL_ARRAYS(TANDEM_DECODE_ARRAY)
#undef TANDEM_DECODE_ARRAY
  }
  if (!r.done()) r.fail("trailing bytes");
  return delta;
}

void encode_batch(const TileBatch& b, WireWriter& w) {
  w.put(b.id);
  w.put(b.sample_begin);
  w.put(b.sample_count);
  w.put(b.film_width);
  w.put(b.film_height);
  put_tiles(w, b.tiles);
}

TileBatch decode_batch(WireReader& r) {
  TileBatch b;
  b.id = r.get<uint32_t>();
  b.sample_begin = r.get<uint32_t>();
  b.sample_count = r.get<uint32_t>();
  b.film_width = r.get<uint32_t>();
  b.film_height = r.get<uint32_t>();
  b.tiles = get_tiles(r);
  for (const Tile& t : b.tiles)
    if (t.x1 > b.film_width || t.y1 > b.film_height) r.fail("tile outside the film");
  if (!r.done()) r.fail("trailing bytes");
  return b;
}

void encode_result_header(const BatchResult& res, WireWriter& w, size_t sum_count) {
  w.reserve(w.bytes().size() + 64 + res.tiles.size() * (sizeof(Tile) + sizeof(double)) +
            sum_count * sizeof(double));
  w.put(res.id);
  w.put(res.busy_seconds);
  w.put(res.cpu_seconds);
  w.put(res.render_cpu_seconds);
  w.put(res.rays);
  w.put(res.samples);
  put_tiles(w, res.tiles);
  w.put_bytes(res.tile_seconds.data(), res.tile_seconds.size() * sizeof(double));
}

void encode_result(const BatchResult& res, WireWriter& w) {
  encode_result_header(res, w, res.sums.size());
  w.put_bytes(res.sums.data(), res.sums.size() * sizeof(double));
}

BatchResult decode_result(WireReader& r) {
  BatchResult res;
  res.id = r.get<uint32_t>();
  res.busy_seconds = r.get<double>();
  res.cpu_seconds = r.get<double>();
  res.render_cpu_seconds = r.get<double>();
  res.rays = r.get<uint64_t>();
  res.samples = r.get<uint64_t>();
  res.tiles = get_tiles(r);
  size_t pixels = 0;
  for (const Tile& t : res.tiles)
    pixels += t.pixel_count();
  res.tile_seconds.resize(res.tiles.size());
  r.get_bytes(res.tile_seconds.data(), res.tile_seconds.size() * sizeof(double));
  r.need(pixels * 3 * sizeof(double));
  res.sums.resize(pixels * 3);
  r.get_bytes(res.sums.data(), res.sums.size() * sizeof(double));
  if (!r.done()) r.fail("trailing bytes");
  return res;
}

}  // namespace tandem::mpi
