// Transparent huge pages for large arrays read at random.
#pragma once

#include <cstddef>

namespace tandem {

// The size of a transparent huge page on x86-64 Linux.
inline constexpr size_t kHugePageBytes = size_t(2) << 20;

// Asks the kernel to back the whole 2 MiB pages inside [data, data + bytes)
// with transparent huge pages when they are first touched, on systems whose
// THP mode leaves that to the program ("madvise", Debian's default). For
// arrays read at random, like the textures: a bilinear lookup in a 2048-wide
// RGBA8 texture reads two rows 8 KiB apart, two 4 KiB pages, so at random
// positions nearly every lookup misses the TLB; one 2 MiB page holds 256
// rows. Call it before the memory is written. Returns the number of bytes
// advised (0 where the range holds no whole huge page, on other systems, or
// when the kernel refuses; nothing else changes then).
size_t advise_huge_pages(const void* data, size_t bytes);

}  // namespace tandem
