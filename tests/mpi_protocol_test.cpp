// The distributed wire format without MPI: a scene sent whole and then as
// deltas arrives identical, array for array; hostile messages are errors.
#include <gtest/gtest.h>

#include <cstring>

#include "backends/mpi/mpi_protocol.h"
#include "core/render/film.h"
#include "scenes/builtin_scenes.h"
#include "sync/scene_sync.h"

namespace tandem::mpi {
namespace {

// Every kernel array of `a` and `b` holds the same bytes.
void expect_same_arrays(const KernelScene& a, const KernelScene& b) {
#define TANDEM_COMPARE_ARRAY(T, name)                                                    \
  ASSERT_EQ(a.name.size(), b.name.size()) << #name;                                      \
  EXPECT_TRUE(a.name.empty() ||                                                          \
              std::memcmp(a.name.data(), b.name.data(), a.name.size() * sizeof(T)) == 0) \
      << #name;
  TANDEM_KERNEL_ARRAYS(TANDEM_COMPARE_ARRAY)
#undef TANDEM_COMPARE_ARRAY
  EXPECT_EQ(std::memcmp(&a.constants, &b.constants, sizeof(KernelConstants)), 0);
}

TEST(MpiProtocol, SceneArrivesWholeThenAsDeltas) {
  Scene scene = make_builtin_scene("cornell-spheres");
  RenderSettings settings;
  settings.width = 64;
  settings.height = 48;
  SceneSync sync(SceneSyncSettings::arrays_only());
  const KernelScene& sender = sync.kernel_scene();
  KernelScene receiver;
  ArrayCounts counts{};
  SceneDelta delta = sync.update(scene, settings).changes;
  WireWriter w;
  encode_scene(sender, delta, counts, w);
  WireReader r(w.bytes(), "test");
  const SceneDelta got = decode_scene(r, receiver);
  EXPECT_TRUE(got.full);
  expect_same_arrays(sender, receiver);
  const size_t full_bytes = w.bytes().size();

  // Move one instance: only its range travels, and the copy still matches.
  ASSERT_FALSE(scene.instances().empty());
  glm::mat4 moved = scene.instances()[0].transform;
  moved[3][0] += 0.25f;
  scene.set_instance_transform(0, moved);
  delta = sync.update(scene, settings).changes;
  ASSERT_TRUE(delta.any());
  WireWriter w2;
  encode_scene(sender, delta, counts, w2);
  EXPECT_LT(w2.bytes().size(), full_bytes / 4) << "a delta, not the scene again";
  WireReader r2(w2.bytes(), "test");
  const SceneDelta got2 = decode_scene(r2, receiver);
  EXPECT_FALSE(got2.full);
  EXPECT_TRUE(got2.instances.any());
  EXPECT_EQ(got2.instances_changed(), delta.instances_changed());
  EXPECT_EQ(got2.meshes_refit, delta.meshes_refit);
  expect_same_arrays(sender, receiver);
}

TEST(MpiProtocol, ArrayThatChangedSizeIsSentWhole) {
  KernelScene sender, receiver;
  sender.texels.assign(10, 7u);
  ArrayCounts counts{};
  SceneDelta everything = SceneDelta::everything();
  WireWriter w;
  encode_scene(sender, everything, counts, w);
  WireReader r(w.bytes(), "test");
  decode_scene(r, receiver);
  // The delta names a range only, but the array grew: a range against a
  // shorter copy would be wrong, so it goes whole.
  sender.texels.assign(20, 9u);
  SceneDelta d;
  d.texels.mark(0, 2);
  WireWriter w2;
  encode_scene(sender, d, counts, w2);
  WireReader r2(w2.bytes(), "test");
  const SceneDelta got = decode_scene(r2, receiver);
  EXPECT_TRUE(got.texels.reallocated);
  expect_same_arrays(sender, receiver);
}

TEST(MpiProtocol, TruncatedOrCorruptMessagesAreErrorsNotCrashes) {
  Scene scene = make_builtin_scene("cornell");
  RenderSettings settings;
  SceneSync sync(SceneSyncSettings::arrays_only());
  const KernelScene& sender = sync.kernel_scene();
  ArrayCounts counts{};
  const SceneDelta delta = sync.update(scene, settings).changes;
  WireWriter w;
  encode_scene(sender, delta, counts, w);
  const std::vector<uint8_t>& bytes = w.bytes();
  for (size_t cut : {size_t(0), size_t(1), size_t(7), bytes.size() / 2, bytes.size() - 1}) {
    KernelScene receiver;
    WireReader r(bytes.data(), cut, "cut");
    EXPECT_THROW(decode_scene(r, receiver), WireError) << cut;
  }
  // A range beyond the receiver's array.
  KernelScene small;
  WireWriter bad;
  bad.put(uint8_t(0)), bad.put(uint8_t(0)), bad.put(uint8_t(0));
  bad.put(uint32_t(0)), bad.put(uint32_t(0));
  bad.put(uint32_t(0));  // positions
  bad.put(uint8_t(2));   // a range
  bad.put(uint32_t(0)), bad.put(uint32_t(1000));
  WireReader r(bad.bytes(), "bad");
  EXPECT_THROW(decode_scene(r, small), WireError);
  // A claimed element count far beyond the message is refused before it
  // is allocated.
  WireWriter huge;
  huge.put(uint8_t(1)), huge.put(uint8_t(0)), huge.put(uint8_t(0));
  huge.put(uint32_t(0)), huge.put(uint32_t(0));
  huge.put(uint32_t(0)), huge.put(uint8_t(1)), huge.put(uint32_t(0xfffffff0u));
  WireReader rh(huge.bytes(), "huge");
  EXPECT_THROW(decode_scene(rh, small), WireError);
}

TEST(MpiProtocol, BatchesAndResultsRoundTrip) {
  TileBatch b;
  b.id = 7;
  b.sample_begin = 3;
  b.sample_count = 2;
  b.film_width = 64;
  b.film_height = 32;
  b.tiles = {{0, 0, 8, 8, 0}, {8, 0, 16, 4, 1}};
  WireWriter w;
  encode_batch(b, w);
  WireReader r(w.bytes(), "batch");
  const TileBatch got = decode_batch(r);
  EXPECT_EQ(got.id, 7u);
  EXPECT_EQ(got.sample_begin, 3u);
  ASSERT_EQ(got.tiles.size(), 2u);
  EXPECT_EQ(got.tiles[1].x1, 16u);

  b.tiles.push_back({60, 0, 70, 8, 2});  // beyond the film
  WireWriter w2;
  encode_batch(b, w2);
  WireReader r2(w2.bytes(), "batch");
  EXPECT_THROW(decode_batch(r2), WireError);

  BatchResult res;
  res.id = 7;
  res.tiles = {{0, 0, 2, 1, 0}};
  res.tile_seconds = {0.5};
  res.sums = {1, 2, 3, 4, 5, 6};
  res.cpu_seconds = 2.5;
  res.render_cpu_seconds = 2.25;
  WireWriter w3;
  encode_result(res, w3);
  WireReader r3(w3.bytes(), "result");
  const BatchResult back = decode_result(r3);
  EXPECT_EQ(back.sums, res.sums);
  EXPECT_EQ(back.tile_seconds, res.tile_seconds);
  EXPECT_EQ(back.cpu_seconds, 2.5);
  EXPECT_EQ(back.render_cpu_seconds, 2.25);
}

TEST(MpiProtocol, ResultWrittenStraightFromTheFilmIsTheSameMessage) {
  // The worker writes the header, then each tile row of its film's sums:
  // byte for byte what encode_result makes of the same sums.
  Film film(8, 4);
  const std::vector<Tile> tiles = {{1, 0, 4, 2, 0}, {4, 2, 8, 4, 5}};
  double v = 0.25;
  for (const Tile& t : tiles) {
    for (uint32_t y = t.y0; y < t.y1; ++y) {
      for (uint32_t x = t.x0; x < t.x1; ++x, v += 1.0) {
        const double sum[3] = {v, -v, v * 3.0};
        film.add(x, y, sum, 1);
      }
    }
  }
  BatchResult res;
  res.id = 3;
  res.busy_seconds = 0.125;
  res.rays = 99;
  res.tiles = tiles;
  res.tile_seconds = {0.5, 0.75};
  size_t count = 0;
  for (const Tile& t : tiles) {
    for (uint32_t y = t.y0; y < t.y1; ++y) {
      for (uint32_t x = t.x0; x < t.x1; ++x, count += 3)
        res.sums.insert(res.sums.end(), film.sum(x, y), film.sum(x, y) + 3);
    }
  }
  WireWriter whole;
  encode_result(res, whole);
  WireWriter direct;
  encode_result_header(res, direct, count);
  for (const Tile& t : tiles) {
    for (uint32_t y = t.y0; y < t.y1; ++y)
      direct.put_bytes(film.sum(t.x0, y), size_t(t.x1 - t.x0) * 3 * sizeof(double));
  }
  EXPECT_EQ(direct.bytes(), whole.bytes());
  WireReader r(direct.bytes(), "result");
  EXPECT_EQ(decode_result(r).sums, res.sums);
}

TEST(MpiProtocol, FingerprintNamesEveryArrayAndTheProtocol) {
  const std::string f = build_fingerprint();
  EXPECT_NE(f.find("protocol " + std::to_string(kProtocolVersion)), std::string::npos);
  EXPECT_NE(f.find("positions:"), std::string::npos);
  EXPECT_NE(f.find("bvh_wide_prim_indices:"), std::string::npos);
}

}  // namespace
}  // namespace tandem::mpi
