// Image files from users: readers must check headers against the file
// length before allocating, and writers must not be redirected through a
// planted link or leave temporary files behind. Cases are generated here.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/image/image.h"
#include "core/util/errors.h"
#include "core/util/interrupt.h"
#include "tests/test_temp_dir.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;

std::string read_error(const fs::path& path) {
  try {
    read_image(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

template <class T>
void put(std::string& out, T v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof v);
}
void put_attr(std::string& out, const char* name, const char* type, int32_t size) {
  out.append(name, std::strlen(name) + 1);
  out.append(type, std::strlen(type) + 1);
  put(out, size);
}

// An uncompressed EXR header with one FLOAT channel R and the data window
// `box`, followed by `tail` (offset table and scanlines, or nothing).
std::string exr_header(const int32_t box[4]) {
  std::string out;
  put<uint32_t>(out, 20000630u);
  put<uint32_t>(out, 2u);
  put_attr(out, "channels", "chlist", 2 + 16 + 1);
  out.append("R", 2);
  put<int32_t>(out, 2);
  put<uint32_t>(out, 0);
  put<int32_t>(out, 1);
  put<int32_t>(out, 1);
  out.push_back('\0');
  put_attr(out, "compression", "compression", 1);
  out.push_back('\0');
  put_attr(out, "dataWindow", "box2i", 16);
  for (int k = 0; k < 4; ++k)
    put(out, box[k]);
  out.push_back('\0');
  return out;
}

TEST(ImageHostile, ExrHeaderClaimingAHugeWindowFailsFastOnLength) {
  TempDir dir("tandem_image");
  const fs::path file = dir.path() / "huge.exr";
  const int32_t box[4] = {0, 0, 8191, 8191};  // 64 M pixels, 768 MiB if allocated
  write_text(file, exr_header(box));
  const auto start = std::chrono::steady_clock::now();
  const std::string error = read_error(file);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_NE(error.find(file.string() + ": file is truncated or corrupt: the 8192x8192 OpenEXR"),
            std::string::npos)
      << error;
  EXPECT_LT(seconds, 0.5);  // nothing was allocated or zeroed
  // Over the pixel limit whatever the length.
  const int32_t too_big[4] = {0, 0, 65535, 65535};
  write_text(file, exr_header(too_big));
  EXPECT_NE(read_error(file).find("OpenEXR header claims 65536x65536 pixels, over the limit"),
            std::string::npos);
}

TEST(ImageHostile, ExrWindowsAndScanlinesNearIntLimitsAreErrors) {
  TempDir dir("tandem_image");
  const fs::path file = dir.path() / "y.exr";
  // A window at INT32_MIN + 1 (y - ymin overflowed int32 in our old reader).
  const int32_t box[4] = {0, INT32_MIN + 1, 0, INT32_MIN + 1};
  std::string data = exr_header(box);
  put<uint64_t>(data, data.size() + 8);
  put<int32_t>(data, INT32_MAX);  // scanline y
  put<uint32_t>(data, 4);
  put<float>(data, 1.0f);
  write_text(file, data);
  EXPECT_EQ(read_error(file).rfind(file.string() + ": ", 0), 0u) << read_error(file);
  // An offset window: a scanline block with the wrong y is corrupt, the right one reads.
  const int32_t offset_box[4] = {-7, 1000, -7, 1000};
  std::string bad = exr_header(offset_box);
  put<uint64_t>(bad, bad.size() + 8);
  put<int32_t>(bad, INT32_MAX);
  put<uint32_t>(bad, 4);
  put<float>(bad, 0.25f);
  write_text(file, bad);
  EXPECT_NE(read_error(file).find("scanline block at y 1000 is not in the file"), std::string::npos)
      << read_error(file);
  std::string good = exr_header(offset_box);
  put<uint64_t>(good, good.size() + 8);
  put<int32_t>(good, 1000);
  put<uint32_t>(good, 4);
  put<float>(good, 0.25f);
  write_text(file, good);
  const ImageRGB img = read_image(file);
  ASSERT_EQ(img.width, 1u);
  EXPECT_EQ(img.rgb[0], 0.25f);
  EXPECT_EQ(img.rgb[2], 0.25f);  // R alone is grey
}

TEST(ImageHostile, ExrAttributeLargerThanTheFileIsRefusedBeforeAllocating) {
  TempDir dir("tandem_image");
  const fs::path file = dir.path() / "attribute.exr";
  const int32_t box[4] = {0, 0, 0, 0};
  std::string data = exr_header(box);
  data.pop_back();  // reopen the header
  // An attribute of a type no reader knows, claiming 800 MB.
  put_attr(data, "junk", "blob", 800 << 20);
  data.append(16, '\0');
  write_text(file, data);
  EXPECT_NE(read_error(file).find(file.string() +
                                  ": OpenEXR header has an attribute of 838860800 bytes, more "
                                  "than the rest of the file (16 bytes)"),
            std::string::npos)
      << read_error(file);
}

TEST(ImageHostile, OnlyPngAndJpegReachStb) {
  TempDir dir("tandem_image");
  // A 15-byte PNM header that made libstb's PNM decoder read past the
  // buffer (found by the fuzzer): PNM, BMP, TGA and the like are refused.
  const fs::path file = dir.path() / "texture.png";
  write_text(file, std::string("P511  940\r515\r ", 15));
  EXPECT_NE(read_error(file).find(file.string() + ": not an image format Tandem reads"),
            std::string::npos)
      << read_error(file);
  write_text(file, std::string("BM") + std::string(60, '\1'));
  EXPECT_NE(read_error(file).find("not an image format Tandem reads"), std::string::npos);
}

TEST(ImageHostile, TruncatedFilesAreErrorsInEveryFormat) {
  TempDir dir("tandem_image");
  ImageRGB img(20, 3);
  for (size_t i = 0; i < img.rgb.size(); ++i)
    img.rgb[i] = float(i % 7) * 0.5f;
  for (const char* ext : {".exr", ".pfm", ".png"}) {
    const fs::path file = dir.path() / (std::string("img") + ext);
    write_image(file, img);
    ASSERT_EQ(read_error(file), "") << ext;
    const std::string full = read_text(file);
    write_text(file, full.substr(0, full.size() - 9));
    const std::string error = read_error(file);
    EXPECT_EQ(error.rfind(file.string() + ": ", 0), 0u) << ext << ": " << error;
  }
  // Radiance HDR, flat and run-length encoded scanlines.
  for (const uint32_t width : {4u, 40u}) {
    const fs::path file = dir.path() / "img.hdr";
    std::string hdr =
        "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X " + std::to_string(width) + "\n";
    for (int y = 0; y < 2; ++y) {
      if (width >= 8) {
        hdr += std::string{2, 2, char(width >> 8), char(width & 0xff)};
        for (int c = 0; c < 4; ++c)
          hdr += std::string{char(128 + width), char(c == 3 ? 129 : 128)};  // one run
      } else {
        for (uint32_t x = 0; x < width; ++x)
          hdr += std::string{char(128), char(64), 0, char(129)};
      }
    }
    write_text(file, hdr);
    const ImageRGB read = read_image(file);
    ASSERT_EQ(read.width, width);
    EXPECT_FLOAT_EQ(read.rgb[0], width >= 8 ? 1.0f : 1.0f);
    write_text(file, hdr.substr(0, hdr.size() - 1));
    EXPECT_NE(read_error(file).find("HDR pixel data is truncated"), std::string::npos) << width;
  }
}

TEST(ImageHostile, PngHeadersAreCheckedBeforeDecoding) {
  TempDir dir("tandem_image");
  const fs::path file = dir.path() / "t.png";
  write_png_rgb8(file, 2, 2, std::vector<uint8_t>(12, 100));
  std::string png = read_text(file);
  png[17] = char(0x7f);  // width now ~8 M, and the IHDR checksum no longer matches
  write_text(file, png);
  const std::string error = read_error(file);
  EXPECT_NE(error.find("corrupt PNG: the IHDR header chunk fails its checksum"), std::string::npos)
      << error;
  EXPECT_EQ(error.find("too large"), std::string::npos) << error;
  write_text(file, png.substr(0, 20));
  EXPECT_NE(read_error(file).find("corrupt PNG"), std::string::npos);
  // A chunk claiming more bytes than the file has (stb would allocate them).
  std::string good = png;
  good[17] = char(0);     // width back to 2, checksum good again
  good[33] = char(0x3f);  // the chunk after IHDR: length ~1 GiB
  write_text(file, good);
  EXPECT_NE(read_error(file).find("corrupt PNG: a chunk claims"), std::string::npos)
      << read_error(file);
}

TEST(ImageHostile, JpegScanWithAnUndefinedHuffmanTableIsRefused) {
  // stb decodes such a scan with an uninitialised table and asserts (the
  // fuzzer found it): SOI, SOF0 8x8 grey, a DC table only, then a baseline
  // scan that also needs AC table 0.
  const std::string jpeg = std::string("\xff\xd8", 2) +
                           std::string("\xff\xc0\x00\x0b\x08\x00\x08\x00\x08\x01\x01\x11\x00", 13) +
                           std::string("\xff\xc4\x00\x14\x00\x01", 6) + std::string(15, '\0') +
                           std::string("\x00", 1) +
                           std::string("\xff\xda\x00\x08\x01\x01\x00\x00\x3f\x00", 10) +
                           std::string("\x12\x34\xff\xd9", 4);
  TempDir dir("tandem_image");
  const fs::path file = dir.path() / "t.jpg";
  write_text(file, jpeg);
  EXPECT_NE(read_error(file).find("a scan uses a Huffman table the file does not define"),
            std::string::npos)
      << read_error(file);
}

TEST(ImageHostile, NonFilesAreNamedForWhatTheyAre) {
  TempDir dir("tandem_image");
  EXPECT_NE(read_error(dir.path() / "none.exr").find("file not found"), std::string::npos);
  EXPECT_NE(read_error(dir.path()).find("is a directory"), std::string::npos);
  EXPECT_NE(read_error("/dev/null").find("not a regular file"), std::string::npos);
}

TEST(ImageHostile, OutputPathIsCheckedUpFront) {
  TempDir dir("tandem_image");
  write_text(dir.path() / "file", "x");
  auto error = [](const fs::path& p) {
    try {
      check_output_path(p);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(error(dir.path() / "out.png"), "");
  EXPECT_NE(error(dir.path()).find("is a directory"), std::string::npos);
  EXPECT_NE(error(dir.path() / "missing" / "o.png").find("does not exist"), std::string::npos);
  EXPECT_NE(error(dir.path() / "file" / "o.png").find("is a file, not a directory"),
            std::string::npos);
  // The temporary file's name (22 bytes longer) must fit the file-name
  // limit too, or a finished render is lost at the very end.
  EXPECT_EQ(error(dir.path() / (std::string(255 - 22 - 4, 'a') + ".png")), "");
  EXPECT_NE(error(dir.path() / (std::string(255 - 22 - 3, 'a') + ".png"))
                .find("with the 22 bytes of the temporary file written first it passes the limit "
                      "of 255 bytes for a file name"),
            std::string::npos);
  if (::geteuid() != 0) {  // root may write anywhere
    fs::create_directory(dir.path() / "ro");
    fs::permissions(dir.path() / "ro", fs::perms::owner_read | fs::perms::owner_exec);
    EXPECT_NE(error(dir.path() / "ro" / "o.png").find("is not writable"), std::string::npos);
  }
}

TEST(ImageHostile, WritesNeverFollowLinks) {
  TempDir dir("tandem_image");
  const fs::path victim = dir.path() / "victim.txt";
  write_text(victim, "precious");
  const fs::path out = dir.path() / "out.pfm";
  // Links planted under every name the old scheme could have used, and the
  // output itself a link: the victim must survive and the output become a
  // regular file.
  for (int pid = ::getpid() - 5; pid <= ::getpid() + 5; ++pid)
    fs::create_symlink(victim, dir.path() / (".out.pfm.tmp." + std::to_string(pid)));
  fs::create_symlink(victim, out);
  write_image(out, ImageRGB(2, 2));
  EXPECT_EQ(read_text(victim), "precious");
  EXPECT_FALSE(fs::is_symlink(out));
  EXPECT_EQ(read_image(out).width, 2u);
  // The output an existing directory: the real reason, not "Success".
  fs::create_directory(dir.path() / "d.pfm");
  try {
    write_image(dir.path() / "d.pfm", ImageRGB(2, 2));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("is a directory"), std::string::npos) << e.what();
  }
  // No temporary file is left behind.
  for (const auto& e : fs::directory_iterator(dir.path())) {
    const std::string name = e.path().filename().string();
    if (name.find(".tmp.") != std::string::npos) {
      EXPECT_TRUE(fs::is_symlink(e.path())) << name;
    }
  }
}

// Replacing an output keeps its permission bits (the temporary file is
// created with the umask's); a new output gets the umask's.
TEST(ImageHostile, ReplacingAnOutputKeepsItsPermissions) {
  TempDir dir("tandem_image");
  const fs::path out = dir.path() / "private.pfm";
  write_text(out, "old");
  fs::permissions(out, fs::perms::owner_read | fs::perms::owner_write);
  write_image(out, ImageRGB(2, 2));
  EXPECT_EQ(fs::status(out).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write);
  EXPECT_EQ(read_image(out).width, 2u);
  fs::permissions(out, fs::perms::owner_all | fs::perms::group_read);
  write_image(out, ImageRGB(2, 2));
  EXPECT_EQ(fs::status(out).permissions() & fs::perms::all,
            fs::perms::owner_all | fs::perms::group_read);
  const mode_t mask = ::umask(022);
  write_image(dir.path() / "new.pfm", ImageRGB(2, 2));
  ::umask(mask);
  EXPECT_EQ(fs::status(dir.path() / "new.pfm").permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read |
                fs::perms::others_read);
}

TEST(ImageHostile, SignalDuringAWriteRemovesTheTemporaryFile) {
  TempDir dir("tandem_image");
  const fs::path tmp = dir.path() / ".out.png.tmp.test";
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    install_interrupt_handlers();
    write_text(tmp, "partial");
    const TempFileRegistration registration(tmp.c_str());
    std::raise(SIGTERM);
    ::_exit(0);  // not reached: the handler ends the process as SIGTERM would
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM) << status;
  EXPECT_FALSE(fs::exists(tmp));
}

TEST(ImageHostile, GracefulStopTurnsTheFirstSignalIntoAFlag) {
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    install_interrupt_handlers();
    int code = 1;
    {
      GracefulStop stop;
      std::raise(SIGINT);
      if (stop.requested() && stop.signal() == SIGINT) code = 42;
    }
    ::_exit(code);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 42) << status;
}

}  // namespace
}  // namespace tandem
