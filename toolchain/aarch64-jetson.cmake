# Cross build for the NVIDIA Jetson AGX (aarch64) with Debian's aarch64-linux-gnu GCC.
#   HWR_AGX_CPU=orin   (default) -mcpu=cortex-a78ae   (Jetson AGX Orin)
#   HWR_AGX_CPU=xavier           -march=armv8.2-a     (Jetson AGX Xavier, Carmel has no GCC -mcpu name)
#   HWR_SYSROOT=/path            the sysroot to build against. Default: build/agx-sysroot, made by
#                                toolchain/make-agx-sysroot.sh from Debian 12 arm64 packages (proves the
#                                code builds and passes its tests on aarch64, under qemu). For a binary
#                                that runs on the device, pass a JetPack sysroot (older glibc).
# CPU flags live here only (STYLE.md rule 9).
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)

set(HWR_AGX_CPU "orin" CACHE STRING "Jetson CPU: orin or xavier")
set_property(CACHE HWR_AGX_CPU PROPERTY STRINGS orin xavier)
set(HWR_SYSROOT "${CMAKE_CURRENT_LIST_DIR}/../build/agx-sysroot" CACHE PATH "aarch64 sysroot")
# try_compile projects (compiler checks) read this file again: hand them the same choices.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES HWR_SYSROOT HWR_AGX_CPU)

set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)

if(HWR_AGX_CPU STREQUAL "orin")
  set(_hwr_cpu_flags "-mcpu=cortex-a78ae")
elseif(HWR_AGX_CPU STREQUAL "xavier")
  set(_hwr_cpu_flags "-march=armv8.2-a")
else()
  message(FATAL_ERROR "HWR_AGX_CPU must be 'orin' or 'xavier', got '${HWR_AGX_CPU}'")
endif()
set(CMAKE_C_FLAGS_INIT "${_hwr_cpu_flags}")
set(CMAKE_CXX_FLAGS_INIT "${_hwr_cpu_flags}")

if(NOT EXISTS "${HWR_SYSROOT}/usr/include")
  message(FATAL_ERROR "aarch64 sysroot '${HWR_SYSROOT}' not found: run toolchain/install-deps.sh --agx "
                      "(or pass -DHWR_SYSROOT=/path/to/jetpack-sysroot)")
endif()
set(CMAKE_SYSROOT "${HWR_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH "${HWR_SYSROOT}")
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE BOTH)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)

# Unit tests run on the host through qemu (Debian qemu-user).
find_program(HWR_QEMU_AARCH64 NAMES qemu-aarch64 qemu-aarch64-static)
if(HWR_QEMU_AARCH64)
  set(CMAKE_CROSSCOMPILING_EMULATOR "${HWR_QEMU_AARCH64};-L;${HWR_SYSROOT}")
endif()
