# shared_math.cmake: the rule of common/shared/compat.h, checked: the shared math (compiled as C++
# by the reference and as GLSL by the shaders) uses no float `/`, `sqrt`, `inversesqrt`,
# `normalize` or `length` built-in, whose results differ by ulps between devices; sh_div, sh_rcp,
# sh_sqrt and sh_normalize are correctly rounded everywhere (docs/SPEC.md, "Division and square
# root"). rounding.h implements them and compat.h maps names, so both are exempt. Integer division
# is written sh_udiv(a, b) (compat.h), or `/` by an unsigned literal (`/ 2u`).
#   cmake -DSHARED_DIR=<common/shared> -P shared_math.cmake
cmake_minimum_required(VERSION 3.20)
if(NOT SHARED_DIR)
  message(FATAL_ERROR "SHARED_DIR not set")
endif()
file(GLOB headers "${SHARED_DIR}/*.h")
if(NOT headers)
  message(FATAL_ERROR "no headers in ${SHARED_DIR}")
endif()
set(found "")
set(checked 0)
foreach(h IN LISTS headers)
  get_filename_component(name "${h}" NAME)
  if(name STREQUAL "rounding.h" OR name STREQUAL "compat.h")
    continue()
  endif()
  math(EXPR checked "${checked} + 1")
  # One list element per line: ';' and brackets (list syntax in CMake) are masked first
  file(READ "${h}" content)
  string(REPLACE ";" "<sc>" content "${content}")
  string(REPLACE "[" "<lb>" content "${content}")
  string(REPLACE "]" "<rb>" content "${content}")
  string(REPLACE "\n" ";" lines "${content}")
  set(n 0)
  foreach(line IN LISTS lines)
    math(EXPR n "${n} + 1")
    string(REGEX REPLACE "//.*$" "" code "${line}")         # line comments
    string(REGEX REPLACE "/\\*.*\\*/" "" code "${code}")     # one-line block comments
    string(REGEX REPLACE "#[ ]*include.*$" "" code "${code}")  # include paths
    string(REGEX REPLACE "/[ ]*[0-9]+u" "" code "${code}")   # integer division by a uint literal
    if(code MATCHES "/" OR code MATCHES "(^|[^_a-zA-Z0-9])(sqrt|inversesqrt|normalize|length)[ ]*\\(")
      string(STRIP "${line}" shown)
      string(REPLACE "<sc>" ";" shown "${shown}")
      string(APPEND found "\n  ${name}:${n}: ${shown}")
    endif()
  endforeach()
endforeach()
if(found)
  message(FATAL_ERROR "float division or square root built-ins in the shared math "
                      "(use sh_div / sh_rcp / sh_sqrt / sh_normalize):${found}")
endif()
message(STATUS "shared math: ${checked} headers use only correctly rounded division and square root")
