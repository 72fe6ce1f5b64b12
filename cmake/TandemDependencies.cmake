# All third-party dependencies come from Debian 12 packages (see setup.sh);
# nothing is vendored or downloaded at build time.
find_package(Threads REQUIRED)
find_package(embree 3 REQUIRED)
find_package(TBB REQUIRED)
find_package(glm REQUIRED)
find_package(TinyGLTF REQUIRED)
# OpenEXR 3.1 (libopenexr-dev): every compression for environment maps,
# `compare` inputs and .exr output.
find_package(OpenEXR 3 REQUIRED)
# libpng (libpng-dev): 8-bit PNG textures, twice as fast as stb's decoder.
find_package(PNG REQUIRED)

# stb ships headers in /usr/include/stb and one shared library with the
# implementations (libstb-dev).
find_path(STB_INCLUDE_DIR stb_image.h PATH_SUFFIXES stb REQUIRED)
find_library(STB_LIBRARY NAMES stb REQUIRED)
add_library(tandem_stb INTERFACE)
target_include_directories(tandem_stb SYSTEM INTERFACE ${STB_INCLUDE_DIR})
target_link_libraries(tandem_stb INTERFACE ${STB_LIBRARY})

# --- tandem-view: SDL2 window, OpenGL 2, Dear ImGui ---------------
# Debian's libimgui-dev ships one static library with the SDL2 platform and
# OpenGL 2/3 renderer backends (headers in /usr/include/imgui[/backends]);
# its font rasteriser uses libstb. tandem-view is skipped, with a message,
# when any of these is missing; the window-free view logic always builds.
find_package(SDL2 CONFIG QUIET)
set(OpenGL_GL_PREFERENCE GLVND)
find_package(OpenGL QUIET)
find_path(IMGUI_INCLUDE_DIR imgui.h PATH_SUFFIXES imgui)
find_library(IMGUI_LIBRARY NAMES imgui)
set(TANDEM_VIEW_DEPS_MISSING "")
if(NOT TARGET SDL2::SDL2)
  list(APPEND TANDEM_VIEW_DEPS_MISSING "SDL2 (libsdl2-dev)")
endif()
if(NOT TARGET OpenGL::GL)
  list(APPEND TANDEM_VIEW_DEPS_MISSING "OpenGL (libgl-dev)")
endif()
if(NOT IMGUI_INCLUDE_DIR OR NOT IMGUI_LIBRARY OR NOT EXISTS "${IMGUI_INCLUDE_DIR}/backends/imgui_impl_sdl.h")
  list(APPEND TANDEM_VIEW_DEPS_MISSING "Dear ImGui with SDL2/OpenGL2 backends (libimgui-dev)")
endif()
if(TANDEM_VIEW_DEPS_MISSING)
  set(TANDEM_HAVE_VIEW_DEPS OFF)
else()
  set(TANDEM_HAVE_VIEW_DEPS ON)
  add_library(tandem_view_deps INTERFACE)
  target_include_directories(tandem_view_deps SYSTEM INTERFACE ${IMGUI_INCLUDE_DIR}
                                                               ${IMGUI_INCLUDE_DIR}/backends)
  target_link_libraries(tandem_view_deps INTERFACE ${IMGUI_LIBRARY} tandem_stb SDL2::SDL2 OpenGL::GL
                                                   ${CMAKE_DL_LIBS})
endif()
