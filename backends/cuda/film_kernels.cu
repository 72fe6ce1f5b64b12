// The per-pixel reduction of a batch's samples, the device-resident film
// for GPU-only output, and its tone mapping to 8 bits, over the per-pixel
// functions of batch.h and core/kernel/tile_batch.h.
#include "backends/cuda/device_exec.h"
#include "core/kernel/tone_map.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

template <class Exec>
TANDEM_DEVICE_FN void ReduceSamples::run(Exec& ex, const Args& a) {
  const uint64_t p = ex.global_x();
  if (p < a.batch.pixel_count) reduce_pixel_samples(a.batch, a.radiance, uint32_t(p), a.pixel_sums);
}

template <class Exec>
TANDEM_DEVICE_FN void AccumulateFilm::run(Exec& ex, const Args& a) {
  const uint64_t p = ex.global_x();
  if (p < a.batch.pixel_count)
    accumulate_film_pixel(a.batch, a.pixel_sums, a.sample_count, a.film, uint32_t(p));
}

template <class Exec>
TANDEM_DEVICE_FN void ResolveFilm::run(Exec& ex, const Args& a) {
  const uint64_t i = ex.global_x();
  if (i < uint64_t(a.film.width) * a.film.height) film_pixel_mean(a.film, i, &a.rgb[3 * i]);
}

template <class Exec>
TANDEM_DEVICE_FN void ToneMapFilm::run(Exec& ex, const Args& a) {
  const uint64_t i = ex.global_x();
  if (i < uint64_t(a.film.width) * a.film.height)
    tone_map_film_pixel(a.film, i, a.exposure_scale, a.curve, a.rgb8);
}

TANDEM_KERNEL_END
}  // namespace tandem

TANDEM_KERNEL_REGISTRY(film) {
  register_kernels<ReduceSamples, AccumulateFilm, ResolveFilm, ToneMapFilm>(table);
}
