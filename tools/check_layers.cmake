# Checks that every #include "..." in the source tree goes down the layer
# table of DEVELOPERS.md ("Layers"), never up or sideways. Run as
#   cmake -DROOT=<source dir> -P tools/check_layers.cmake
# (ctest runs it as `project_layers`). An include of a folder that the
# including folder may not see fails with the file, the line and the rule.
#
cmake_minimum_required(VERSION 3.20)

# Each rule: a folder, then the folders its files may include (its own is
# always allowed). A file belongs to the longest folder that names it.
set(TANDEM_LAYER_RULES
  "core/util:"
  "core/kernel:"
  "core/image:core/kernel,core/util"
  "core/world:core/kernel,core/image,core/util"
  "core/render:core/world,core/kernel,core/image,core/util"
  "accstruc:core/world,core/kernel,core/util"
  "scenes:core/world,core/kernel,core/image,core/util"
  "sync:accstruc,core/world,core/kernel,core/image,core/util"
  "backends/cpu_loops:core/render,core/world,core/kernel,core/image,core/util"
  "backends/cpu:backends,backends/cpu_loops,core/render,core/world,core/kernel,core/image,core/util"
  "backends/cuda:backends,backends/cpu_loops,core/render,core/world,core/kernel,core/image,core/util"
  "backends/mpi:backends,core/render,core/world,core/kernel,core/image,core/util"
  "backends:backends/cpu,backends/cuda,core/render,core/world,core/kernel,core/image,core/util"
  "core/tracer:sync,accstruc,core/render,core/world,core/kernel,core/image,core/util"
  "core/api:core/tracer,sync,backends,backends/cuda,scenes,accstruc,core/render,core/world,core/kernel,core/image,core/util"
  "app/view:app,core/tracer,sync,backends,scenes,accstruc,core/render,core/world,core/kernel,core/image,core/util"
  "app:app/view,core/tracer,sync,backends,backends/cpu,backends/mpi,backends/cuda,scenes,accstruc,core/render,core/world,core/kernel,core/image,core/util"
)
# Folders whose files may include anything (they test or measure the rest).
set(TANDEM_LAYER_FREE tests tools)

if(NOT ROOT)
  message(FATAL_ERROR "usage: cmake -DROOT=<source dir> -P check_layers.cmake")
endif()

set(rule_folders "")
foreach(rule IN LISTS TANDEM_LAYER_RULES)
  string(REPLACE ":" ";" parts "${rule}")
  list(GET parts 0 folder)
  list(LENGTH parts n)
  set(allowed "")
  if(n GREATER 1)
    list(GET parts 1 allowed_csv)
    string(REPLACE "," ";" allowed "${allowed_csv}")
  endif()
  list(APPEND rule_folders "${folder}")
  list(PREPEND allowed "${folder}")
  list(REMOVE_ITEM allowed "")
  set("allowed_${folder}" "${allowed}")
endforeach()

# The rule folder a path belongs to: the longest one that is a prefix.
function(layer_of path out)
  set(best "")
  foreach(folder IN LISTS rule_folders)
    string(LENGTH "${folder}" len)
    string(FIND "${path}/" "${folder}/" at)
    if(at EQUAL 0)
      string(LENGTH "${best}" best_len)
      if(len GREATER best_len)
        set(best "${folder}")
      endif()
    endif()
  endforeach()
  set(${out} "${best}" PARENT_SCOPE)
endfunction()

file(GLOB_RECURSE sources RELATIVE "${ROOT}"
  "${ROOT}/*.h" "${ROOT}/*.cpp" "${ROOT}/*.cu" "${ROOT}/*.cuh")
set(violations 0)
set(checked 0)
foreach(source IN LISTS sources)
  if(source MATCHES "^(build|\\.)" OR source MATCHES "/build/")
    continue()
  endif()
  string(REGEX MATCH "^[^/]+" top "${source}")
  if(top IN_LIST TANDEM_LAYER_FREE)
    continue()
  endif()
  get_filename_component(dir "${source}" DIRECTORY)
  layer_of("${dir}" from)
  if(from STREQUAL "")
    continue()  # examples/ and other trees that use only installed headers
  endif()
  math(EXPR checked "${checked} + 1")
  file(STRINGS "${ROOT}/${source}" lines REGEX "^[ \t]*#[ \t]*include[ \t]*\"")
  foreach(line IN LISTS lines)
    string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]*\"([^\"]+)\".*" "\\1" header "${line}")
    if(NOT header MATCHES "/")
      continue()  # a file of the same folder
    endif()
    if(NOT EXISTS "${ROOT}/${header}")
      continue()  # generated in the build tree or a system header
    endif()
    get_filename_component(header_dir "${header}" DIRECTORY)
    layer_of("${header_dir}" to)
    if(to STREQUAL "")
      message(SEND_ERROR "${source}: includes ${header}, which is in no layer of the table")
      math(EXPR violations "${violations} + 1")
    elseif(NOT to IN_LIST allowed_${from})
      string(REPLACE ";" ", " allowed_text "${allowed_${from}}")
      message(SEND_ERROR "${source}: includes ${header} (${to}), but ${from} may only include ${allowed_text}")
      math(EXPR violations "${violations} + 1")
    endif()
  endforeach()
endforeach()

if(checked EQUAL 0)
  message(FATAL_ERROR "no source files found under ${ROOT}")
endif()
if(violations GREATER 0)
  message(FATAL_ERROR "${violations} include(s) break the layer table in DEVELOPERS.md")
endif()
message(STATUS "layers: ${checked} files, every include goes down the table")
