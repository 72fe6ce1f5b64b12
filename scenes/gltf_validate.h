// Structural validation of a tinygltf model. tinygltf parses JSON and loads
// buffers but checks few references or ranges, so everything the loader
// will index or read is checked here first.
#pragma once

#include <cstddef>
#include <string>

#include "scenes/gltf_internal.h"

namespace tandem::gltf {

// Checks the whole model: every index (buffer, bufferView, accessor, mesh,
// material, texture, image, sampler, camera, light, node, scene), every byte
// range (overflow-safe), alignment, attribute/index formats, equal attribute
// counts, node hierarchy (cycles, several parents), finite numbers in JSON,
// extensionsRequired. Throws InputError. Afterwards code may index model
// arrays and read accessor bytes without further bounds checks; accessor
// *contents* (index values, NaN) are checked while decoding.
void validate_model(Context& ctx);

// Extensions whose data we read.
bool extension_supported(const std::string& name);
// Extensions that only add optional detail: ignoring them (with a warning)
// still gives a sensible picture, even when a file lists them as required.
bool extension_ignorable(const std::string& name);

}  // namespace tandem::gltf
