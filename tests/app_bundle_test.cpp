// What a bare GPU machine needs to start the built binaries: with the CUDA
// runtime linked statically (backends/cuda/CMakeLists.txt), `tandem` and
// cuda_tests must not ask the dynamic loader for libcudart (the toolkit's)
// or libcuda (the driver's, which cudart opens itself at run time, so that
// a machine without a driver still starts and falls back to the CPU).
#include <elf.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace {

// DT_NEEDED entries of a 64-bit little-endian ELF file, read through its
// section headers (.dynamic and the string table it links to). Empty with
// *error set when the file is missing or not such an ELF file.
std::vector<std::string> needed_libraries(const std::string& path, std::string* error) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<char> bytes{std::istreambuf_iterator<char>(in), {}};
  auto fail = [&](const std::string& why) {
    *error = path + ": " + why;
    return std::vector<std::string>{};
  };
  if (bytes.size() < sizeof(Elf64_Ehdr)) return fail("missing or too short for an ELF header");
  Elf64_Ehdr eh;
  std::memcpy(&eh, bytes.data(), sizeof eh);
  if (std::memcmp(eh.e_ident, ELFMAG, SELFMAG) != 0 || eh.e_ident[EI_CLASS] != ELFCLASS64 ||
      eh.e_ident[EI_DATA] != ELFDATA2LSB)
    return fail("not a 64-bit little-endian ELF file");
  auto section = [&](size_t i, Elf64_Shdr* sh) {
    const size_t off = eh.e_shoff + i * sizeof(Elf64_Shdr);
    if (i >= eh.e_shnum || off + sizeof(Elf64_Shdr) > bytes.size()) return false;
    std::memcpy(sh, bytes.data() + off, sizeof *sh);
    return sh->sh_offset + sh->sh_size <= bytes.size();
  };
  std::vector<std::string> needed;
  for (size_t i = 0; i < eh.e_shnum; ++i) {
    Elf64_Shdr dyn, str;
    if (!section(i, &dyn) || dyn.sh_type != SHT_DYNAMIC) continue;
    if (!section(dyn.sh_link, &str)) return fail("bad string table of .dynamic");
    for (size_t off = 0; off + sizeof(Elf64_Dyn) <= dyn.sh_size; off += sizeof(Elf64_Dyn)) {
      Elf64_Dyn d;
      std::memcpy(&d, bytes.data() + dyn.sh_offset + off, sizeof d);
      if (d.d_tag == DT_NULL) break;
      if (d.d_tag != DT_NEEDED) continue;
      if (d.d_un.d_val >= str.sh_size) return fail("DT_NEEDED outside the string table");
      const char* name = bytes.data() + str.sh_offset + d.d_un.d_val;
      needed.emplace_back(name, strnlen(name, str.sh_size - d.d_un.d_val));
    }
    return needed;
  }
  return fail("no .dynamic section (a static executable?)");
}

[[maybe_unused]] void expect_no_cuda_libraries(const std::string& binary) {
  std::string error;
  const std::vector<std::string> needed = needed_libraries(binary, &error);
  ASSERT_TRUE(error.empty()) << error;
  // The reader itself: every dynamically linked program here needs libc.
  bool has_libc = false;
  std::string all;
  for (const std::string& lib : needed) {
    has_libc |= lib.rfind("libc.so", 0) == 0;
    all += lib + " ";
  }
  EXPECT_TRUE(has_libc) << binary << " needs: " << all;
  for (const std::string& lib : needed) {
    EXPECT_NE(lib.rfind("libcudart", 0), 0u) << binary << " links the CUDA runtime dynamically";
    EXPECT_NE(lib.rfind("libcuda.so", 0), 0u) << binary << " links the CUDA driver library";
  }
}

TEST(AppBundle, TandemNeedsNoCudaSharedLibrary) {
#if TANDEM_BUILT_WITH_CUDA
  expect_no_cuda_libraries(TANDEM_BINARY);
#else
  GTEST_SKIP() << "this build has no CUDA backend: nothing to link statically";
#endif
}

TEST(AppBundle, CudaTestsNeedNoCudaSharedLibrary) {
#if TANDEM_BUILT_WITH_CUDA && defined(TANDEM_CUDA_TESTS_BINARY)
  expect_no_cuda_libraries(TANDEM_CUDA_TESTS_BINARY);
#else
  GTEST_SKIP() << "this build has no CUDA backend (and no cuda_tests)";
#endif
}

TEST(AppBundle, ElfReaderRejectsWhatIsNotAnElfFile) {
  std::string error;
  EXPECT_TRUE(needed_libraries("/nonexistent/tandem", &error).empty());
  EXPECT_NE(error.find("/nonexistent/tandem"), std::string::npos) << error;
  error.clear();
  EXPECT_TRUE(needed_libraries(TANDEM_SOURCE_DIR "/CMakeLists.txt", &error).empty());
  EXPECT_NE(error.find("not a 64-bit"), std::string::npos) << error;
}

// The bundled tests run away from the source tree and find their data
// through the environment (tests/test_shared_dir.h).
TEST(AppBundle, SharedDataDirectoryFollowsTheEnvironment) {
  const char* old = std::getenv("TANDEM_SHARED_DIR");
  const std::string saved = old ? old : "";
  ::setenv("TANDEM_SHARED_DIR", "/bundle/shared", 1);
  EXPECT_EQ(std::string(TANDEM_SHARED_DIR), "/bundle/shared");
  ::setenv("TANDEM_SHARED_DIR", "", 1);
  EXPECT_EQ(std::string(TANDEM_SHARED_DIR), TANDEM_SHARED_DIR_DEFAULT);
  ::unsetenv("TANDEM_SHARED_DIR");
  EXPECT_EQ(std::string(TANDEM_SHARED_DIR), TANDEM_SHARED_DIR_DEFAULT);
  if (old) ::setenv("TANDEM_SHARED_DIR", saved.c_str(), 1);
}

}  // namespace
