# Debian package of the build (CPack DEB), for the architecture the build
# targets: `cpack --config <build>/CPackConfig.cmake` or the `package` target.
# It holds whatever install() rules the project has (the ECU binary, its
# configuration under /etc/markloop, the DBC in /usr/share/markloop, the
# systemd unit): a new install() rule is packaged without touching this file.
# tests/package/check-deb.sh installs the package into a scratch root.
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME markloop)
set(CPACK_PACKAGE_VENDOR "markloop")
set(CPACK_PACKAGE_CONTACT "markloop developers <markloop@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
  "Place recognition and loop closure from road markings, reported on CAN")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION misc)
set(CPACK_STRIP_FILES ON)

# Debian's name of the target architecture.
if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64)$")
  set(markloop_deb_arch arm64)
elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^arm")
  set(markloop_deb_arch armhf)
elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^(x86_64|AMD64)$")
  set(markloop_deb_arch amd64)
else()
  message(FATAL_ERROR "Packaging: no Debian architecture known for ${CMAKE_SYSTEM_PROCESSOR}")
endif()
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE ${markloop_deb_arch})

# Shared-library dependencies (libstdc++6, libopencv-core406, ...) from
# dpkg-shlibdeps, which finds the target's libraries through the multiarch
# dpkg database; a build against a private sysroot lists them itself.
if(CMAKE_CROSSCOMPILING AND CMAKE_SYSROOT)
  set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS OFF)
  set(CPACK_DEBIAN_PACKAGE_DEPENDS
    "libc6, libstdc++6, libgcc-s1, libopencv-core406, libopencv-imgproc406")
else()
  set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
endif()

# Files installed under /etc are configuration that dpkg must keep when the
# administrator edited it: list them as conffiles once CPack has staged the
# files (so rules added later are covered too).
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA ${CMAKE_BINARY_DIR}/packaging/conffiles)
set(CPACK_PRE_BUILD_SCRIPTS ${CMAKE_CURRENT_LIST_DIR}/PackagingConffiles.cmake)
include(CPack)
