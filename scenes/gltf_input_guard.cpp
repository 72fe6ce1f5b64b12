// Defences that run before and around tinygltf: JSON nesting, the .glb
// container, which files URIs may name, and the loader's memory budgets.
#include <cstring>
#include <system_error>

#include "scenes/gltf_internal.h"

namespace tandem::gltf {

std::string format_bytes(uint64_t bytes) {
  if (bytes < 1024) return std::to_string(bytes) + (bytes == 1 ? " byte" : " bytes");
  const char* units[] = {"KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
  double v = double(bytes) / 1024.0;
  int u = 0;
  while (v >= 1024.0 && u < 5) {
    v /= 1024.0;
    ++u;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, v < 10.0 ? "%.1f %s" : "%.0f %s", v, units[u]);
  return buf;
}

uint64_t Context::limit(Budget budget) const {
  // Data that really is in the file's buffers may decode to a few times its
  // size (bytes to floats, one vertex into every merged attribute array), so
  // big files get that much on top of the fixed budget; what a small file
  // can ask for beyond its size stays bounded by the fixed part.
  uint64_t buffer_bytes = 0;
  for (const tinygltf::Buffer& b : model.buffers)
    buffer_bytes += b.data.size();
  switch (budget) {
    case Budget::kAccessorBytes:
      return limits.max_accessor_bytes + 4 * buffer_bytes;
    case Budget::kZeroFilledElements:
      return limits.max_zero_filled_elements;
    case Budget::kGeometryBytes:
      return limits.max_geometry_bytes + 6 * buffer_bytes;
    case Budget::kInstances:
      return limits.max_instances;
    case Budget::kTextureBytes:
      return limits.max_texture_bytes;
    case Budget::kNameBytes:
      return limits.max_name_bytes;
    case Budget::kEmissiveLights:
      return limits.max_emissive_lights;
  }
  return 0;
}

bool Context::fits(Budget budget, uint64_t amount) const {
  const uint64_t used = used_[int(budget)];
  return amount <= limit(budget) && used <= limit(budget) - amount;
}

void Context::charge(Budget budget, uint64_t amount, const std::string& what) const {
  if (!fits(budget, amount)) {
    const uint64_t used = used_[int(budget)];
    const uint64_t cap = limit(budget);
    std::string sizes, kind;
    switch (budget) {
      case Budget::kAccessorBytes:
        kind = "decoded accessor data";
        break;
      case Budget::kZeroFilledElements:
        kind = "elements of accessors without a bufferView (zero-filled)";
        break;
      case Budget::kGeometryBytes:
        kind = "mesh geometry";
        break;
      case Budget::kInstances:
        kind = "instances";
        break;
      case Budget::kTextureBytes:
        kind = "decoded textures";
        break;
      case Budget::kNameBytes:
        kind = "instance names";
        break;
      case Budget::kEmissiveLights:
        kind = "lights (one for each emissive triangle of a mesh, one for each instance of one)";
        break;
    }
    const bool counts = budget == Budget::kZeroFilledElements || budget == Budget::kInstances ||
                        budget == Budget::kEmissiveLights;
    auto size = [&](uint64_t v) { return counts ? std::to_string(v) : format_bytes(v); };
    fail(what + " needs " + size(amount) + " more " + (counts ? "" : "of ") + kind + " (" +
         size(used) + " already used), over this loader's limit of " + size(cap) +
         "; the file is refused rather than allowed to take that much memory");
  }
  used_[int(budget)] += amount;
}

size_t json_nesting_depth(const char* json, size_t size, size_t limit, size_t* where) {
  size_t depth = 0, deepest = 0;
  bool in_string = false;
  for (size_t i = 0; i < size; ++i) {
    const char c = json[i];
    if (in_string) {
      if (c == '\\') {
        ++i;  // the escaped character cannot end the string
      } else if (c == '"') {
        in_string = false;
      }
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > deepest) {
        deepest = depth;
        if (deepest > limit) {
          if (where != nullptr) *where = i;
          return deepest;
        }
      }
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return deepest;
}

bool glb_json_chunk(const unsigned char* data, size_t size, const char** json, size_t* json_size) {
  // 12-byte header (magic, version, length), then chunk 0: length, type "JSON".
  if (size < 20 || std::memcmp(data, "glTF", 4) != 0) return false;
  uint32_t chunk_length = 0;
  std::memcpy(&chunk_length, data + 12, 4);
  if (std::memcmp(data + 16, "JSON", 4) != 0 || chunk_length > size - 20) return false;
  *json = reinterpret_cast<const char*>(data + 20);
  *json_size = chunk_length;
  return true;
}

std::string glb_bin_chunk_problem(const unsigned char* data, size_t size) {
  if (size < 20 || std::memcmp(data, "glTF", 4) != 0) return "";
  uint32_t length = 0, json_length = 0, bin_length = 0;
  std::memcpy(&length, data + 8, 4);
  std::memcpy(&json_length, data + 12, 4);
  const uint64_t bin_at = 20 + uint64_t(json_length);
  if (length > size || bin_at + 8 > length) return "";  // tinygltf explains these
  std::memcpy(&bin_length, data + bin_at, 4);
  // tinygltf 2.7 checks the BIN data against the length without its 8-byte
  // chunk header, and then reads up to 8 bytes past the end of the file.
  if (bin_at + 8 + bin_length > length) {
    return "invalid glTF: the BIN chunk (" + std::to_string(bin_length) +
           " bytes) runs past the end of the file (" + std::to_string(length) + " bytes)";
  }
  return "";
}

namespace {

// Whether `inner` is `outer` or below it; both canonical.
bool is_inside(const std::filesystem::path& inner, const std::filesystem::path& outer) {
  auto o = outer.begin(), i = inner.begin();
  for (; o != outer.end(); ++o, ++i) {
    if (i == inner.end() || *i != *o) return false;
  }
  return true;
}

}  // namespace

bool UriPolicy::permits(const std::string& path) {
  if (allow_outside) return true;
  std::error_code ec;
  // weakly_canonical resolves "..", and every symlink of the part that
  // exists, so a link inside the folder that points out of it is caught.
  const std::filesystem::path resolved = std::filesystem::weakly_canonical(path, ec);
  if (!ec && !base_dir.empty() && is_inside(resolved, base_dir)) return true;
  if (refused.empty()) {
    // Show the URI as written (tinygltf joined it to the base folder), and
    // nothing about the file it names.
    std::string shown = path;
    if (!joined_base.empty() && shown.rfind(joined_base + "/", 0) == 0)
      shown = shown.substr(joined_base.size() + 1);
    refused = "the URI \"" + shown +
              "\" leaves the scene's folder (resolved through \"..\" or a symlink); files "
              "outside it are not read unless --allow-outside-uris is given";
  }
  return false;
}

}  // namespace tandem::gltf
