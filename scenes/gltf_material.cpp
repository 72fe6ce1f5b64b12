// glTF materials, textures and images -> tandem Materials and Textures.
#include <algorithm>
#include <atomic>
#include <climits>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <exception>
#include <functional>
#include <map>
#include <mutex>
#include <new>
#include <set>
#include <string_view>
#include <thread>

#include <tbb/global_control.h>
#include <tuple>
#include <utility>

#include <stb_image.h>

#include "core/image/image.h"
#include "scenes/gltf_internal.h"

namespace tandem::gltf {

namespace {

using tinygltf::Value;

// Value::Get(key) asserts on non-objects, so every lookup goes through here.
const Value* member(const Value* object, const char* key) {
  if (object == nullptr || !object->IsObject() || !object->Has(key)) return nullptr;
  return &object->Get(key);
}

const Value* extension(const tinygltf::ExtensionMap& extensions, const char* name) {
  const auto it = extensions.find(name);
  return it == extensions.end() ? nullptr : &it->second;
}

double number(const Context& ctx, const Value* object, const char* key, double fallback,
              const std::string& who) {
  const Value* v = member(object, key);
  if (v == nullptr) return fallback;
  if (!v->IsNumber() || !std::isfinite(v->GetNumberAsDouble())) {
    ctx.fail(who + " " + key + " must be a finite number");
  }
  return v->GetNumberAsDouble();
}

// Reads an array of `n` finite numbers, or returns false when absent.
bool numbers(const Context& ctx, const Value* object, const char* key, int n, double* out,
             const std::string& who) {
  const Value* v = member(object, key);
  if (v == nullptr) return false;
  if (!v->IsArray() || v->ArrayLen() != size_t(n)) {
    ctx.fail(who + " " + key + " must be an array of " + std::to_string(n) + " numbers");
  }
  for (int i = 0; i < n; ++i) {
    const Value& e = v->Get(i);
    if (!e.IsNumber() || !std::isfinite(e.GetNumberAsDouble())) {
      ctx.fail(who + " " + key + " must be an array of " + std::to_string(n) + " finite numbers");
    }
    out[i] = e.GetNumberAsDouble();
  }
  return true;
}

struct DecodedImage {
  bool ok = false;
  uint32_t width = 0, height = 0;
  std::vector<uint32_t> rgba8;
  std::string error;
};

// The shape of an encoded image, from its header (without decoding).
struct ImageShape {
  uint32_t width = 0, height = 0;
  int channels = 4, bytes_per_channel = 1;
  bool png = false;
  uint64_t pixels() const { return uint64_t(width) * height; }
  // What the texture keeps: packed RGBA8.
  uint64_t kept_bytes() const { return pixels() * 4; }
  // The most decoding holds at once: stb's inflated rows and its image
  // (a 16-bit RGB PNG: 12 bytes a pixel), then its image and our RGBA8.
  uint64_t decode_bytes() const {
    const uint64_t native = uint64_t(channels) * uint64_t(bytes_per_channel);
    return pixels() * std::max(2 * native, native + 4);
  }
  std::string text() const {
    return std::to_string(width) + "x" + std::to_string(height) + " pixels, " +
           std::to_string(channels) + " channel" + (channels == 1 ? "" : "s") + " of " +
           std::to_string(8 * bytes_per_channel) + " bits";
  }
};

// The shape from the PNG/JPEG header, or an error that says what is wrong:
// a size over the limit, or a corrupt header.
bool image_shape(const unsigned char* bytes, size_t size, uint64_t max_pixels, ImageShape& shape,
                 std::string& error) {
  const EncodedImageInfo info = probe_encoded_image(bytes, size);
  if (info.format != EncodedImageInfo::kUnknown) {  // PNG or JPEG
    if (!info.header_ok) {
      error = info.problem;
      return false;
    }
    shape.width = info.width;
    shape.height = info.height;
    shape.channels = info.channels;
    shape.bytes_per_channel = info.bytes_per_channel;
    shape.png = info.format == EncodedImageInfo::kPng;
  } else {
    // glTF textures are PNG or JPEG; stb's other decoders (PNM, BMP, TGA,
    // ...) are not hardened against hostile files and are never reached.
    error = "not a PNG or JPEG image";
    return false;
  }
  if (shape.width < 1 || shape.height < 1 || shape.pixels() > max_pixels) {
    error = "it claims " + std::to_string(shape.width) + "x" + std::to_string(shape.height) +
            " pixels, over the limit of " + std::to_string(max_pixels) + " pixels per texture";
    return false;
  }
  return true;
}

// Decodes 8-bit PNGs with libpng, the rest with stb directly (tinygltf's
// decoder copies the decoded pixels once more): the memory it takes is at
// most ImageShape::decode_bytes(). `png8`: the header (image_shape) says
// an 8-bit PNG.
DecodedImage decode_image(const unsigned char* bytes, size_t size, bool png8) {
  DecodedImage out;
  if (size > size_t(INT_MAX)) {
    out.error = "the encoded image is larger than 2 GiB";
    return out;
  }
  // 8-bit PNGs, nearly every PNG texture, through libpng (twice as fast).
  if (png8) {
    out.ok = decode_png_rgba8(bytes, size, out.width, out.height, out.rgba8, out.error);
    return out;
  }
  int w = 0, h = 0, c = 0;
  const bool sixteen = stbi_is_16_bit_from_memory(bytes, int(size)) != 0;
  void* pixels = sixteen
                     ? static_cast<void*>(stbi_load_16_from_memory(bytes, int(size), &w, &h, &c, 0))
                     : static_cast<void*>(stbi_load_from_memory(bytes, int(size), &w, &h, &c, 0));
  if (pixels == nullptr) {
    const char* reason = stbi_failure_reason();
    out.error = reason != nullptr && std::string(reason) == "outofmem"
                    ? std::string("not enough memory to decode it")
                    : "the image could not be decoded (" +
                          std::string(reason != nullptr ? reason : "unknown reason") + ")";
    return out;
  }
  const int bits = sixteen ? 16 : 8;
  const size_t byte_count = size_t(w) * size_t(h) * size_t(c) * size_t(bits / 8);
  bool converted = false;
  try {
    converted = pixels_to_rgba8(static_cast<const unsigned char*>(pixels), byte_count, w, h, c,
                                bits, out.rgba8);
  } catch (...) {
    stbi_image_free(pixels);
    throw;
  }
  stbi_image_free(pixels);
  if (!converted) {
    out.error = "unsupported pixel layout (" + std::to_string(c) + " channels, " +
                std::to_string(bits) + " bits)";
    return out;
  }
  out.width = uint32_t(w);
  out.height = uint32_t(h);
  out.ok = true;
  return out;
}

// The memory the decoding threads may take together: a thread waits until
// its image's share is free (one image larger than all of it runs alone).
class DecodeMemory {
 public:
  explicit DecodeMemory(uint64_t capacity) : free_(capacity), capacity_(capacity) {}
  class Hold {
   public:
    Hold(DecodeMemory& pool, uint64_t bytes)
        : pool_(pool), bytes_(std::min(bytes, pool.capacity_)) {
      std::unique_lock<std::mutex> lock(pool_.mutex_);
      pool_.freed_.wait(lock, [&] { return pool_.free_ >= bytes_; });
      pool_.free_ -= bytes_;
    }
    ~Hold() {
      {
        const std::lock_guard<std::mutex> lock(pool_.mutex_);
        pool_.free_ += bytes_;
      }
      pool_.freed_.notify_all();
    }
    Hold(const Hold&) = delete;
    Hold& operator=(const Hold&) = delete;

   private:
    DecodeMemory& pool_;
    uint64_t bytes_;
  };

 private:
  std::mutex mutex_;
  std::condition_variable freed_;
  uint64_t free_, capacity_;
};

std::string image_label(const tinygltf::Model& m, int index) {
  const tinygltf::Image& img = m.images[size_t(index)];
  std::string label = "image " + std::to_string(index);
  if (!img.uri.empty() && img.uri.rfind("data:", 0) != 0) {
    label += " (\"" + img.uri + "\")";
  } else if (!img.name.empty()) {
    label += " (\"" + img.name + "\")";
  }
  return label;
}

class MaterialConverter {
 public:
  MaterialConverter(Context& ctx, const EncodedImages& encoded) : ctx_(ctx), encoded_(encoded) {}

  MaterialResult run() {
    const tinygltf::Model& m = ctx_.model;
    decode_referenced_images();
    texture_map_.assign(m.textures.size(), kNotCreated);
    for (size_t i = 0; i < m.materials.size(); ++i) {
      result_.materials.push_back(convert(m.materials[i], "material " + std::to_string(i)));
    }
    return std::move(result_);
  }

 private:
  static constexpr int kNotCreated = -2;

  // Texture indices of every slot we read, so only those images get decoded.
  std::vector<int> referenced_textures() const {
    std::vector<int> out;
    for (const tinygltf::Material& mat : ctx_.model.materials) {
      out.push_back(mat.pbrMetallicRoughness.baseColorTexture.index);
      out.push_back(mat.pbrMetallicRoughness.metallicRoughnessTexture.index);
      out.push_back(mat.normalTexture.index);
      out.push_back(mat.emissiveTexture.index);
      static const std::pair<const char*, const char*> kExtensionTextures[] = {
          {"KHR_materials_transmission", "transmissionTexture"},
          {"KHR_materials_clearcoat", "clearcoatTexture"},
          {"KHR_materials_clearcoat", "clearcoatRoughnessTexture"},
          {"KHR_materials_sheen", "sheenColorTexture"},
          {"KHR_materials_sheen", "sheenRoughnessTexture"},
      };
      for (const auto& [ext, slot] : kExtensionTextures) {
        const Value* t = member(extension(mat.extensions, ext), slot);
        if (const Value* idx = member(t, "index"); idx != nullptr && idx->IsInt()) {
          out.push_back(idx->Get<int>());
        }
      }
    }
    return out;
  }

  // The encoded bytes of image i: in a bufferView or read from its URI.
  bool encoded_bytes(int i, const unsigned char*& data, size_t& size, std::string& error) const {
    const tinygltf::Model& m = ctx_.model;
    const tinygltf::Image& img = m.images[size_t(i)];
    if (img.bufferView >= 0) {
      const tinygltf::BufferView& v = m.bufferViews[size_t(img.bufferView)];
      data = m.buffers[size_t(v.buffer)].data.data() + v.byteOffset;
      size = v.byteLength;
      return true;
    }
    if (const std::vector<unsigned char>* b = encoded_.bytes(i)) {
      data = b->data();
      size = b->size();
      return true;
    }
    const auto e = encoded_.errors.find(i);
    error = e != encoded_.errors.end() ? e->second : "the file was not found or could not be read";
    return false;
  }

  void decode_referenced_images() {
    const tinygltf::Model& m = ctx_.model;
    std::vector<int> images;
    for (int t : referenced_textures()) {
      if (t >= 0 && m.textures[size_t(t)].source >= 0)
        images.push_back(m.textures[size_t(t)].source);
    }
    std::sort(images.begin(), images.end());
    images.erase(std::unique(images.begin(), images.end()), images.end());
    decoded_.resize(m.images.size());
    canonical_.resize(m.images.size());
    for (size_t i = 0; i < canonical_.size(); ++i)
      canonical_[i] = int(i);

    // Images with identical bytes (one file named by several entries, one
    // bufferView used twice) are decoded once: canonical_ maps each to the
    // first. Then every image to decode is sized from its header and
    // charged against the texture budget, in file order, before decoding.
    struct Job {
      int image;
      const unsigned char* data;
      size_t size;
      uint64_t decode_bytes = 0;
      bool png8 = false;  // an 8-bit PNG, decoded by libpng
    };
    uint64_t encoded_total = 0;
    std::pair<uint64_t, int> largest_decode{0, -1};
    std::vector<Job> jobs;
    std::map<std::pair<size_t, size_t>, std::vector<Job>> by_content;
    for (int i : images) {
      Job job{i, nullptr, 0, 0};
      std::string error;
      if (!encoded_bytes(i, job.data, job.size, error)) {
        decoded_[size_t(i)].error = error;
        continue;
      }
      const size_t hash =
          std::hash<std::string_view>{}({reinterpret_cast<const char*>(job.data), job.size});
      std::vector<Job>& same = by_content[{job.size, hash}];
      const auto twin = std::find_if(same.begin(), same.end(), [&](const Job& o) {
        return std::memcmp(o.data, job.data, job.size) == 0;
      });
      if (twin != same.end()) {
        canonical_[size_t(i)] = twin->image;
        continue;
      }
      same.push_back(job);
      ImageShape shape;
      if (!image_shape(job.data, job.size, ctx_.limits.max_texture_pixels, shape, error)) {
        decoded_[size_t(i)].error = error;
        continue;
      }
      // Decoding takes more than the texture keeps (a 16-bit PNG three
      // times as much): that is held to a limit of its own per image, and
      // the decoders together to the same amount at any one time.
      job.decode_bytes = shape.decode_bytes();
      job.png8 = shape.png && shape.bytes_per_channel == 1;
      if (job.decode_bytes > ctx_.limits.max_image_decode_bytes) {
        decoded_[size_t(i)].error = "its " + shape.text() + " need " +
                                    format_bytes(job.decode_bytes) +
                                    " while decoding, over this loader's limit of " +
                                    format_bytes(ctx_.limits.max_image_decode_bytes) + " per image";
        continue;
      }
      const uint64_t bytes = shape.kept_bytes();
      if (!ctx_.fits(Budget::kTextureBytes, bytes)) {
        decoded_[size_t(i)].error = budget_message(shape.width, shape.height, bytes);
        continue;
      }
      ctx_.charge(Budget::kTextureBytes, bytes, image_label(m, i));
      encoded_total += job.size;
      if (job.decode_bytes > largest_decode.first) largest_decode = {job.decode_bytes, i};
      jobs.push_back(job);
    }
    // A small file whose textures need far more memory than it holds says
    // so before that memory is taken (a 500 KiB PNG can decode to 1 GiB).
    const uint64_t need = ctx_.used(Budget::kTextureBytes) + largest_decode.first;
    if (need > (uint64_t(512) << 20) && need > 64 * encoded_total) {
      ctx_.warn("the textures' " + format_bytes(encoded_total) + " of encoded images need up to " +
                format_bytes(need) + " of memory to decode (" +
                format_bytes(ctx_.used(Budget::kTextureBytes)) + " kept; the largest, " +
                image_label(m, largest_decode.second) + ", takes " +
                format_bytes(largest_decode.first) + " while decoding)");
    }
    DecodeMemory decode_memory(ctx_.limits.max_image_decode_bytes);

    // PNG decoding dominates load time for textured models; images are
    // independent, so decode them on all cores.
    std::atomic<size_t> next{0};
    auto worker = [&] {
      for (size_t k = next++; k < jobs.size(); k = next++) {
        const Job& job = jobs[k];
        DecodedImage& d = decoded_[size_t(job.image)];
        try {
          const DecodeMemory::Hold hold(decode_memory, job.decode_bytes);
          d = decode_image(job.data, job.size, job.png8);
        } catch (const std::exception& e) {  // bad_alloc: must not escape a thread
          d = DecodedImage{};
          d.error = std::string("decoding failed (") +
                    (dynamic_cast<const std::bad_alloc*>(&e) ? "not enough memory" : e.what()) +
                    ")";
        }
      }
    };
    // As many threads as TBB's limit allows (an embedding host's thread
    // budget is a tbb::global_control; without one it is every core).
    const size_t allowed =
        tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
    const size_t threads = std::min<size_t>(
        jobs.size(),
        std::max<size_t>(1, std::min<size_t>(allowed, std::thread::hardware_concurrency())));
    std::vector<std::thread> pool;
    for (size_t t = 1; t < threads; ++t)
      pool.emplace_back(worker);
    worker();
    for (std::thread& t : pool)
      t.join();

    for (int i : images) {
      if (canonical_[size_t(i)] != i) continue;
      if (!decoded_[size_t(i)].ok) {
        ++result_.images_unavailable;
        ctx_.warn(image_label(m, i) + " is unavailable: " + decoded_[size_t(i)].error +
                  "; textures using it are ignored");
      }
    }
    // How many distinct tandem textures will take each decoded image, so
    // the last one can take the pixels instead of copying them.
    std::set<std::tuple<int, int, int, bool>> keys;
    for (int t : referenced_textures()) {
      if (t >= 0 && m.textures[size_t(t)].source >= 0) keys.insert(texture_key(t));
    }
    image_users_.assign(m.images.size(), 0);
    for (const auto& k : keys)
      ++image_users_[size_t(std::get<0>(k))];
  }

  std::string budget_message(uint32_t w, uint32_t h, uint64_t bytes) const {
    return "its " + std::to_string(w) + "x" + std::to_string(h) + " pixels need " +
           format_bytes(bytes) + ", and the textures already take " +
           format_bytes(ctx_.used(Budget::kTextureBytes)) + " of this loader's limit of " +
           format_bytes(ctx_.limits.max_texture_bytes);
  }

  // Textures that show the same decoded image with the same sampling share
  // one tandem texture.
  std::tuple<int, int, int, bool> texture_key(int t) const {
    const tinygltf::Model& m = ctx_.model;
    const tinygltf::Texture& gt = m.textures[size_t(t)];
    int wrap_s = TINYGLTF_TEXTURE_WRAP_REPEAT, wrap_t = TINYGLTF_TEXTURE_WRAP_REPEAT;
    bool nearest = false;
    if (gt.sampler >= 0) {
      const tinygltf::Sampler& s = m.samplers[size_t(gt.sampler)];
      wrap_s = s.wrapS;
      wrap_t = s.wrapT;
      nearest = s.magFilter == TINYGLTF_TEXTURE_FILTER_NEAREST;
    }
    return {canonical_[size_t(gt.source)], wrap_s, wrap_t, nearest};
  }

  // Tandem texture for glTF texture `t`, created on first use; -1 when its
  // image is unavailable.
  int32_t texture(int t) {
    if (texture_map_[size_t(t)] != kNotCreated) return texture_map_[size_t(t)];
    const tinygltf::Model& m = ctx_.model;
    const tinygltf::Texture& gt = m.textures[size_t(t)];
    int32_t id = -1;
    if (gt.source < 0) {
      ctx_.warn(
          "texture " + std::to_string(t) +
          " has no PNG/JPEG source (e.g. KTX2/WebP via an extension, which is not supported); "
          "it is ignored");
    } else if (const auto key = texture_key(t); texture_by_key_.count(key)) {
      id = texture_by_key_[key];
    } else if (const int source = std::get<0>(key); decoded_[size_t(source)].ok) {
      DecodedImage& img = decoded_[size_t(source)];
      Texture out;
      const tinygltf::Image& gi = m.images[size_t(gt.source)];
      out.name = gt.name;
      if (out.name.empty()) out.name = gi.name;
      if (out.name.empty() && gi.uri.rfind("data:", 0) != 0) out.name = gi.uri;
      if (out.name.empty()) out.name = "texture " + std::to_string(t);
      out.width = img.width;
      out.height = img.height;
      // Several glTF textures may show an image with different samplers;
      // all but the last take a copy, which counts against the budget.
      bool have_pixels = true;
      if (--image_users_[size_t(source)] == 0) {
        out.rgba8 = std::move(img.rgba8);
      } else {
        const uint64_t bytes = uint64_t(img.rgba8.size()) * 4;
        if (ctx_.fits(Budget::kTextureBytes, bytes)) {
          ctx_.charge(Budget::kTextureBytes, bytes, "texture " + std::to_string(t));
          out.rgba8 = img.rgba8;
        } else {
          ctx_.warn("texture " + std::to_string(t) + " is ignored: a copy of " +
                    image_label(m, source) + " for its sampler settings does not fit: " +
                    budget_message(img.width, img.height, bytes));
          have_pixels = false;
        }
      }
      if (have_pixels) {
        const auto [s_wrap, t_wrap, nearest] =
            std::tuple(std::get<1>(key), std::get<2>(key), std::get<3>(key));
        auto wrap = [](int w) {
          return w == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE     ? WrapMode::kClampToEdge
                 : w == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT ? WrapMode::kMirroredRepeat
                                                              : WrapMode::kRepeat;
        };
        out.wrap_s = wrap(s_wrap);
        out.wrap_t = wrap(t_wrap);
        out.nearest = nearest;
        id = int32_t(result_.textures.size());
        result_.textures.push_back(std::move(out));
        texture_by_key_[key] = id;
      }
    }
    texture_map_[size_t(t)] = id;
    return id;
  }

  // A texture reference: index, texCoord and the reference's extensions
  // (for KHR_texture_transform).
  TextureRef reference(int index, int tex_coord, const Value* transform, const std::string& who) {
    TextureRef ref;
    if (index < 0) return ref;
    ref.texture = texture(index);
    int uv = tex_coord;
    if (transform != nullptr) {
      double v[2];
      if (numbers(ctx_, transform, "offset", 2, v, who + " KHR_texture_transform")) {
        ref.transform.offset = glm::vec2(float(v[0]), float(v[1]));
      }
      if (numbers(ctx_, transform, "scale", 2, v, who + " KHR_texture_transform")) {
        ref.transform.scale = glm::vec2(float(v[0]), float(v[1]));
      }
      ref.transform.rotation =
          float(number(ctx_, transform, "rotation", 0.0, who + " KHR_texture_transform"));
      if (const Value* tc = member(transform, "texCoord"); tc != nullptr) {
        if (!tc->IsInt() || tc->Get<int>() < 0) {
          ctx_.fail(who + " KHR_texture_transform texCoord must be a non-negative integer");
        }
        uv = tc->Get<int>();
      }
    }
    if (uv > 1) {
      ctx_.warn_once("texcoord",
                     who + " (and possibly others) uses TEXCOORD_" + std::to_string(uv) +
                         "; only TEXCOORD_0 and TEXCOORD_1 are supported, using TEXCOORD_0");
      uv = 0;
    }
    ref.transform.uv_set = uint32_t(uv);
    return ref;
  }

  TextureRef reference(const tinygltf::TextureInfo& info, const std::string& who) {
    return reference(info.index, info.texCoord, extension(info.extensions, "KHR_texture_transform"),
                     who);
  }

  // A texture object inside a material extension (a JSON Value).
  TextureRef reference(const Value* info, const std::string& who) {
    if (info == nullptr) return {};
    const Value* tc = member(info, "texCoord");
    return reference(member(info, "index")->Get<int>(), tc != nullptr ? tc->Get<int>() : 0,
                     member(member(info, "extensions"), "KHR_texture_transform"), who);
  }

  float unit(double v, const std::string& who) {
    if (v < 0.0 || v > 1.0) {
      ctx_.warn_once("clamp", who + " (and possibly others) is outside [0, 1] and was clamped");
    }
    return float(std::clamp(v, 0.0, 1.0));
  }

  Material convert(const tinygltf::Material& gm, const std::string& who) {
    Material out;
    out.name = gm.name.empty() ? who : gm.name;
    const auto& pbr = gm.pbrMetallicRoughness;
    for (int k = 0; k < 4; ++k)
      out.base_color[k] = unit(pbr.baseColorFactor[size_t(k)], who + " baseColorFactor");
    out.metallic = unit(pbr.metallicFactor, who + " metallicFactor");
    out.roughness = unit(pbr.roughnessFactor, who + " roughnessFactor");
    for (int k = 0; k < 3; ++k)
      out.emissive[k] = unit(gm.emissiveFactor[size_t(k)], who + " emissiveFactor");
    out.alpha_mode = gm.alphaMode == "MASK"    ? AlphaMode::kMask
                     : gm.alphaMode == "BLEND" ? AlphaMode::kBlend
                                               : AlphaMode::kOpaque;
    out.alpha_cutoff = float(gm.alphaCutoff);
    out.double_sided = gm.doubleSided;
    out.normal_scale = float(gm.normalTexture.scale);
    out.base_color_texture = reference(pbr.baseColorTexture, who + " baseColorTexture");
    out.metallic_roughness_texture =
        reference(pbr.metallicRoughnessTexture, who + " metallicRoughnessTexture");
    out.normal_texture = reference(gm.normalTexture.index, gm.normalTexture.texCoord,
                                   extension(gm.normalTexture.extensions, "KHR_texture_transform"),
                                   who + " normalTexture");
    out.emissive_texture = reference(gm.emissiveTexture, who + " emissiveTexture");

    if (const Value* e = extension(gm.extensions, "KHR_materials_emissive_strength")) {
      const std::string ewho = who + " KHR_materials_emissive_strength";
      const double s = number(ctx_, e, "emissiveStrength", 1.0, ewho);
      if (s < 0.0) ctx_.fail(ewho + " emissiveStrength must be >= 0");
      out.emissive_strength = float(s);
    }
    if (const Value* e = extension(gm.extensions, "KHR_materials_transmission")) {
      const std::string ewho = who + " KHR_materials_transmission";
      out.transmission =
          unit(number(ctx_, e, "transmissionFactor", 0.0, ewho), ewho + " transmissionFactor");
      out.transmission_texture =
          reference(member(e, "transmissionTexture"), ewho + " transmissionTexture");
    }
    if (const Value* e = extension(gm.extensions, "KHR_materials_ior")) {
      const std::string ewho = who + " KHR_materials_ior";
      double ior = number(ctx_, e, "ior", 1.5, ewho);
      if (ior < 1.0) {
        ctx_.warn(ewho + " ior " + std::to_string(ior) + " is below 1; using 1");
        ior = 1.0;
      }
      out.ior = float(ior);
    }
    if (const Value* e = extension(gm.extensions, "KHR_materials_specular")) {
      const std::string ewho = who + " KHR_materials_specular";
      out.specular = unit(number(ctx_, e, "specularFactor", 1.0, ewho), ewho + " specularFactor");
      double c[3];
      if (numbers(ctx_, e, "specularColorFactor", 3, c, ewho)) {
        // Colours above 1 are allowed by the extension but our BSDF is only
        // energy-conserving up to 1.
        for (int k = 0; k < 3; ++k)
          out.specular_color[k] = float(std::clamp(c[k], 0.0, 1.0));
      }
      if (member(e, "specularTexture") != nullptr || member(e, "specularColorTexture") != nullptr) {
        ctx_.warn_once("spectex",
                       ewho + " (and possibly others) has specular textures, which are ignored");
      }
    }
    convert_layers(gm, who, out);
    return out;
  }

  // KHR_materials_clearcoat and KHR_materials_sheen (defaults: no layer).
  void convert_layers(const tinygltf::Material& gm, const std::string& who, Material& out) {
    if (const Value* e = extension(gm.extensions, "KHR_materials_clearcoat")) {
      const std::string ewho = who + " KHR_materials_clearcoat";
      out.clearcoat =
          unit(number(ctx_, e, "clearcoatFactor", 0.0, ewho), ewho + " clearcoatFactor");
      out.clearcoat_roughness = unit(number(ctx_, e, "clearcoatRoughnessFactor", 0.0, ewho),
                                     ewho + " clearcoatRoughnessFactor");
      out.clearcoat_texture = reference(member(e, "clearcoatTexture"), ewho + " clearcoatTexture");
      out.clearcoat_roughness_texture =
          reference(member(e, "clearcoatRoughnessTexture"), ewho + " clearcoatRoughnessTexture");
      if (member(e, "clearcoatNormalTexture") != nullptr) {
        ctx_.warn_once("coatnormal", ewho +
                                         " (and possibly others) has a clearcoatNormalTexture, "
                                         "which is ignored: the coat uses the base's normal");
      }
    }
    if (const Value* e = extension(gm.extensions, "KHR_materials_sheen")) {
      const std::string ewho = who + " KHR_materials_sheen";
      double c[3];
      if (numbers(ctx_, e, "sheenColorFactor", 3, c, ewho)) {
        for (int k = 0; k < 3; ++k)
          out.sheen_color[k] = unit(c[k], ewho + " sheenColorFactor");
      }
      out.sheen_roughness =
          unit(number(ctx_, e, "sheenRoughnessFactor", 0.0, ewho), ewho + " sheenRoughnessFactor");
      out.sheen_color_texture =
          reference(member(e, "sheenColorTexture"), ewho + " sheenColorTexture");
      out.sheen_roughness_texture =
          reference(member(e, "sheenRoughnessTexture"), ewho + " sheenRoughnessTexture");
    }
  }

  Context& ctx_;
  const EncodedImages& encoded_;
  std::vector<DecodedImage> decoded_;
  std::vector<int> canonical_;  // image index -> first image with the same bytes
  std::map<std::tuple<int, int, int, bool>, int32_t> texture_by_key_;
  std::vector<int32_t> texture_map_;
  std::vector<int> image_users_;
  MaterialResult result_;
};

// One channel as 8 bits: a byte as it is, a 16-bit value (in the host's
// byte order, as stb and so tinygltf store it) rounded to the nearest of 255
// steps.
template <int kBytes>
inline uint32_t channel8(const unsigned char* p) {
  if constexpr (kBytes == 1) {
    return *p;
  } else {
    uint16_t v;
    std::memcpy(&v, p, 2);
    return (uint32_t(v) * 255u + 32767u) / 65535u;
  }
}

// The conversion for one layout, so the pixel loop has no per-channel
// decisions left: FlightHelmet's 8-bit images took about 15 instructions a
// pixel through a per-channel lambda (a tenth of decoding them), a few here.
template <int kChannels, int kBytes>
void to_rgba8(const unsigned char* src, size_t pixels, uint32_t* out) {
  constexpr size_t kStride = size_t(kChannels) * kBytes;
  for (size_t i = 0; i < pixels; ++i) {
    const unsigned char* p = src + i * kStride;
    uint32_t r, g, b, a = 255;
    if constexpr (kChannels <= 2) {
      r = g = b = channel8<kBytes>(p);  // grey
      if constexpr (kChannels == 2) a = channel8<kBytes>(p + kBytes);
    } else {
      r = channel8<kBytes>(p);
      g = channel8<kBytes>(p + kBytes);
      b = channel8<kBytes>(p + 2 * kBytes);
      if constexpr (kChannels == 4) a = channel8<kBytes>(p + 3 * kBytes);
    }
    out[i] = r | (g << 8) | (b << 16) | (a << 24);
  }
}

template <int kBytes>
void to_rgba8(int channels, const unsigned char* src, size_t pixels, uint32_t* out) {
  switch (channels) {
    case 1:
      return to_rgba8<1, kBytes>(src, pixels, out);
    case 2:
      return to_rgba8<2, kBytes>(src, pixels, out);
    case 3:
      return to_rgba8<3, kBytes>(src, pixels, out);
    default:
      return to_rgba8<4, kBytes>(src, pixels, out);
  }
}

}  // namespace

bool pixels_to_rgba8(const unsigned char* data, size_t size, int width, int height, int channels,
                     int bits, std::vector<uint32_t>& out) {
  const int bytes = bits / 8;
  if (width < 1 || height < 1 || channels < 1 || channels > 4 || (bits != 8 && bits != 16)) {
    return false;
  }
  const size_t pixels = size_t(width) * size_t(height);
  if (size != pixels * size_t(channels) * size_t(bytes)) return false;
  out.resize(pixels);
  if (bytes == 1) {
    to_rgba8<1>(channels, data, pixels, out.data());
  } else {
    to_rgba8<2>(channels, data, pixels, out.data());
  }
  return true;
}

bool image_to_rgba8(const tinygltf::Image& image, std::vector<uint32_t>& out) {
  return pixels_to_rgba8(image.image.data(), image.image.size(), image.width, image.height,
                         image.component, image.bits, out);
}

void EncodedImages::keep(int index, const unsigned char* data, size_t size) {
  for (const auto& [other, bytes] : by_image) {
    if (bytes.size() == size && std::memcmp(bytes.data(), data, size) == 0) {
      same_as[index] = other;
      return;
    }
  }
  by_image[index].assign(data, data + size);
}

const std::vector<unsigned char>* EncodedImages::bytes(int index) const {
  if (const auto alias = same_as.find(index); alias != same_as.end()) index = alias->second;
  const auto it = by_image.find(index);
  return it == by_image.end() ? nullptr : &it->second;
}

MaterialResult convert_materials(Context& ctx, const EncodedImages& encoded) {
  return MaterialConverter(ctx, encoded).run();
}

}  // namespace tandem::gltf
