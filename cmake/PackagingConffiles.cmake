# CPack pre-build script (runs after the files are staged): writes the
# Debian conffiles list, every staged file under /etc, to the file named by
# CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA.
file(GLOB_RECURSE staged_etc LIST_DIRECTORIES false
  RELATIVE ${CPACK_TEMPORARY_INSTALL_DIRECTORY} ${CPACK_TEMPORARY_INSTALL_DIRECTORY}/etc/*)
set(conffiles "")
foreach(file IN LISTS staged_etc)
  string(APPEND conffiles "/${file}\n")
endforeach()
file(WRITE ${CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA} "${conffiles}")
