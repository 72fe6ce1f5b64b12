// libFuzzer entry for the image readers (environment maps, textures and
// `compare` inputs): EXR through the OpenEXR library after its header and
// chunk table are checked, PFM and HDR by our own decoders, PNG/JPEG by
// stb after our header probe. The format is chosen from the content, as
// read_image does for a file whose extension says nothing.
#include <cstdint>

#include "core/image/image.h"
#include "core/util/errors.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  tandem::ImageReadLimits limits;
  limits.max_pixels = uint64_t(1) << 22;  // 48 MiB as float RGB: far below -rss_limit_mb
  try {
    tandem::read_image_from_memory(data, size, "fuzz-input", limits);
  } catch (const tandem::InputError&) {
  }
  tandem::probe_encoded_image(data, size);
  return 0;
}
