// What BlasRefit's index (blas_refit_index.cpp) and its per-frame refit
// (blas_refit.cpp) both read: the encoding of the index's arrays. Internal
// to those two files.
#pragma once

#include <cstddef>
#include <cstdint>

namespace tandem::blas_refit_entries {

constexpr uint32_t kNone = 0xffffffffu;
// A wide slot's source in wide_src_: its kind in the top two bits, then a
// binary node child (2 * node + c) or a binary leaf entry.
constexpr uint32_t kSlotEmpty = 0u, kSlotNode = 1u << 30, kSlotTris = 2u << 30;
constexpr uint32_t kSlotKind = 3u << 30, kSlotIndex = ~kSlotKind;
// Words per leaf entry in leaf_tris_: the three vertex indices and the
// triangle's index (what its record holds in p0.w) with kLastOfLeaf set on
// the last entry of each binary leaf, one aligned 16 bytes.
constexpr size_t kEntryWords = 4;
constexpr uint32_t kLastOfLeaf = 0x80000000u;

// Triangles in a wide leaf slot, from its meta byte.
inline uint32_t wide_leaf_count(uint32_t meta) {
  const uint32_t unary = meta >> 5;
  return unary == 7 ? 3u : (unary == 3 ? 2u : 1u);
}

}  // namespace tandem::blas_refit_entries
