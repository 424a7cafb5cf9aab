# Finds the OpenCV modules markloop uses from Debian's per-module packages
# (libopencv-core-dev, libopencv-imgproc-dev, libopencv-imgcodecs-dev).
# Debian ships OpenCVConfig.cmake only in the libopencv-dev meta package,
# which drags in ~140 packages (video codecs, GUI, ...) per architecture; the
# per-module packages carry just headers and libraries, which is all we need,
# natively and in a cross sysroot alike.
#
#   find_package(OpenCV REQUIRED COMPONENTS core imgproc [imgcodecs])
#
# Defines the imported targets OpenCV::<component> and OpenCV_VERSION.

set(_opencv_known_components core imgproc imgcodecs)
if(NOT OpenCV_FIND_COMPONENTS)
  set(OpenCV_FIND_COMPONENTS core)
endif()

find_path(OpenCV_INCLUDE_DIR opencv2/core/version.hpp PATH_SUFFIXES opencv4)
mark_as_advanced(OpenCV_INCLUDE_DIR)

if(OpenCV_INCLUDE_DIR)
  file(STRINGS "${OpenCV_INCLUDE_DIR}/opencv2/core/version.hpp" _opencv_version_lines
       REGEX "#define CV_VERSION_(MAJOR|MINOR|REVISION) ")
  foreach(_part MAJOR MINOR REVISION)
    string(REGEX REPLACE ".*#define CV_VERSION_${_part} +([0-9]+).*" "\\1"
           _opencv_${_part} "${_opencv_version_lines}")
  endforeach()
  set(OpenCV_VERSION "${_opencv_MAJOR}.${_opencv_MINOR}.${_opencv_REVISION}")
endif()

set(_opencv_required_vars OpenCV_INCLUDE_DIR)
foreach(_component IN LISTS OpenCV_FIND_COMPONENTS)
  if(NOT _component IN_LIST _opencv_known_components)
    message(FATAL_ERROR "FindOpenCV: unknown component '${_component}'")
  endif()
  find_library(OpenCV_${_component}_LIBRARY opencv_${_component})
  mark_as_advanced(OpenCV_${_component}_LIBRARY)
  if(OpenCV_${_component}_LIBRARY AND OpenCV_INCLUDE_DIR)
    set(OpenCV_${_component}_FOUND TRUE)
  endif()
  if(OpenCV_FIND_REQUIRED_${_component})
    list(APPEND _opencv_required_vars OpenCV_${_component}_LIBRARY)
  endif()
endforeach()

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(OpenCV
  REQUIRED_VARS ${_opencv_required_vars}
  VERSION_VAR OpenCV_VERSION
  HANDLE_COMPONENTS)

if(OpenCV_FOUND)
  foreach(_component IN LISTS OpenCV_FIND_COMPONENTS)
    if(OpenCV_${_component}_FOUND AND NOT TARGET OpenCV::${_component})
      add_library(OpenCV::${_component} UNKNOWN IMPORTED)
      set_target_properties(OpenCV::${_component} PROPERTIES
        IMPORTED_LOCATION "${OpenCV_${_component}_LIBRARY}"
        INTERFACE_INCLUDE_DIRECTORIES "${OpenCV_INCLUDE_DIR}")
    endif()
  endforeach()
  if(TARGET OpenCV::imgproc AND TARGET OpenCV::core)
    set_property(TARGET OpenCV::imgproc APPEND PROPERTY INTERFACE_LINK_LIBRARIES OpenCV::core)
  endif()
  if(TARGET OpenCV::imgcodecs AND TARGET OpenCV::imgproc)
    set_property(TARGET OpenCV::imgcodecs APPEND PROPERTY INTERFACE_LINK_LIBRARIES OpenCV::imgproc)
  endif()
endif()
