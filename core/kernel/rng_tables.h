// Byte tables for the CPU's bit reversals in rng.h, and the unit-float
// conversion they are built with.
//
// x86-64's baseline instruction set has no bit reversal: reversing a word
// with shifts and masks takes about 16 instructions, and a Cornell-box hit
// reverses about ten words (every Owen-scrambled draw reverses its shuffled
// index and its result). Bit reversal, and the second Sobol dimension's
// Pascal matrix after it, are linear over GF(2), so each is the XOR of its
// four bytes' images: four loads instead of the shift cascade, with exactly
// the same bits. The final reversal feeds u32_to_unit_float, whose 24 bits
// come from three bytes with disjoint images: a sum of three exact floats.
// The tables are built at compile time from the shift versions; the GPU
// has a bit-reversal instruction (__brev) and does not use them.
#pragma once

#include "core/kernel/defines.h"
#include "core/kernel/gpu_intrinsics.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

// Maps 24 random bits to [0, 1): exactly representable, never returns 1.
TANDEM_HD_INLINE constexpr float u32_to_unit_float(uint32_t x) {
  return float(x >> 8) * (1.0f / 16777216.0f);
}

// The shift-and-mask reversal (the table's reference; constexpr for it).
constexpr uint32_t reverse_bits_u32_shifts(uint32_t x) {
  x = (x >> 16) | (x << 16);
  x = ((x >> 8) & 0x00ff00ffu) | ((x & 0x00ff00ffu) << 8);
  x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  return ((x >> 4) & 0x0f0f0f0fu) | ((x & 0x0f0f0f0fu) << 4);
}

// Pascal's triangle mod 2 applied to x's bits: bit i of the result is the
// parity of the bits j of x whose positions contain i's (Lucas' theorem).
TANDEM_HD_INLINE constexpr uint32_t pascal_mod2(uint32_t x) {
  x ^= (x & 0xaaaaaaaau) >> 1;
  x ^= (x & 0xccccccccu) >> 2;
  x ^= (x & 0xf0f0f0f0u) >> 4;
  x ^= (x & 0xff00ff00u) >> 8;
  x ^= (x & 0xffff0000u) >> 16;
  return x;
}

#if !TANDEM_GPU_CODE
// A byte's reversal and the Pascal matrix of it share an entry (low and high
// word), so that a 2-d draw, which wants both of the same word, reads four
// entries for the two.
struct RngByteTables {
  uint64_t reverse_pascal[4][256];  // r | pascal_mod2(r) << 32, r = reverse(b << 8k)
  float unit_reverse[3][256];       // float(reverse(b << 8k) >> 8) / 2^24
};

constexpr RngByteTables make_rng_byte_tables() {
  RngByteTables t{};
  for (uint32_t k = 0; k < 4; ++k) {
    for (uint32_t b = 0; b < 256; ++b) {
      const uint32_t r = reverse_bits_u32_shifts(b << (8 * k));
      t.reverse_pascal[k][b] = uint64_t(r) | uint64_t(pascal_mod2(r)) << 32;
      if (k < 3) t.unit_reverse[k][b] = u32_to_unit_float(r);
    }
  }
  return t;
}

inline constexpr RngByteTables kRngByteTables = make_rng_byte_tables();

// reverse_bits_u32(x) | pascal_mod2(reverse_bits_u32(x)) << 32: both are
// linear in x's bits, and the reversals of different bytes do not overlap.
TANDEM_HD_INLINE uint64_t reverse_and_pascal_by_bytes(uint32_t x) {
  const RngByteTables& t = kRngByteTables;
  return t.reverse_pascal[0][x & 0xffu] ^ t.reverse_pascal[1][(x >> 8) & 0xffu] ^
         t.reverse_pascal[2][(x >> 16) & 0xffu] ^ t.reverse_pascal[3][x >> 24];
}
#endif

// reverse_bits_u32(x).
TANDEM_HD_INLINE uint32_t reverse_bits_u32(uint32_t x) {
#if TANDEM_GPU_CODE
  return gpu_reverse_bits(x);
#else
  return uint32_t(reverse_and_pascal_by_bytes(x));
#endif
}

// pascal_mod2(reverse_bits_u32(x)).
TANDEM_HD_INLINE uint32_t pascal_mod2_of_reversed(uint32_t x) {
#if TANDEM_GPU_CODE
  return pascal_mod2(gpu_reverse_bits(x));
#else
  return uint32_t(reverse_and_pascal_by_bytes(x) >> 32);
#endif
}

// Both: *reversed = reverse_bits_u32(x), *pascal = pascal_mod2(*reversed).
TANDEM_HD_INLINE void reverse_and_pascal(uint32_t x, uint32_t* reversed, uint32_t* pascal) {
#if TANDEM_GPU_CODE
  *reversed = gpu_reverse_bits(x);
  *pascal = pascal_mod2(*reversed);
#else
  const uint64_t both = reverse_and_pascal_by_bytes(x);
  *reversed = uint32_t(both);
  *pascal = uint32_t(both >> 32);
#endif
}

// u32_to_unit_float(reverse_bits_u32(x)): the result's 24 bits are the
// reversal of x's low three bytes; their three images are multiples of
// 2^-24 below 1 with disjoint bits, so the float sums are exact.
TANDEM_HD_INLINE float unit_float_of_reversed(uint32_t x) {
#if TANDEM_GPU_CODE
  return u32_to_unit_float(gpu_reverse_bits(x));
#else
  const RngByteTables& t = kRngByteTables;
  return (t.unit_reverse[0][x & 0xffu] + t.unit_reverse[1][(x >> 8) & 0xffu]) +
         t.unit_reverse[2][(x >> 16) & 0xffu];
#endif
}

TANDEM_KERNEL_END
}  // namespace tandem
