# Per-target settings for project code: warnings, sanitizers. No global flags.

function(hwr_target_settings target)
  if(CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
    target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor)
    if(HWR_WERROR)
      target_compile_options(${target} PRIVATE -Werror)
    endif()
  endif()
  if(HWR_SANITIZE)
    target_compile_options(${target} PRIVATE -fsanitize=address,undefined -fno-omit-frame-pointer)
    target_link_options(${target} PRIVATE -fsanitize=address,undefined)
  endif()
endfunction()

# hwr_add_module(<name> SOURCES ... DEPS ...): library hwr_<name> with public headers in
# <dir>/include (hwr/<name>/...) and private sources in <dir>/src.
function(hwr_add_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  if(NOT ARG_SOURCES)
    # A module with no compiled sources yet is a header-only (INTERFACE) target.
    add_library(hwr_${name} INTERFACE)
    add_library(hwr::${name} ALIAS hwr_${name})
    target_include_directories(hwr_${name} INTERFACE ${CMAKE_CURRENT_SOURCE_DIR}/include)
    target_link_libraries(hwr_${name} INTERFACE ${ARG_PUBLIC_DEPS})
    return()
  endif()
  add_library(hwr_${name} ${ARG_SOURCES})
  add_library(hwr::${name} ALIAS hwr_${name})
  target_include_directories(hwr_${name} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include)
  target_link_libraries(hwr_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  hwr_target_settings(hwr_${name})
endfunction()

# hwr_add_app(<exe name> SOURCES ... DEPS ...): a thin main.
function(hwr_add_app name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS})
  hwr_target_settings(${name})
endfunction()
