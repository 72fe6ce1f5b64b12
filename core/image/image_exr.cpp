// OpenEXR reading and writing through the OpenEXR library.
//
// Two halves of the library, each for what it does best. The C core
// (OpenEXRCore) parses headers from memory without touching pixels and
// without exceptions, and reports through a handler instead of printing:
// it tells which part and layer to read and how large it is, and that is
// judged against the caller's limits first. The C++ library then decodes
// the pixels, because in the Debian version (3.1) only it implements every
// compression (the core lacks DWAA/DWAB). Everything the library throws
// becomes an InputError naming the file.
#include "core/image/image_exr.h"

#include <ImfChannelList.h>
#include <ImfCompression.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfInputPart.h>
#include <ImfMultiPartInputFile.h>
#include <ImfOutputFile.h>
#include <half.h>
#include <openexr.h>

#include <algorithm>
#include <cstring>
#include <exception>
#include <new>
#include <string>
#include <vector>

#include "core/util/errors.h"
#include "core/util/log.h"

namespace tandem {

namespace {

// ---------------------------------------------------------------- header

// Every attribute of every header must fit in the file. The C++ reader
// allocates an attribute of a type it does not know at its declared size
// before reading it (the fuzzer made a 2 KB file ask for 800 MB); the C core
// skips such an attribute without that check. So the headers are walked
// here first: name, type name, size, value; an empty name ends a header,
// and in a multi-part file an empty header ends the list.
void check_attribute_sizes(const uint8_t* data, size_t size, const std::string& name) {
  if (size < 8) fail_image(name, "OpenEXR file is truncated in its header");
  uint32_t version;
  std::memcpy(&version, data + 4, 4);
  const bool multipart = (version & 0x1000u) != 0;
  size_t pos = 8;
  auto read_name = [&](const char* what) {
    const size_t start = pos;
    while (pos < size && data[pos] != 0)
      ++pos;
    if (pos >= size) fail_image(name, std::string("OpenEXR header is truncated in ") + what);
    ++pos;
    return pos - 1 - start;
  };
  while (true) {
    size_t attributes = 0;
    while (true) {
      if (read_name("an attribute name") == 0) break;
      read_name("an attribute type");
      if (size - pos < 4) fail_image(name, "OpenEXR header is truncated in an attribute size");
      int32_t bytes;
      std::memcpy(&bytes, data + pos, 4);
      pos += 4;
      if (bytes < 0 || uint64_t(bytes) > size - pos) {
        fail_image(name, "OpenEXR header has an attribute of " + std::to_string(bytes) +
                             " bytes, more than the rest of the file (" +
                             std::to_string(size - pos) + " bytes)");
      }
      pos += size_t(bytes);
      ++attributes;
    }
    // A single-part file has one header; a multi-part list ends with an
    // empty header (its terminating zero byte was read as an empty name).
    if (!multipart || attributes == 0) return;
  }
}

struct CoreStream {
  const uint8_t* data;
  size_t size;
  std::string error;  // the core's last message
};

int64_t core_read(exr_const_context_t, void* user, void* buffer, uint64_t bytes, uint64_t offset,
                  exr_stream_error_func_ptr_t) {
  const auto* s = static_cast<const CoreStream*>(user);
  if (offset >= s->size) return 0;
  const uint64_t n = std::min<uint64_t>(bytes, s->size - offset);
  std::memcpy(buffer, s->data + offset, size_t(n));
  return int64_t(n);
}

int64_t core_size(exr_const_context_t, void* user) {
  return int64_t(static_cast<const CoreStream*>(user)->size);
}

void core_error(exr_const_context_t ctxt, exr_result_t, const char* message) {
  void* user = nullptr;
  if (exr_get_user_data(ctxt, &user) == EXR_ERR_SUCCESS && user != nullptr) {
    static_cast<CoreStream*>(user)->error = message != nullptr ? message : "";
  }
}

// The layer of one part that becomes the image: channel names for R, G, B
// (G and B may be empty: a grey image from R or Y).
struct ExrChoice {
  int part = -1;
  std::string layer;  // "" for the unnamed layer, else e.g. "ViewLayer.Combined"
  std::string r, g, b;
  int32_t min_x = 0, min_y = 0;
  uint64_t width = 0, height = 0;
  std::vector<std::string> ignored;  // other parts' and layers' names, for the notice
};

std::string layer_of(const std::string& channel) {
  const size_t dot = channel.rfind('.');
  return dot == std::string::npos ? std::string() : channel.substr(0, dot);
}

std::string part_label(exr_const_context_t ctxt, int part) {
  const char* name = nullptr;
  if (exr_get_name(ctxt, part, &name) == EXR_ERR_SUCCESS && name != nullptr && *name) {
    return "part '" + std::string(name) + "'";
  }
  return "part " + std::to_string(part);
}

// Picks the part and layer from the header alone. Within a part the
// unnamed layer (plain R, G, B) comes first, then one whose name has
// "Combined" (Blender's beauty pass), then the first in name order.
ExrChoice choose_layer(exr_const_context_t ctxt, const std::string& name) {
  int parts = 0;
  if (exr_get_count(ctxt, &parts) != EXR_ERR_SUCCESS || parts < 1) {
    fail_image(name, "OpenEXR file has no image parts");
  }
  ExrChoice choice;
  std::string why_none;
  for (int p = 0; p < parts; ++p) {
    exr_storage_t storage;
    if (exr_get_storage(ctxt, p, &storage) != EXR_ERR_SUCCESS) continue;
    if (storage == EXR_STORAGE_DEEP_SCANLINE || storage == EXR_STORAGE_DEEP_TILED) {
      if (why_none.empty()) why_none = "deep-data parts hold no flat image";
      if (choice.part >= 0) choice.ignored.push_back(part_label(ctxt, p) + " (deep data)");
      continue;
    }
    const exr_attr_chlist_t* channels = nullptr;
    exr_attr_box2i_t window;
    if (exr_get_channels(ctxt, p, &channels) != EXR_ERR_SUCCESS || channels == nullptr ||
        exr_get_data_window(ctxt, p, &window) != EXR_ERR_SUCCESS) {
      continue;
    }
    std::vector<std::string> names;
    for (int c = 0; c < channels->num_channels; ++c) {
      const exr_attr_chlist_entry_t& e = channels->entries[c];
      names.emplace_back(e.name.str != nullptr ? std::string(e.name.str, size_t(e.name.length))
                                               : std::string());
    }
    auto find = [&](const std::string& n) -> const exr_attr_chlist_entry_t* {
      for (size_t c = 0; c < names.size(); ++c)
        if (names[c] == n) return &channels->entries[c];
      return nullptr;
    };
    // Layers with colour: a prefix P ("" or "A.B") with P.R or P.Y.
    std::vector<std::string> layers;
    for (const std::string& n : names) {
      const std::string layer = layer_of(n);
      const std::string base = n.substr(layer.empty() ? 0 : layer.size() + 1);
      if ((base == "R" || base == "Y") &&
          std::find(layers.begin(), layers.end(), layer) == layers.end()) {
        layers.push_back(layer);
      }
    }
    if (layers.empty()) {
      if (why_none.empty()) {
        why_none = "no R, G, B or Y channel (it has " + std::to_string(names.size()) +
                   (names.empty() ? " channels)" : " channels, the first '" + names[0] + "')");
      }
      continue;
    }
    auto rank = [](const std::string& l) {
      return l.empty() ? 0 : l.find("Combined") != std::string::npos ? 1 : 2;
    };
    std::stable_sort(layers.begin(), layers.end(),
                     [&](const std::string& a, const std::string& b) { return rank(a) < rank(b); });
    if (choice.part >= 0) {
      choice.ignored.push_back(part_label(ctxt, p));
      continue;
    }
    const std::string prefix = layers[0].empty() ? "" : layers[0] + ".";
    const bool rgb = find(prefix + "R") != nullptr;
    const std::string used[3] = {prefix + (rgb ? "R" : "Y"), rgb ? prefix + "G" : "",
                                 rgb ? prefix + "B" : ""};
    for (const std::string& n : used) {
      const exr_attr_chlist_entry_t* e = n.empty() ? nullptr : find(n);
      if (e == nullptr) continue;
      if (e->x_sampling != 1 || e->y_sampling != 1) {
        fail_image(name, "OpenEXR channel '" + n + "' is subsampled, which is not supported");
      }
      if (e->pixel_type != EXR_PIXEL_HALF && e->pixel_type != EXR_PIXEL_FLOAT) {
        fail_image(name, "OpenEXR channel '" + n +
                             "' holds unsigned integers (an ID or mask), not half or float colour");
      }
    }
    choice.part = p;
    choice.layer = layers[0];
    choice.r = used[0];
    choice.g = find(used[1]) != nullptr ? used[1] : "";
    choice.b = find(used[2]) != nullptr ? used[2] : "";
    const int64_t w = int64_t(window.max.x) - window.min.x + 1;
    const int64_t h = int64_t(window.max.y) - window.min.y + 1;
    if (w <= 0 || h <= 0) {
      fail_image(name, "OpenEXR data window is empty (" + std::to_string(std::max<int64_t>(w, 0)) +
                           "x" + std::to_string(std::max<int64_t>(h, 0)) + ")");
    }
    choice.min_x = window.min.x;
    choice.min_y = window.min.y;
    choice.width = uint64_t(w);
    choice.height = uint64_t(h);
    for (size_t l = 1; l < layers.size(); ++l)
      choice.ignored.push_back("layer '" + layers[l] + "'");
    bool has_chroma = false;  // a Y image with chroma: RY/BY are not read
    for (const std::string& n : names)
      has_chroma |= n == prefix + "RY" || n == prefix + "BY";
    if (!rgb && has_chroma) choice.ignored.push_back("chroma channels RY and BY (read as grey)");
  }
  if (choice.part < 0) fail_image(name, "OpenEXR file has no colour image: " + why_none);
  return choice;
}

// Every chunk of the chosen part (its offset-table entry and its leader)
// must lie in the file, with its data, before pixel memory is allocated:
// a header alone cannot make the reader allocate and zero a large image.
// The core reads only the table and the leaders, never the pixel data.
void check_chunks(exr_const_context_t ctxt, const ExrChoice& choice, const CoreStream& stream,
                  const std::string& name) {
  exr_storage_t storage;
  exr_get_storage(ctxt, choice.part, &storage);
  const std::string image = std::to_string(choice.width) + "x" + std::to_string(choice.height);
  auto check = [&](exr_result_t result, const exr_chunk_info_t& info, const std::string& what) {
    if (result == EXR_ERR_SUCCESS && info.data_offset <= stream.size &&
        info.packed_size <= stream.size - info.data_offset) {
      return;
    }
    std::string why = stream.error.empty() ? exr_get_default_error_message(result) : stream.error;
    if (result == EXR_ERR_SUCCESS) why = "its data runs past the end of the file";
    fail_image(name, "file is truncated or corrupt: the " + image + " OpenEXR image's " + what +
                         " is not in the file (" + why + ")");
  };
  exr_chunk_info_t info{};
  if (storage == EXR_STORAGE_TILED) {
    uint32_t tile_w = 0, tile_h = 0;
    exr_tile_level_mode_t levels;
    exr_tile_round_mode_t round;
    if (exr_get_tile_descriptor(ctxt, choice.part, &tile_w, &tile_h, &levels, &round) !=
            EXR_ERR_SUCCESS ||
        tile_w == 0 || tile_h == 0) {
      fail_image(name, "OpenEXR tiled part has no valid tile description");
    }
    // The reader holds buffers of whole tiles: a tile far larger than the
    // image would make a small file allocate gigabytes.
    const uint64_t tile_pixels = uint64_t(tile_w) * tile_h;
    if (tile_pixels > std::max<uint64_t>(uint64_t(1) << 20, choice.width * choice.height)) {
      fail_image(name, "OpenEXR tiles of " + std::to_string(tile_w) + "x" + std::to_string(tile_h) +
                           " pixels are larger than the " + image + " image they tile");
    }
    const uint64_t tiles_x = (choice.width + tile_w - 1) / tile_w;
    const uint64_t tiles_y = (choice.height + tile_h - 1) / tile_h;
    for (uint64_t ty = 0; ty < tiles_y; ++ty) {
      for (uint64_t tx = 0; tx < tiles_x; ++tx) {
        const exr_result_t r =
            exr_read_tile_chunk_info(ctxt, choice.part, int(tx), int(ty), 0, 0, &info);
        check(r, info, "tile " + std::to_string(tx) + "," + std::to_string(ty));
      }
    }
    return;
  }
  int32_t lines = 0;
  if (exr_get_scanlines_per_chunk(ctxt, choice.part, &lines) != EXR_ERR_SUCCESS || lines < 1) {
    fail_image(name, "OpenEXR part has no valid compression");
  }
  const int64_t end = int64_t(choice.min_y) + int64_t(choice.height);
  for (int64_t y = choice.min_y; y < end; y += lines) {
    const exr_result_t r = exr_read_scanline_chunk_info(ctxt, choice.part, int(y), &info);
    check(r, info, "scanline block at y " + std::to_string(y));
  }
}

// ----------------------------------------------------------------- pixels

class MemoryInput : public Imf::IStream {
 public:
  MemoryInput(const std::string& name, const uint8_t* data, size_t size)
      : Imf::IStream(name.c_str()), data_(data), size_(size) {}
  bool isMemoryMapped() const override { return true; }
  char* readMemoryMapped(int n) override {
    need(n);
    char* p = reinterpret_cast<char*>(const_cast<uint8_t*>(data_ + pos_));
    pos_ += size_t(n);
    return p;
  }
  bool read(char c[], int n) override {
    need(n);
    std::memcpy(c, data_ + pos_, size_t(n));
    pos_ += size_t(n);
    return pos_ < size_;
  }
  uint64_t tellg() override { return pos_; }
  void seekg(uint64_t pos) override { pos_ = size_t(std::min<uint64_t>(pos, size_)); }

 private:
  void need(int n) const {
    if (n < 0 || size_t(n) > size_ - pos_) throw std::runtime_error("the file is truncated");
  }
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
};

class MemoryOutput : public Imf::OStream {
 public:
  explicit MemoryOutput(std::vector<uint8_t>& out) : Imf::OStream("memory"), out_(out) {}
  void write(const char c[], int n) override {
    if (pos_ + size_t(n) > out_.size()) out_.resize(pos_ + size_t(n));
    std::memcpy(out_.data() + pos_, c, size_t(n));
    pos_ += size_t(n);
  }
  uint64_t tellp() override { return pos_; }
  void seekp(uint64_t pos) override { pos_ = size_t(pos); }

 private:
  std::vector<uint8_t>& out_;
  size_t pos_ = 0;
};

}  // namespace

ImageRGB decode_exr(const uint8_t* data, size_t size, const std::string& name,
                    const ImageReadLimits& limits) {
  check_attribute_sizes(data, size, name);
  CoreStream stream{data, size, {}};
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  init.user_data = &stream;
  init.read_fn = core_read;
  init.size_fn = core_size;
  init.error_handler_fn = core_error;
  ExrChoice choice;
  {
    exr_context_t ctxt = nullptr;
    struct Finish {  // the core's context ends with this scope, however it is left
      exr_context_t& ctxt;
      ~Finish() { exr_finish(&ctxt); }
    } finish{ctxt};
    if (exr_start_read(&ctxt, name.c_str(), &init) != EXR_ERR_SUCCESS) {
      const std::string why = stream.error.empty() ? "unreadable header" : stream.error;
      fail_image(name, "not a valid OpenEXR file: " + why);
    }
    choice = choose_layer(ctxt, name);
    check_image_pixels(name, "OpenEXR", choice.width, choice.height, limits);
    check_chunks(ctxt, choice, stream, name);
  }
  if (!choice.ignored.empty()) {
    std::string others;
    for (const std::string& i : choice.ignored)
      others += (others.empty() ? "" : ", ") + i;
    const std::string layer =
        choice.layer.empty() ? "the unnamed layer" : "layer '" + choice.layer + "'";
    log_warning(name + ": reading " + layer + " of part " + std::to_string(choice.part) +
                "; not read: " + others);
  }

  ImageRGB img{uint32_t(choice.width), uint32_t(choice.height)};
  try {
    MemoryInput in(name, data, size);
    // No chunk table reconstruction: a file whose table is damaged is an
    // error, not a scan of the whole file for chunks.
    Imf::MultiPartInputFile file(in, Imf::globalThreadCount(), false);
    Imf::InputPart part(file, choice.part);
    const Imath::V2i origin(choice.min_x, choice.min_y);
    Imf::FrameBuffer frame;
    const std::string* sources[3] = {&choice.r, &choice.g, &choice.b};
    for (int c = 0; c < 3; ++c) {
      if (sources[c]->empty()) continue;
      frame.insert(*sources[c],
                   Imf::Slice::Make(Imf::FLOAT, img.rgb.data() + c, origin, int64_t(choice.width),
                                    int64_t(choice.height), 3 * sizeof(float),
                                    3 * sizeof(float) * choice.width));
    }
    part.setFrameBuffer(frame);
    part.readPixels(choice.min_y, choice.min_y + int(choice.height) - 1);
  } catch (const std::bad_alloc&) {
    fail_image(name, "not enough memory to decode the OpenEXR image");
  } catch (const std::exception& e) {
    fail_image(name, std::string("cannot decode OpenEXR data: ") + e.what());
  }
  if (choice.g.empty() || choice.b.empty()) {  // grey: copy R (or Y) to the missing channels
    for (size_t i = 0; i < img.rgb.size(); i += 3) {
      if (choice.g.empty()) img.rgb[i + 1] = img.rgb[i];
      if (choice.b.empty()) img.rgb[i + 2] = img.rgb[i];
    }
  }
  return img;
}

std::vector<uint8_t> encode_exr(const ImageRGB& image, ExrPixelType pixel_type,
                                ExrCompression compression) {
  static_assert(int(ExrCompression::kDwab) == int(Imf::DWAB_COMPRESSION));
  Imf::Header header(int(image.width), int(image.height));
  header.compression() = Imf::Compression(int(compression));
  // Frame buffer and file agree on the type: the library converts types
  // when it reads, not when it writes.
  const bool half = pixel_type == ExrPixelType::kHalf;
  std::vector<Imath::half> halves;
  if (half) halves.assign(image.rgb.begin(), image.rgb.end());
  char* base = half ? reinterpret_cast<char*>(halves.data())
                    : reinterpret_cast<char*>(const_cast<float*>(image.rgb.data()));
  const size_t bytes_per_value = half ? sizeof(Imath::half) : sizeof(float);
  Imf::FrameBuffer frame;
  const char* names[3] = {"R", "G", "B"};
  for (int c = 0; c < 3; ++c) {
    const Imf::PixelType type = half ? Imf::HALF : Imf::FLOAT;
    header.channels().insert(names[c], Imf::Channel(type));
    frame.insert(names[c], Imf::Slice(type, base + c * bytes_per_value, 3 * bytes_per_value,
                                      3 * bytes_per_value * image.width));
  }
  std::vector<uint8_t> bytes;
  MemoryOutput out(bytes);
  {
    // The file writes its chunk offset table when it closes.
    Imf::OutputFile file(out, header);
    file.setFrameBuffer(frame);
    file.writePixels(int(image.height));
  }
  return bytes;
}

}  // namespace tandem
