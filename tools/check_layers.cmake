# Checks that every #include "..." in the source tree goes down the layer
# table, never up or sideways. The table is read from DEVELOPERS.md
# ("Layers"), the one place it is written: each row that starts with a floor
# number names a folder in backquotes in its second column and the folders
# it may include in its third. Run as
#   cmake -DROOT=<source dir> -P tools/check_layers.cmake
# (ctest runs it as `project_layers`). An include of a folder that the
# including folder may not see fails with the file, the line and the rule.
#
cmake_minimum_required(VERSION 3.20)

# Folders whose files may include anything (they test or measure the rest).
set(TANDEM_LAYER_FREE tests tools)

if(NOT ROOT)
  message(FATAL_ERROR "usage: cmake -DROOT=<source dir> -P check_layers.cmake")
endif()

# TANDEM_LAYER_RULES: "folder:allowed,allowed,...", one per table row.
file(STRINGS "${ROOT}/DEVELOPERS.md" table_rows REGEX "^\\| *[0-9]+ *\\|")
set(TANDEM_LAYER_RULES "")
foreach(row IN LISTS table_rows)
  # Columns: "", floor, folder, may include, why.
  string(REPLACE "|" ";" columns "${row}")
  list(GET columns 2 folder_column)
  list(GET columns 3 allowed_column)
  string(REGEX MATCHALL "`[^`]+`" folder "${folder_column}")
  list(LENGTH folder n)
  if(NOT n EQUAL 1)
    message(FATAL_ERROR "DEVELOPERS.md: a layer row must name one folder: ${row}")
  endif()
  string(REPLACE "`" "" folder "${folder}")
  string(REGEX MATCHALL "`[^`]+`" allowed "${allowed_column}")
  string(REPLACE "`" "" allowed "${allowed}")
  string(REPLACE ";" "," allowed_csv "${allowed}")
  list(APPEND TANDEM_LAYER_RULES "${folder}:${allowed_csv}")
endforeach()
list(LENGTH TANDEM_LAYER_RULES rule_count)
if(rule_count LESS 10)
  message(FATAL_ERROR "DEVELOPERS.md: the layer table has ${rule_count} rows; is it still there?")
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
