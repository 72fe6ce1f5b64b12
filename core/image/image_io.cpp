// Image writers. EXR goes through the OpenEXR library (image_exr.cpp), PNG
// through stb, PFM through our own few lines. The readers are in
// image_read.cpp.
#include <fcntl.h>
#include <stb_image_write.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>

#include "core/image/image.h"
#include "core/image/image_exr.h"
#include "core/util/errors.h"
#include "core/util/interrupt.h"

namespace tandem {
namespace fs = std::filesystem;

namespace {

std::string lower_extension(const fs::path& p) {
  std::string ext = p.extension().string();
  for (char& c : ext)
    c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

fs::path output_dir(const fs::path& path) {
  return path.has_parent_path() ? path.parent_path() : fs::path(".");
}

// Creates a temporary file next to `path`, exclusively: O_CREAT|O_EXCL
// fails on anything already there, a symlink planted under the name
// included, and O_NOFOLLOW makes sure of it. The random part makes the
// name unpredictable, so nobody can plant one in advance either.
// The temporary name is "." + the file name + ".tmp." + 16 hex digits.
constexpr size_t kTempNameExtraBytes = 1 + 5 + 16;

int create_temp_file(const fs::path& path, std::string& tmp_name) {
  const fs::path dir = output_dir(path);
  static thread_local std::mt19937_64 rng(std::random_device{}() ^ (uint64_t(::getpid()) << 32));
  for (int attempt = 0; attempt < 100; ++attempt) {
    char suffix[24];
    std::snprintf(suffix, sizeof suffix, "%016llx", static_cast<unsigned long long>(rng()));
    tmp_name = (dir / ("." + path.filename().string() + ".tmp." + suffix)).string();
    static_assert(kTempNameExtraBytes == sizeof(".") - 1 + sizeof(".tmp.") - 1 + 16);
    const int fd =
        ::open(tmp_name.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
    if (fd >= 0 || errno != EEXIST) return fd;
  }
  errno = EEXIST;
  return -1;
}

bool write_all(int fd, const uint8_t* data, size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    data += n;
    size -= size_t(n);
  }
  return true;
}

}  // namespace

// Writes bytes to a temporary sibling and renames it over `path`. A signal
// during the write removes the temporary file (TempFileRegistration).
void write_file_atomically(const fs::path& path, const std::vector<uint8_t>& bytes) {
  check_output_path(path);
  std::string tmp;
  const int fd = create_temp_file(path, tmp);
  if (fd < 0) {
    throw InputError(path.string() + ": cannot create a temporary file in '" +
                     output_dir(path).string() + "': " + std::strerror(errno));
  }
  const TempFileRegistration registration(tmp.c_str());
  const bool written = write_all(fd, bytes.data(), bytes.size());
  int saved = errno;
  const bool synced = written && ::fsync(fd) == 0;
  if (written && !synced) saved = errno;
  const bool closed = ::close(fd) == 0;
  if (written && synced && !closed) saved = errno;
  // Replacing a file keeps its permission bits (a 0600 output stays 0600);
  // a new one gets the umask's, as any created file does.
  struct stat old = {};
  if (written && synced && closed && ::lstat(path.c_str(), &old) == 0 && S_ISREG(old.st_mode))
    ::chmod(tmp.c_str(), old.st_mode & 07777);
  if (!written || !synced || !closed) {
    ::unlink(tmp.c_str());
    throw InputError(path.string() + ": write failed: " + std::strerror(saved));
  }
  // rename() replaces a symlink at `path` itself, never the file it names.
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int rename_error = errno;  // before unlink() can change errno
    ::unlink(tmp.c_str());
    throw InputError(path.string() + ": cannot replace the file: " + std::strerror(rename_error));
  }
}

namespace {

template <class T>
void put(std::vector<uint8_t>& out, T v) {
  const size_t at = out.size();
  out.resize(at + sizeof(T));
  std::memcpy(out.data() + at, &v, sizeof(T));
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

}  // namespace

void check_output_path(const fs::path& path) {
  const std::string name = path.string();
  if (path.empty()) throw InputError("the output path is empty");
  struct stat st = {};
  if (::lstat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) {
    throw InputError(name + ": is a directory; give a file name for the output");
  }
  if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) {
    throw InputError(name + ": is a link to a directory; give a file name for the output");
  }
  const fs::path dir = output_dir(path);
  if (::stat(dir.c_str(), &st) != 0) {
    const int e = errno;
    // ENOTDIR: some component of the directory is a regular file.
    if (e == ENOTDIR) {
      throw InputError(name + ": cannot write: a component of '" + dir.string() +
                       "' is a file, not a directory");
    }
    if (e == ENOENT) {
      throw InputError(name + ": cannot write: directory '" + dir.string() + "' does not exist");
    }
    throw InputError(name + ": cannot write: '" + dir.string() + "': " + std::strerror(e));
  }
  if (!S_ISDIR(st.st_mode)) {
    throw InputError(name + ": cannot write: '" + dir.string() + "' is a file, not a directory");
  }
  if (::access(dir.c_str(), W_OK | X_OK) != 0) {
    throw InputError(name + ": cannot write: directory '" + dir.string() + "' is not writable (" +
                     std::strerror(errno) + ")");
  }
  // The image is written to a temporary sibling first, whose name is
  // longer: it must fit too, or a finished render is lost at the end.
  const long name_max = ::pathconf(dir.c_str(), _PC_NAME_MAX);
  const size_t limit = name_max > 0 ? size_t(name_max) : 255;
  const size_t name_bytes = path.filename().string().size();
  if (name_bytes + kTempNameExtraBytes > limit) {
    throw InputError(name + ": cannot write: the file name is " + std::to_string(name_bytes) +
                     " bytes; with the " + std::to_string(kTempNameExtraBytes) +
                     " bytes of the temporary file written first it passes the limit of " +
                     std::to_string(limit) + " bytes for a file name in '" + dir.string() + "'");
  }
  const size_t path_bytes = (dir / path.filename()).string().size() + kTempNameExtraBytes;
  if (path_bytes >= PATH_MAX) {
    throw InputError(name + ": cannot write: with the temporary file's suffix the path is " +
                     std::to_string(path_bytes) + " bytes, over the limit of " +
                     std::to_string(PATH_MAX - 1));
  }
}

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
    std::vector<uint8_t> bytes;
    try {
      bytes = encode_exr(image, options.exr_pixel_type, options.exr_compression);
    } catch (const std::bad_alloc&) {
      throw InputError(path.string() + ": not enough memory to encode the OpenEXR image");
    } catch (const std::exception& e) {
      throw InputError(path.string() + ": OpenEXR encoding failed: " + e.what());
    }
    write_file_atomically(path, bytes);
  } else if (ext == ".pfm") {
    write_file_atomically(path, encode_pfm(image));
  } else {
    throw InputError(path.string() + ": unsupported output format '" + ext +
                     "' (use .png, .exr or .pfm)");
  }
}

}  // namespace tandem
