// Image file formats. EXR and PFM are written and read by our own small
// codecs (uncompressed float scanlines are all Tandem needs, and this keeps
// OpenEXR out of the dependency list); PNG/HDR/JPEG go through stb.
#include <stb_image.h>
#include <stb_image_write.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>

#include "core/image/image.h"
#include "core/kernel/texture.h"
#include "core/util/errors.h"

namespace tandem {
namespace fs = std::filesystem;

namespace {

std::string lower_extension(const fs::path& p) {
  std::string ext = p.extension().string();
  for (char& c : ext)
    c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

}  // namespace

// Writes bytes to a temporary sibling and renames it over `path`.
void write_file_atomically(const fs::path& path, const std::vector<uint8_t>& bytes) {
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    throw InputError(path.string() + ": cannot write: directory '" + dir.string() +
                     "' does not exist");
  }
  const fs::path tmp =
      dir / ("." + path.filename().string() + ".tmp." + std::to_string(::getpid()));
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) throw InputError(path.string() + ": cannot write: " + std::strerror(errno));
  const bool ok = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  const bool flushed = std::fflush(f) == 0 && ::fsync(fileno(f)) == 0;
  const bool closed = std::fclose(f) == 0;
  if (!ok || !flushed || !closed) {
    const std::string reason = std::strerror(errno);
    fs::remove(tmp, ec);
    throw InputError(path.string() + ": write failed: " + reason);
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw InputError(path.string() + ": cannot replace file: " + ec.message());
  }
}

namespace {

template <class T>
void put(std::vector<uint8_t>& out, T v) {
  const size_t at = out.size();
  out.resize(at + sizeof(T));
  std::memcpy(out.data() + at, &v, sizeof(T));
}
void put_str(std::vector<uint8_t>& out, const char* s) {
  out.insert(out.end(), s, s + std::strlen(s) + 1);
}

void put_attribute_header(std::vector<uint8_t>& out, const char* name, const char* type,
                          int32_t size) {
  put_str(out, name);
  put_str(out, type);
  put(out, size);
}

// OpenEXR 2.0 single-part scanline file, NO_COMPRESSION, FLOAT B/G/R.
std::vector<uint8_t> encode_exr(const ImageRGB& img) {
  std::vector<uint8_t> out;
  put<uint32_t>(out, 20000630u);              // magic
  put<uint32_t>(out, 2u);                     // version 2, no flags
  const char* channels[3] = {"B", "G", "R"};  // channel list must be sorted
  put_attribute_header(out, "channels", "chlist", 3 * (2 + 16) + 1);
  for (const char* c : channels) {
    put_str(out, c);
    put<int32_t>(out, 2);   // FLOAT
    put<uint32_t>(out, 0);  // pLinear + reserved
    put<int32_t>(out, 1);
    put<int32_t>(out, 1);
  }
  out.push_back(0);
  put_attribute_header(out, "compression", "compression", 1);
  out.push_back(0);
  const int32_t box[4] = {0, 0, int32_t(img.width) - 1, int32_t(img.height) - 1};
  for (const char* name : {"dataWindow", "displayWindow"}) {
    put_attribute_header(out, name, "box2i", 16);
    for (int32_t v : box)
      put(out, v);
  }
  put_attribute_header(out, "lineOrder", "lineOrder", 1);
  out.push_back(0);
  put_attribute_header(out, "pixelAspectRatio", "float", 4);
  put(out, 1.0f);
  put_attribute_header(out, "screenWindowCenter", "v2f", 8);
  put(out, 0.0f);
  put(out, 0.0f);
  put_attribute_header(out, "screenWindowWidth", "float", 4);
  put(out, 1.0f);
  out.push_back(0);  // end of header

  const uint64_t line_bytes = uint64_t(img.width) * 3 * sizeof(float);
  const uint64_t table_end = out.size() + uint64_t(img.height) * 8;
  for (uint32_t y = 0; y < img.height; ++y)
    put<uint64_t>(out, table_end + y * (8 + line_bytes));
  for (uint32_t y = 0; y < img.height; ++y) {
    put<int32_t>(out, int32_t(y));
    put<uint32_t>(out, uint32_t(line_bytes));
    for (int c = 2; c >= 0; --c) {  // B, G, R
      for (uint32_t x = 0; x < img.width; ++x)
        put(out, img.pixel(x, y)[c]);
    }
  }
  return out;
}

// Portable float map: little-endian (negative scale), rows bottom to top.
std::vector<uint8_t> encode_pfm(const ImageRGB& img) {
  const std::string header =
      "PF\n" + std::to_string(img.width) + " " + std::to_string(img.height) + "\n-1.0\n";
  std::vector<uint8_t> out(header.begin(), header.end());
  out.reserve(out.size() + img.rgb.size() * 4);
  for (uint32_t row = 0; row < img.height; ++row) {
    const uint32_t y = img.height - 1 - row;
    for (uint32_t x = 0; x < img.width; ++x) {
      for (int c = 0; c < 3; ++c)
        put(out, img.pixel(x, y)[c]);
    }
  }
  return out;
}

std::vector<uint8_t> read_file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string() + ": cannot open file");
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                             std::istreambuf_iterator<char>());
  return bytes;
}

float half_to_float(uint16_t h) {
  const uint32_t sign = uint32_t(h >> 15) << 31;
  const uint32_t exp = (h >> 10) & 0x1fu;
  const uint32_t mant = h & 0x3ffu;
  float f;
  if (exp == 0) {
    f = std::ldexp(float(mant), -24);
  } else if (exp == 31) {
    f = mant ? NAN : INFINITY;
  } else {
    f = std::ldexp(float(mant | 0x400u), int(exp) - 25);
  }
  return sign ? -f : f;
}

class ByteReader {
 public:
  ByteReader(const std::vector<uint8_t>& b, const fs::path& p) : bytes_(b), path_(p) {}
  template <class T>
  T get() {
    need(sizeof(T));
    T v;
    std::memcpy(&v, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  std::string get_str() {
    std::string s;
    while (true) {
      need(1);
      const char c = char(bytes_[pos_++]);
      if (c == 0) return s;
      if (s.size() > 255) fail("attribute name too long");
      s.push_back(c);
    }
  }
  void need(size_t n) const {
    if (n > bytes_.size() || pos_ > bytes_.size() - n) fail("file is truncated");
  }
  [[noreturn]] void fail(const std::string& why) const {
    throw InputError(path_.string() + ": " + why);
  }
  size_t pos_ = 0;
  const std::vector<uint8_t>& bytes_;
  const fs::path& path_;
};

ImageRGB decode_exr(const std::vector<uint8_t>& bytes, const fs::path& path) {
  ByteReader r(bytes, path);
  if (r.get<uint32_t>() != 20000630u) r.fail("not an OpenEXR file (bad magic number)");
  const uint32_t version = r.get<uint32_t>();
  if ((version & 0xffu) != 2 || (version & 0x1e00u) != 0) {
    r.fail("only single-part scanline OpenEXR files are supported");
  }
  struct Channel {
    std::string name;
    int32_t type;
  };
  std::vector<Channel> channels;
  int compression = -1;
  int32_t box[4] = {0, 0, -1, -1};
  while (true) {
    const std::string name = r.get_str();
    if (name.empty()) break;
    const std::string type = r.get_str();
    const int32_t size = r.get<int32_t>();
    if (size < 0) r.fail("negative attribute size");
    r.need(size_t(size));
    const size_t end = r.pos_ + size_t(size);
    if (name == "channels") {
      while (true) {
        const std::string cname = r.get_str();
        if (cname.empty()) break;
        const int32_t ptype = r.get<int32_t>();
        r.get<uint32_t>();
        if (r.get<int32_t>() != 1 || r.get<int32_t>() != 1)
          r.fail("subsampled channels are not supported");
        channels.push_back({cname, ptype});
      }
    } else if (name == "compression") {
      compression = r.get<uint8_t>();
    } else if (name == "dataWindow") {
      for (int32_t& v : box)
        v = r.get<int32_t>();
    }
    r.pos_ = end;
  }
  if (compression != 0)
    r.fail("compressed OpenEXR files are not supported (save without compression)");
  const int64_t w = int64_t(box[2]) - box[0] + 1, h = int64_t(box[3]) - box[1] + 1;
  if (w <= 0 || h <= 0 || w > 65536 || h > 65536) r.fail("invalid data window");
  int src[3] = {-1, -1, -1};
  size_t pixel_bytes = 0;
  std::vector<size_t> channel_offset;
  for (size_t i = 0; i < channels.size(); ++i) {
    if (channels[i].type != 1 && channels[i].type != 2)
      r.fail("only half and float channels are supported");
    channel_offset.push_back(pixel_bytes);
    pixel_bytes += channels[i].type == 1 ? 2 : 4;
    if (channels[i].name == "R") src[0] = int(i);
    if (channels[i].name == "G") src[1] = int(i);
    if (channels[i].name == "B") src[2] = int(i);
  }
  if (src[0] < 0) r.fail("no R channel");
  ImageRGB img{uint32_t(w), uint32_t(h)};
  std::vector<uint64_t> offsets(static_cast<size_t>(h));
  for (auto& o : offsets)
    o = r.get<uint64_t>();
  for (int64_t line = 0; line < h; ++line) {
    r.pos_ = 0;
    if (offsets[size_t(line)] > bytes.size()) r.fail("scanline offset out of range");
    r.pos_ = size_t(offsets[size_t(line)]);
    const int32_t y = r.get<int32_t>() - box[1];
    const uint32_t size = r.get<uint32_t>();
    if (y < 0 || y >= h || uint64_t(size) != uint64_t(w) * pixel_bytes)
      r.fail("corrupt scanline block");
    r.need(size);
    const uint8_t* data = bytes.data() + r.pos_;
    for (int c = 0; c < 3; ++c) {
      const int ch = src[c] >= 0 ? src[c] : src[0];
      const uint8_t* base = data + channel_offset[size_t(ch)] * size_t(w);
      for (int64_t x = 0; x < w; ++x) {
        float v;
        if (channels[size_t(ch)].type == 2) {
          std::memcpy(&v, base + x * 4, 4);
        } else {
          uint16_t hv;
          std::memcpy(&hv, base + x * 2, 2);
          v = half_to_float(hv);
        }
        img.pixel(uint32_t(x), uint32_t(y))[c] = v;
      }
    }
  }
  return img;
}

ImageRGB decode_pfm(const std::vector<uint8_t>& bytes, const fs::path& path) {
  const std::string text(bytes.begin(), bytes.begin() + std::min<size_t>(bytes.size(), 128));
  char kind[3] = {};
  unsigned w = 0, h = 0;
  float scale = 0.0f;
  int consumed = 0;
  if (std::sscanf(text.c_str(), "%2s %u %u %f%n", kind, &w, &h, &scale, &consumed) != 4 ||
      (std::strcmp(kind, "PF") != 0 && std::strcmp(kind, "Pf") != 0) || w == 0 || h == 0 ||
      w > 65536 || h > 65536) {
    throw InputError(path.string() + ": not a valid PFM header");
  }
  const size_t data_start = size_t(consumed) + 1;
  const int comps = kind[1] == 'F' ? 3 : 1;
  const size_t need = size_t(w) * h * comps * 4;
  if (bytes.size() < data_start || bytes.size() - data_start < need) {
    throw InputError(path.string() + ": PFM pixel data is truncated");
  }
  const bool big_endian = scale > 0.0f;
  ImageRGB img(w, h);
  const uint8_t* p = bytes.data() + data_start;
  for (unsigned row = 0; row < h; ++row) {
    for (unsigned x = 0; x < w; ++x) {
      for (int c = 0; c < comps; ++c) {
        uint8_t b[4];
        std::memcpy(b, p, 4);
        p += 4;
        if (big_endian) std::swap(b[0], b[3]), std::swap(b[1], b[2]);
        float v;
        std::memcpy(&v, b, 4);
        float* px = img.pixel(x, h - 1 - row);
        if (comps == 3)
          px[c] = v;
        else
          px[0] = px[1] = px[2] = v;
      }
    }
  }
  return img;
}

}  // namespace

void write_png_rgb8(const fs::path& path, uint32_t width, uint32_t height,
                    const std::vector<uint8_t>& rgb) {
  std::vector<uint8_t> bytes;
  auto sink = [](void* ctx, void* data, int size) {
    auto* out = static_cast<std::vector<uint8_t>*>(ctx);
    out->insert(out->end(), static_cast<uint8_t*>(data), static_cast<uint8_t*>(data) + size);
  };
  if (!stbi_write_png_to_func(sink, &bytes, int(width), int(height), 3, rgb.data(),
                              int(width) * 3)) {
    throw InputError(path.string() + ": PNG encoding failed");
  }
  write_file_atomically(path, bytes);
}

void write_image(const fs::path& path, const ImageRGB& image, const ImageWriteOptions& options) {
  const std::string ext = lower_extension(path);
  if (ext == ".png") {
    write_png_rgb8(path, image.width, image.height,
                   tone_map_to_srgb8(image, options.exposure, options.tone_map));
  } else if (ext == ".exr") {
    write_file_atomically(path, encode_exr(image));
  } else if (ext == ".pfm") {
    write_file_atomically(path, encode_pfm(image));
  } else {
    throw InputError(path.string() + ": unsupported output format '" + ext +
                     "' (use .png, .exr or .pfm)");
  }
}

ImageRGB read_image(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError(path.string() + ": file not found");
  const std::string ext = lower_extension(path);
  const std::vector<uint8_t> bytes = read_file_bytes(path);
  if (bytes.empty()) throw InputError(path.string() + ": file is empty");
  if (ext == ".exr") return decode_exr(bytes, path);
  if (ext == ".pfm") return decode_pfm(bytes, path);
  int w = 0, h = 0, comp = 0;
  if (bytes.size() > size_t(INT32_MAX)) throw InputError(path.string() + ": file too large");
  if (ext == ".hdr") {
    float* data = stbi_loadf_from_memory(bytes.data(), int(bytes.size()), &w, &h, &comp, 3);
    if (!data)
      throw InputError(path.string() + ": cannot decode HDR image: " + stbi_failure_reason());
    ImageRGB img{uint32_t(w), uint32_t(h)};
    std::memcpy(img.rgb.data(), data, img.rgb.size() * sizeof(float));
    stbi_image_free(data);
    return img;
  }
  unsigned char* data = stbi_load_from_memory(bytes.data(), int(bytes.size()), &w, &h, &comp, 3);
  if (!data) throw InputError(path.string() + ": cannot decode image: " + stbi_failure_reason());
  ImageRGB img{uint32_t(w), uint32_t(h)};
  for (size_t i = 0; i < img.rgb.size(); ++i)
    img.rgb[i] = srgb8_to_linear(data[i]);
  stbi_image_free(data);
  return img;
}

}  // namespace tandem
