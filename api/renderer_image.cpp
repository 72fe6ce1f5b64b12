// tandem::Renderer's images: the accumulation and the denoised frame,
// linear or tone mapped, into new vectors, the caller's buffers or files.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "api/renderer_impl.h"

namespace tandem {
inline namespace embed_v0 {

namespace {

ToneMap to_tone_map(ToneCurve curve) {
  switch (curve) {
    case ToneCurve::kAces:
      return ToneMap::kAces;
    case ToneCurve::kReinhard:
      return ToneMap::kReinhard;
    case ToneCurve::kStandard:
      break;
  }
  return ToneMap::kStandard;
}

}  // namespace

uint32_t Renderer::width() const {
  impl_->require_image("width");
  return impl_->tracer->film().width();
}

uint32_t Renderer::height() const {
  impl_->require_image("height");
  return impl_->tracer->film().height();
}

std::vector<float> Renderer::image_linear() const {
  impl_->require_image("image_linear");
  return impl_->tracer->image().rgb;
}

namespace {

// A caller's buffer for the image of `film`: not null and large enough.
void check_image_buffer(const void* out, size_t count, const Film& film, const char* what,
                        const char* unit) {
  if (out == nullptr) invalid(std::string(what) + ": the buffer is null");
  const size_t needed = size_t(film.width()) * film.height() * 3;
  if (count < needed) {
    invalid(std::string(what) + ": the buffer holds " + std::to_string(count) + " " + unit +
            "; the " + std::to_string(film.width()) + "x" + std::to_string(film.height()) +
            " image needs " + std::to_string(needed));
  }
}

}  // namespace

void Renderer::copy_image_linear(float* out, size_t count, FrameImage image) const {
  const char* what = "copy_image_linear";
  if (image == FrameImage::kDenoised) {
    const ImageRGB& d = impl_->denoised_image(what);
    check_image_buffer(out, count, impl_->tracer->film(), what, "floats");
    std::copy(d.rgb.begin(), d.rgb.end(), out);
    return;
  }
  impl_->require_image(what);
  const Film& film = impl_->tracer->film();
  check_image_buffer(out, count, film, what, "floats");
  film.resolve_into(out);
}

void Renderer::copy_image_srgb8(uint8_t* out, size_t count, float exposure_stops, ToneCurve curve,
                                FrameImage image) const {
  const char* what = "copy_image_srgb8";
  impl_->require_image(what);
  if (!std::isfinite(exposure_stops)) invalid("copy_image_srgb8: exposure_stops is not finite");
  check_image_buffer(out, count, impl_->tracer->film(), what, "bytes");
  if (image == FrameImage::kDenoised) {
    tone_map_to_srgb8_into(impl_->denoised_image(what), exposure_stops, to_tone_map(curve), out);
  } else {
    tone_map_to_srgb8_into(impl_->tracer->image(), exposure_stops, to_tone_map(curve), out);
  }
}

std::vector<float> Renderer::image_denoised() const {
  return impl_->denoised_image("image_denoised").rgb;
}

FeatureBuffers Renderer::features() {
  Impl& im = *impl_;
  im.require_image("features");
  if (im.features_frame != im.frames) {
    const bool have = guarded([&] { return im.tracer->render_features(im.motion, im.features); },
                              Error::Kind::kDevice);
    if (!have) {
      throw Error(Error::Kind::kDevice,
                  "features: no backend of this renderer traces feature buffers (a GPU-only "
                  "renderer); BackendChoice::kCpu or kHetero do");
    }
    im.features_frame = im.frames;
  }
  FeatureBuffers out;
  out.width = im.tracer->film().width();
  out.height = im.tracer->film().height();
  const size_t n = im.features.size();
  out.albedo.resize(3 * n);
  out.normal.resize(3 * n);
  out.depth.resize(n);
  out.motion.resize(2 * n);
  for (size_t i = 0; i < n; ++i) {
    const PixelFeatures& p = im.features[i];
    out.albedo[3 * i] = p.albedo.x, out.albedo[3 * i + 1] = p.albedo.y,
                   out.albedo[3 * i + 2] = p.albedo.z;
    out.normal[3 * i] = p.normal.x, out.normal[3 * i + 1] = p.normal.y,
                   out.normal[3 * i + 2] = p.normal.z;
    out.depth[i] = p.depth;
    out.motion[2 * i] = p.motion.x, out.motion[2 * i + 1] = p.motion.y;
  }
  return out;
}

std::vector<uint8_t> Renderer::image_srgb8(float exposure_stops, ToneCurve curve,
                                           FrameImage image) const {
  const ImageRGB linear = impl_->frame_image(image, "image_srgb8");
  if (!std::isfinite(exposure_stops)) invalid("image_srgb8: exposure_stops is not finite");
  return tone_map_to_srgb8(linear, exposure_stops, to_tone_map(curve));
}

void Renderer::write_image(const std::string& path, float exposure_stops, ToneCurve curve,
                           FrameImage image) const {
  const ImageRGB linear = impl_->frame_image(image, "write_image");
  if (!std::isfinite(exposure_stops)) invalid("write_image: exposure_stops is not finite");
  ImageWriteOptions o;
  o.exposure = exposure_stops;
  o.tone_map = to_tone_map(curve);
  guarded([&] { tandem::write_image(path, linear, o); });
}

const void* Renderer::cuda_image_linear() {
  CudaBackend& gpu = impl_->cuda_image_backend("cuda_image_linear");
  return guarded([&] { return gpu.device_image_linear(); }, Error::Kind::kDevice);
}

const void* Renderer::cuda_image_srgb8(float exposure_stops, ToneCurve curve) {
  CudaBackend& gpu = impl_->cuda_image_backend("cuda_image_srgb8");
  if (!std::isfinite(exposure_stops)) invalid("cuda_image_srgb8: exposure_stops is not finite");
  return guarded([&] { return gpu.device_image_srgb8(exposure_stops, to_tone_map(curve)); },
                 Error::Kind::kDevice);
}

}  // namespace embed_v0
}  // namespace tandem
