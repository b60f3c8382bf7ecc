# Finds the OpenCV modules the project uses and provides targets opencv_<module>.
# On the host, Debian's libopencv-dev ships OpenCVConfig.cmake. For the arm64 cross build only the
# per-module -dev packages can be installed beside the amd64 ones (libopencv-dev is not
# multi-arch co-installable) and they carry no CMake config, so each module is imported directly.
set(HWR_OPENCV_MODULES core imgproc imgcodecs calib3d features2d flann dnn)
find_package(OpenCV QUIET COMPONENTS ${HWR_OPENCV_MODULES})
if(OpenCV_FOUND)
  message(STATUS "OpenCV ${OpenCV_VERSION} (CMake config)")
  return()
endif()

find_path(HWR_OPENCV_INCLUDE_DIR opencv2/core.hpp PATH_SUFFIXES opencv4)
find_path(HWR_OPENCV_ARCH_INCLUDE_DIR opencv2/opencv_modules.hpp PATH_SUFFIXES opencv4)
if(NOT HWR_OPENCV_INCLUDE_DIR OR NOT HWR_OPENCV_ARCH_INCLUDE_DIR)
  message(FATAL_ERROR "OpenCV headers not found: run toolchain/install-deps.sh (--agx for the cross build)")
endif()
foreach(module IN LISTS HWR_OPENCV_MODULES)
  find_library(HWR_OPENCV_${module}_LIBRARY opencv_${module})
  if(NOT HWR_OPENCV_${module}_LIBRARY)
    message(FATAL_ERROR "libopencv_${module} not found: run toolchain/install-deps.sh (--agx for the cross build)")
  endif()
  add_library(opencv_${module} SHARED IMPORTED GLOBAL)
  set_target_properties(opencv_${module} PROPERTIES
    IMPORTED_LOCATION "${HWR_OPENCV_${module}_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${HWR_OPENCV_INCLUDE_DIR};${HWR_OPENCV_ARCH_INCLUDE_DIR}")
endforeach()
message(STATUS "OpenCV per-module libraries (${HWR_OPENCV_core_LIBRARY})")
