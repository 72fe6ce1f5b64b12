// Image readers. PFM and Radiance HDR are decoded by our own small codecs,
// EXR by the OpenEXR library (image_exr.cpp), PNG/JPEG by stb after our
// own header check. Files come from users and downloads, so nothing in a header is
// trusted: every field, and the file length it implies, is checked in
// 64-bit arithmetic before pixels are allocated, and a truncated file is an
// error, never a partly black image.
#include <stb_image.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <new>
#include <string>
#include <system_error>
#include <vector>

#include "core/image/image.h"
#include "core/image/image_exr.h"
#include "core/kernel/srgb_table.h"
#include "core/util/errors.h"

namespace tandem {
namespace fs = std::filesystem;

namespace {

std::string dims(uint64_t w, uint64_t h) {
  return std::to_string(w) + "x" + std::to_string(h);
}

uint32_t be32(const uint8_t* p) {
  return uint32_t(p[0]) << 24 | uint32_t(p[1]) << 16 | uint32_t(p[2]) << 8 | p[3];
}

uint32_t crc32(const uint8_t* p, size_t n) {
  uint32_t c = 0xffffffffu;
  for (size_t i = 0; i < n; ++i) {
    c ^= p[i];
    for (int k = 0; k < 8; ++k)
      c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
  }
  return ~c;
}

ImageRGB decode_pfm(const uint8_t* bytes, size_t size, const std::string& name,
                    const ImageReadLimits& limits) {
  // "PF" or "Pf", whitespace, width, height, scale, one whitespace byte.
  const std::string text(reinterpret_cast<const char*>(bytes), std::min<size_t>(size, 128));
  char kind[3] = {};
  char wtext[24] = {}, htext[24] = {};
  double scale = 0.0;
  int consumed = 0;
  if (std::sscanf(text.c_str(), "%2s %20s %20s %lf%n", kind, wtext, htext, &scale, &consumed) !=
          4 ||
      (std::strcmp(kind, "PF") != 0 && std::strcmp(kind, "Pf") != 0) ||
      std::strspn(wtext, "0123456789") != std::strlen(wtext) ||
      std::strspn(htext, "0123456789") != std::strlen(htext) || std::strlen(wtext) > 10 ||
      std::strlen(htext) > 10 || !std::isfinite(scale) || scale == 0.0 ||
      size_t(consumed) >= text.size()) {
    fail_image(name, "not a valid PFM header");
  }
  const uint64_t w = std::strtoull(wtext, nullptr, 10), h = std::strtoull(htext, nullptr, 10);
  check_image_pixels(name, "PFM", w, h, limits);
  const size_t data_start = size_t(consumed) + 1;
  const uint64_t comps = kind[1] == 'F' ? 3 : 1;
  const uint64_t need = w * h * comps * 4;
  if (size < data_start || size - data_start < need) {
    fail_image(name, "PFM pixel data is truncated (" + dims(w, h) + " needs " +
                         std::to_string(need) + " bytes, the file has " +
                         std::to_string(size - std::min(size, data_start)) + ")");
  }
  const bool big_endian = scale > 0.0;
  ImageRGB img{uint32_t(w), uint32_t(h)};
  const uint8_t* p = bytes + data_start;
  for (uint64_t row = 0; row < h; ++row) {
    for (uint64_t x = 0; x < w; ++x) {
      float* px = img.pixel(uint32_t(x), uint32_t(h - 1 - row));
      for (uint64_t c = 0; c < comps; ++c) {
        uint8_t b[4];
        std::memcpy(b, p, 4);
        p += 4;
        if (big_endian) std::swap(b[0], b[3]), std::swap(b[1], b[2]);
        float v;
        std::memcpy(&v, b, 4);
        if (comps == 3) {
          px[c] = v;
        } else {
          px[0] = px[1] = px[2] = v;
        }
      }
    }
  }
  return img;
}

// Radiance RGBE: a text header ending in an empty line, "-Y H +X W", then
// H scanlines, each flat (4 bytes per pixel) or run-length encoded per
// channel ("2 2 W/256 W%256" then runs). stb_image reads past the end of a
// truncated file as zeros; this decoder refuses it.
ImageRGB decode_hdr(const uint8_t* bytes, size_t size, const std::string& name,
                    const ImageReadLimits& limits) {
  size_t pos = 0;
  auto line = [&](std::string& out) {
    out.clear();
    while (pos < size && bytes[pos] != '\n') {
      if (out.size() > 4096) fail_image(name, "HDR header line too long");
      out.push_back(char(bytes[pos++]));
    }
    if (pos >= size) fail_image(name, "HDR header is truncated");
    ++pos;
  };
  std::string text;
  line(text);
  if (text != "#?RADIANCE" && text != "#?RGBE") fail_image(name, "not a Radiance HDR file");
  while (true) {
    line(text);
    if (text.empty()) break;
    if (text.rfind("FORMAT=", 0) == 0 && text != "FORMAT=32-bit_rle_rgbe") {
      fail_image(name,
                 "HDR format '" + text.substr(7) + "' is not supported (only 32-bit_rle_rgbe)");
    }
  }
  line(text);
  char wtext[24] = {}, htext[24] = {};
  int consumed = 0;
  if (std::sscanf(text.c_str(), "-Y %20s +X %20s%n", htext, wtext, &consumed) != 2 ||
      size_t(consumed) != text.size() || std::strspn(wtext, "0123456789") != std::strlen(wtext) ||
      std::strspn(htext, "0123456789") != std::strlen(htext) || std::strlen(wtext) > 10 ||
      std::strlen(htext) > 10) {
    fail_image(name, "HDR resolution line '" + text.substr(0, 64) +
                         "' is not supported (expected \"-Y height +X width\")");
  }
  const uint64_t w = std::strtoull(wtext, nullptr, 10), h = std::strtoull(htext, nullptr, 10);
  check_image_pixels(name, "HDR", w, h, limits);
  // The smallest a scanline can be: runs of at most 127 equal bytes per
  // channel, or 4 bytes per pixel when it cannot be run-length encoded.
  const bool rle_possible = w >= 8 && w < 32768;
  const uint64_t min_line =
      rle_possible ? std::min<uint64_t>(4 * w, 4 + 8 * ((w + 126) / 127)) : 4 * w;
  if (h * min_line > size - pos) {
    fail_image(name, "HDR pixel data is truncated (" + dims(w, h) + " needs at least " +
                         std::to_string(h * min_line) + " bytes, the file has " +
                         std::to_string(size - pos) + ")");
  }
  ImageRGB img{uint32_t(w), uint32_t(h)};
  std::vector<uint8_t> rgbe(size_t(w) * 4);
  auto truncated = [&](uint64_t y) {
    fail_image(name, "HDR pixel data is truncated (scanline " + std::to_string(y) + " of " +
                         std::to_string(h) + ")");
  };
  for (uint64_t y = 0; y < h; ++y) {
    if (rle_possible && size - pos >= 4 && bytes[pos] == 2 && bytes[pos + 1] == 2 &&
        !(bytes[pos + 2] & 0x80)) {
      if ((uint64_t(bytes[pos + 2]) << 8 | bytes[pos + 3]) != w) {
        fail_image(name, "HDR scanline " + std::to_string(y) + " has the wrong width");
      }
      pos += 4;
      for (int c = 0; c < 4; ++c) {
        uint64_t x = 0;
        while (x < w) {
          if (pos >= size) truncated(y);
          uint64_t count = bytes[pos++];
          if (count > 128) {
            count -= 128;
            if (pos >= size) truncated(y);
            if (x + count > w)
              fail_image(name, "HDR scanline " + std::to_string(y) + " is corrupt");
            const uint8_t v = bytes[pos++];
            for (uint64_t k = 0; k < count; ++k)
              rgbe[size_t(x++) * 4 + size_t(c)] = v;
          } else {
            if (count == 0 || x + count > w) {
              fail_image(name, "HDR scanline " + std::to_string(y) + " is corrupt");
            }
            if (size - pos < count) truncated(y);
            for (uint64_t k = 0; k < count; ++k)
              rgbe[size_t(x++) * 4 + size_t(c)] = bytes[pos++];
          }
        }
      }
    } else {
      if (size - pos < 4 * w) truncated(y);
      std::memcpy(rgbe.data(), bytes + pos, size_t(4 * w));
      pos += size_t(4 * w);
    }
    for (uint64_t x = 0; x < w; ++x) {
      const uint8_t* e = &rgbe[size_t(x) * 4];
      float* px = img.pixel(uint32_t(x), uint32_t(y));
      const float f = e[3] == 0 ? 0.0f : std::ldexp(1.0f, int(e[3]) - (128 + 8));
      for (int c = 0; c < 3; ++c)
        px[c] = float(e[c]) * f;
    }
  }
  return img;
}

// PNG and JPEG through stb, 8 bits, sRGB-decoded to linear.
ImageRGB decode_8bit(const uint8_t* bytes, size_t size, const std::string& name,
                     const ImageReadLimits& limits) {
  const EncodedImageInfo info = probe_encoded_image(bytes, size);
  const char* format = info.format == EncodedImageInfo::kPng    ? "PNG"
                       : info.format == EncodedImageInfo::kJpeg ? "JPEG"
                                                                : "image";
  if (size > size_t(INT_MAX)) fail_image(name, "file too large for the image decoder (over 2 GiB)");
  // Only PNG and JPEG reach stb: its other decoders (PNM, BMP, TGA, PSD,
  // GIF, PIC) are not what Tandem documents and not hardened (the fuzzer
  // made a 15-byte PNM header read past the buffer in libstb).
  if (info.format == EncodedImageInfo::kUnknown) {
    fail_image(name, "not an image format Tandem reads (.exr, .pfm, .hdr, .png, .jpg)");
  }
  if (!info.header_ok) fail_image(name, info.problem);
  check_image_pixels(name, format, info.width, info.height, limits);
  int w = 0, h = 0, comp = 0;
  unsigned char* data = stbi_load_from_memory(bytes, int(size), &w, &h, &comp, 3);
  if (!data) {
    // The header was checked above, so stb's "too large" and the like
    // here mean the data after it is corrupt.
    fail_image(name, std::string("cannot decode ") + format + " data: corrupt or unsupported (" +
                         stbi_failure_reason() + ")");
  }
  struct Free {
    void operator()(unsigned char* p) const { stbi_image_free(p); }
  };
  std::unique_ptr<unsigned char, Free> owned(data);
  ImageRGB img{uint32_t(w), uint32_t(h)};
  for (size_t i = 0; i < img.rgb.size(); ++i)
    img.rgb[i] = srgb8_to_linear(data[i]);
  return img;
}

// stb's JPEG decoder builds Huffman tables only from DHT segments and
// asserts (aborting the process) when a scan decodes with a table the file
// never defined, since that table is uninitialised memory. So every scan's
// tables must have been defined before it. Returns the problem, or "".
std::string check_jpeg_tables(const uint8_t* data, size_t size) {
  bool dc[4] = {}, ac[4] = {};
  size_t p = 2;
  while (p + 4 <= size) {
    if (data[p] != 0xff) return "corrupt JPEG: no marker where one must be";
    const uint8_t marker = data[p + 1];
    if (marker == 0xff) {
      ++p;
      continue;
    }
    if (marker == 0xd8 || marker == 0x01 || (marker >= 0xd0 && marker <= 0xd7)) {
      p += 2;
      continue;
    }
    if (marker == 0xd9) return "";
    const size_t length = size_t(data[p + 2]) << 8 | data[p + 3];
    const size_t seg = p + 4, end = p + 2 + length;
    if (length < 2 || end > size) return "corrupt JPEG: a segment runs past the end of the file";
    if (marker == 0xc4) {  // DHT: class/id, 16 code counts, the codes
      for (size_t q = seg; q < end;) {
        const uint8_t tc = data[q] >> 4, th = data[q] & 15;
        if (tc > 1 || th > 3 || end - q < 17) return "corrupt JPEG: invalid Huffman table";
        size_t codes = 0;
        for (size_t k = 1; k <= 16; ++k)
          codes += data[q + k];
        if (end - q - 17 < codes) return "corrupt JPEG: invalid Huffman table";
        (tc ? ac : dc)[th] = true;
        q += 17 + codes;
      }
    } else if (marker == 0xda) {  // SOS: components with their tables, Ss, Se, Ah/Al
      const size_t n = seg < end ? data[seg] : 0;
      if (n < 1 || n > 4 || end - seg < 1 + 2 * n + 3) return "corrupt JPEG: invalid scan header";
      const uint8_t ss = data[seg + 1 + 2 * n], se = data[seg + 2 + 2 * n];
      const uint8_t ah = data[seg + 3 + 2 * n] >> 4;
      for (size_t i = 0; i < n; ++i) {
        const uint8_t td = data[seg + 2 + 2 * i] >> 4, ta = data[seg + 2 + 2 * i] & 15;
        if (td > 3 || ta > 3 || (ss == 0 && ah == 0 && !dc[td]) || (se > 0 && !ac[ta])) {
          return "corrupt JPEG: a scan uses a Huffman table the file does not define";
        }
      }
      // Skip the entropy-coded data up to the next marker (FF 00 is a
      // stuffed byte, FF D0..D7 a restart marker inside the data).
      p = end;
      while (p + 1 < size && !(data[p] == 0xff && data[p + 1] != 0 &&
                               !(data[p + 1] >= 0xd0 && data[p + 1] <= 0xd7))) {
        ++p;
      }
      continue;
    }
    p = end;
  }
  return "";
}

}  // namespace

void fail_image(const std::string& name, const std::string& why) {
  throw InputError(name + ": " + why);
}

void check_image_pixels(const std::string& name, const char* format, uint64_t w, uint64_t h,
                        const ImageReadLimits& limits) {
  if (w < 1 || h < 1)
    fail_image(name, std::string(format) + " image has no pixels (" + dims(w, h) + ")");
  // w and h are each below 2^32 here, so the product cannot overflow.
  if (w > UINT32_MAX || h > UINT32_MAX || w * h > limits.max_pixels) {
    std::string use;
    if (limits.use != nullptr) use = std::string(" for ") + limits.use;
    if (limits.bytes_per_pixel_in_use > 0 && w <= UINT32_MAX && h <= UINT32_MAX) {
      const double gib = double(w * h) * limits.bytes_per_pixel_in_use / double(1u << 30);
      char text[96];
      std::snprintf(text, sizeof text, " (it would take about %.1f GiB of memory)", gib);
      use += text;
    }
    if (limits.advice != nullptr) use += std::string("; ") + limits.advice;
    fail_image(name, std::string(format) + " header claims " + dims(w, h) +
                         " pixels, over the limit of " + std::to_string(limits.max_pixels) +
                         " pixels" + use);
  }
}

EncodedImageInfo probe_encoded_image(const uint8_t* data, size_t size) {
  EncodedImageInfo info;
  static const uint8_t kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (size >= 8 && std::memcmp(data, kPngSignature, 8) == 0) {
    info.format = EncodedImageInfo::kPng;
    // The first chunk must be IHDR: length 13, type, 13 bytes, CRC.
    if (size < 33 || be32(data + 8) != 13 || std::memcmp(data + 12, "IHDR", 4) != 0) {
      info.problem = "corrupt PNG: no valid IHDR header chunk";
      return info;
    }
    if (crc32(data + 12, 17) != be32(data + 29)) {
      info.problem = "corrupt PNG: the IHDR header chunk fails its checksum";
      return info;
    }
    info.width = be32(data + 16);
    info.height = be32(data + 20);
    const uint8_t depth = data[24], color = data[25];
    const bool depth_ok = depth == 1 || depth == 2 || depth == 4 || depth == 8 || depth == 16;
    const bool color_ok = color == 0 || color == 2 || color == 3 || color == 4 || color == 6;
    if (!depth_ok || !color_ok || info.width == 0 || info.height == 0 || info.width > 0x7fffffffu ||
        info.height > 0x7fffffffu) {
      info.problem = "corrupt PNG: invalid IHDR header values";
      return info;
    }
    // stb grows its buffer to a chunk's declared length before reading it
    // (the fuzzer made a 159-byte file ask for 2 GiB): every chunk must be
    // in the file.
    for (size_t p = 8; p + 12 <= size;) {
      const uint64_t length = be32(data + p);
      if (length > size - p - 12) {
        info.problem = "corrupt PNG: a chunk claims " + std::to_string(length) +
                       " bytes, more than the rest of the file";
        return info;
      }
      if (std::memcmp(data + p + 4, "IEND", 4) == 0) break;
      p += 12 + size_t(length);
    }
    info.bytes_per_channel = depth == 16 ? 2 : 1;
    info.channels = color == 0 ? 1 : color == 2 ? 3 : color == 4 ? 2 : 4;
    info.header_ok = true;
    return info;
  }
  if (size >= 3 && data[0] == 0xff && data[1] == 0xd8 && data[2] == 0xff) {
    info.format = EncodedImageInfo::kJpeg;
    // Walk the marker segments up to the first start-of-frame.
    size_t p = 2;
    while (p + 4 <= size) {
      if (data[p] != 0xff) break;
      const uint8_t marker = data[p + 1];
      if (marker == 0xff) {
        ++p;  // fill byte
        continue;
      }
      if (marker == 0xd8 || marker == 0x01 || (marker >= 0xd0 && marker <= 0xd7)) {
        p += 2;
        continue;
      }
      if (marker == 0xd9 || marker == 0xda) break;  // end of image / start of scan: no frame
      const size_t length = size_t(data[p + 2]) << 8 | data[p + 3];
      if (length < 2) break;
      const bool frame =
          marker >= 0xc0 && marker <= 0xcf && marker != 0xc4 && marker != 0xc8 && marker != 0xcc;
      if (frame) {
        if (length < 8 || p + 2 + 7 > size) break;
        info.height = uint32_t(data[p + 5]) << 8 | data[p + 6];
        info.width = uint32_t(data[p + 7]) << 8 | data[p + 8];
        info.channels = p + 9 < size && data[p + 9] >= 1 && data[p + 9] <= 4 ? data[p + 9] : 4;
        if (info.width == 0 || info.height == 0) {
          info.problem = "corrupt JPEG: the frame header has a zero width or height";
          return info;
        }
        info.problem = check_jpeg_tables(data, size);
        info.header_ok = info.problem.empty();
        return info;
      }
      p += 2 + length;
    }
    info.problem = "corrupt JPEG: no frame header before the image data";
    return info;
  }
  return info;
}

ImageRGB read_image_from_memory(const uint8_t* data, size_t size, const std::string& name,
                                const ImageReadLimits& limits) {
  if (size == 0) fail_image(name, "file is empty");
  std::string ext = fs::path(name).extension().string();
  for (char& c : ext)
    c = char(std::tolower(static_cast<unsigned char>(c)));
  // The content decides the format; the extension only breaks ties.
  const bool exr =
      size >= 4 && data[0] == 0x76 && data[1] == 0x2f && data[2] == 0x31 && data[3] == 0x01;
  const bool pfm = size >= 2 && data[0] == 'P' && (data[1] == 'F' || data[1] == 'f');
  const bool hdr = size >= 2 && data[0] == '#' && data[1] == '?';
  try {
    if (exr || (ext == ".exr" && !pfm && !hdr)) return decode_exr(data, size, name, limits);
    if (pfm || (ext == ".pfm" && !hdr)) return decode_pfm(data, size, name, limits);
    if (hdr || ext == ".hdr") return decode_hdr(data, size, name, limits);
    return decode_8bit(data, size, name, limits);
  } catch (const std::bad_alloc&) {
    fail_image(name, "not enough memory to decode the image");
  }
}

ImageRGB read_image(const fs::path& path, const ImageReadLimits& limits) {
  const std::string name = path.string();
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (!fs::exists(st)) fail_image(name, "file not found");
  if (fs::is_directory(st)) fail_image(name, "is a directory, not an image file");
  if (!fs::is_regular_file(st)) fail_image(name, "not a regular file (a device, FIFO or socket)");
  const uintmax_t size = fs::file_size(path, ec);
  if (ec) fail_image(name, "cannot read the file size (" + ec.message() + ")");
  if (size == 0) fail_image(name, "file is empty");
  if (size > limits.max_file_bytes) {
    fail_image(name, "file is " + std::to_string(size) + " bytes, over the limit of " +
                         std::to_string(limits.max_file_bytes));
  }
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) fail_image(name, std::string("cannot open the file (") + std::strerror(errno) + ")");
  std::vector<uint8_t> bytes;
  try {
    bytes.resize(size_t(size));
  } catch (const std::bad_alloc&) {
    std::fclose(f);
    fail_image(name, "not enough memory to read the file");
  }
  const size_t got = std::fread(bytes.data(), 1, bytes.size(), f);
  std::fclose(f);
  if (got != bytes.size()) fail_image(name, "cannot read the whole file");
  return read_image_from_memory(bytes.data(), bytes.size(), name, limits);
}

}  // namespace tandem
