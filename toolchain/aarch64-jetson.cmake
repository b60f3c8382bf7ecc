# Cross build for the NVIDIA Jetson AGX (aarch64) with Debian's aarch64-linux-gnu GCC.
#   HWR_AGX_CPU=orin   (default) -mcpu=cortex-a78ae   (Jetson AGX Orin)
#   HWR_AGX_CPU=xavier           -march=armv8.2-a     (Jetson AGX Xavier, Carmel has no GCC -mcpu name)
#   HWR_SYSROOT=/path            a JetPack sysroot for binaries that must run on the device (older glibc);
#                                empty: Debian's arm64 multiarch packages on this host.
# CPU flags live here only (STYLE.md rule 9).
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)

set(HWR_AGX_CPU "orin" CACHE STRING "Jetson CPU: orin or xavier")
set_property(CACHE HWR_AGX_CPU PROPERTY STRINGS orin xavier)
set(HWR_SYSROOT "" CACHE PATH "JetPack sysroot (empty: Debian arm64 multiarch on this host)")

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

if(HWR_SYSROOT)
  set(CMAKE_SYSROOT "${HWR_SYSROOT}")
  set(CMAKE_FIND_ROOT_PATH "${HWR_SYSROOT}")
else()
  # Debian multiarch: arm64 libraries in /usr/lib/aarch64-linux-gnu, headers shared in /usr/include.
  set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)
  set(CMAKE_FIND_ROOT_PATH /usr/aarch64-linux-gnu /usr)
endif()
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE BOTH)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)

# Unit tests run on the host through qemu (Debian qemu-user).
find_program(HWR_QEMU_AARCH64 NAMES qemu-aarch64 qemu-aarch64-static)
if(HWR_QEMU_AARCH64)
  if(HWR_SYSROOT)
    set(CMAKE_CROSSCOMPILING_EMULATOR "${HWR_QEMU_AARCH64};-L;${HWR_SYSROOT}")
  else()
    set(CMAKE_CROSSCOMPILING_EMULATOR "${HWR_QEMU_AARCH64};-L;/usr/aarch64-linux-gnu")
  endif()
endif()
