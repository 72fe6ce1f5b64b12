# All third-party dependencies come from Debian 12 packages (see tools/setup.sh);
# nothing is vendored or downloaded at build time.
find_package(Threads REQUIRED)
find_package(embree 3 REQUIRED)
find_package(TBB REQUIRED)
find_package(glm REQUIRED)
find_package(TinyGLTF REQUIRED)

# stb ships headers in /usr/include/stb and one shared library with the
# implementations (libstb-dev).
find_path(STB_INCLUDE_DIR stb_image.h PATH_SUFFIXES stb REQUIRED)
find_library(STB_LIBRARY NAMES stb REQUIRED)
add_library(tandem_stb INTERFACE)
target_include_directories(tandem_stb SYSTEM INTERFACE ${STB_INCLUDE_DIR})
target_link_libraries(tandem_stb INTERFACE ${STB_LIBRARY})
