# The Debian package (.deb) of everything `cmake --install` installs, made by
# CPack: `cpack -G DEB --config <build>/CPackConfig.cmake`, or scripts/package,
# which also builds what the package holds. One package (monolithic): every
# install component lands in it, so a component added later needs no change
# here. Its version is project(VERSION), the one place it is set.
#
# Besides the targets' own install rules, this file installs the man pages
# (generated from --help at build time, cmake/manpages.cmake), the README, the
# copyright file and a Debian changelog under /usr/share/doc/decalprep/.
# tests/packaging builds the .deb, runs lintian on it and installs it into a
# clean Debian root.

set(DECALPREP_PACKAGE_MAINTAINER
    "decalprep maintainers <maintainers@users.noreply.h-seed-a31dc569.example>"
    CACHE STRING "Maintainer field of the Debian package (and its changelog), as 'Name <address>'")

# --- Man pages from --help --------------------------------------------------
# help2man turns `decalprep --help` into decalprep.1 and each subcommand's
# `decalprep <command> --help` into decalprep-<command>.1. The subcommands are
# read from the tool's own help, so a new cmd_*.cpp gets its page unasked.
find_program(DECALPREP_HELP2MAN help2man)
set(DECALPREP_MAN_DIR ${CMAKE_BINARY_DIR}/man)
if(DECALPREP_HELP2MAN)
  add_custom_command(
    OUTPUT ${DECALPREP_MAN_DIR}/stamp
    COMMAND ${CMAKE_COMMAND} -DTOOL=$<TARGET_FILE:decalprep> -DHELP2MAN=${DECALPREP_HELP2MAN}
            -DVERSION=${PROJECT_VERSION} -DOUT_DIR=${DECALPREP_MAN_DIR}
            -P ${CMAKE_CURRENT_LIST_DIR}/manpages.cmake
    DEPENDS decalprep ${CMAKE_CURRENT_LIST_DIR}/manpages.cmake
    COMMENT "Man pages from decalprep --help (help2man)")
  add_custom_target(decalprep_man ALL DEPENDS ${DECALPREP_MAN_DIR}/stamp)
  install(DIRECTORY ${DECALPREP_MAN_DIR}/man1 DESTINATION ${CMAKE_INSTALL_MANDIR}
          COMPONENT decalprep FILES_MATCHING PATTERN "*.1.gz")
else()
  message(STATUS "help2man not found: no man pages (scripts/deps installs it)")
endif()

# --- /usr/share/doc/decalprep ---------------------------------------------
# The changelog is generated: one entry for this version, dated at configure
# time (SOURCE_DATE_EPOCH, when set, fixes the date for a reproducible build).
# Debian wants it, and the man pages, compressed with gzip -9n.
string(TIMESTAMP DECALPREP_PACKAGE_DATE "%a, %d %b %Y %H:%M:%S +0000" UTC)
set(DECALPREP_DOC_DIR ${CMAKE_BINARY_DIR}/doc)
configure_file(${CMAKE_CURRENT_LIST_DIR}/debian/changelog.in ${DECALPREP_DOC_DIR}/changelog @ONLY)
find_program(DECALPREP_GZIP gzip REQUIRED)
add_custom_command(
  OUTPUT ${DECALPREP_DOC_DIR}/changelog.gz
  COMMAND ${DECALPREP_GZIP} -9nf -k ${DECALPREP_DOC_DIR}/changelog
  DEPENDS ${DECALPREP_DOC_DIR}/changelog
  COMMENT "Compressing the Debian changelog")
add_custom_target(decalprep_changelog ALL DEPENDS ${DECALPREP_DOC_DIR}/changelog.gz)
install(FILES ${PROJECT_SOURCE_DIR}/README.md ${CMAKE_CURRENT_LIST_DIR}/debian/copyright
              ${DECALPREP_DOC_DIR}/changelog.gz
        DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT decalprep)

# --- What the package needs built ------------------------------------------
# cpack installs from the build tree and builds nothing, so every file an
# install rule names must exist first. `decalprep_package_contents` builds
# them without the tests and benchmarks: every library and program defined
# under formats/ and tools/ (a library added there later is picked up), the
# man pages and the changelog.
function(decalprep_collect_targets dir out)
  get_property(targets DIRECTORY ${dir} PROPERTY BUILDSYSTEM_TARGETS)
  set(found "")
  foreach(t IN LISTS targets)
    get_target_property(type ${t} TYPE)
    if(type MATCHES "^(EXECUTABLE|STATIC_LIBRARY|SHARED_LIBRARY|MODULE_LIBRARY|OBJECT_LIBRARY)$")
      list(APPEND found ${t})
    endif()
  endforeach()
  get_property(subdirs DIRECTORY ${dir} PROPERTY SUBDIRECTORIES)
  foreach(sub IN LISTS subdirs)
    decalprep_collect_targets(${sub} sub_found)
    list(APPEND found ${sub_found})
  endforeach()
  set(${out} ${found} PARENT_SCOPE)
endfunction()
decalprep_collect_targets(${PROJECT_SOURCE_DIR}/formats formats_targets)
decalprep_collect_targets(${PROJECT_SOURCE_DIR}/tools tools_targets)
add_custom_target(decalprep_package_contents)
add_dependencies(decalprep_package_contents ${formats_targets} ${tools_targets}
                 decalprep_changelog)
if(DECALPREP_HELP2MAN)
  add_dependencies(decalprep_package_contents decalprep_man)
endif()

# --- CPack -------------------------------------------------------------------
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME decalprep)
set(CPACK_PACKAGE_VENDOR "decalprep")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DIRECTORY ${CMAKE_BINARY_DIR}/packages)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_PACKAGE_CONTACT "${DECALPREP_PACKAGE_MAINTAINER}")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "GIS vector data to GPU-ready decal packages")
set(CPACK_PACKAGE_DESCRIPTION
    "decalprep reads GIS vector layers (any source GDAL opens), projects them into a\n\
local metric frame, cleans and triangulates them, and writes binary decal\n\
packages that a GPU draws over terrain. It verifies, dumps and renders\n\
packages (headless GL, or a CPU evaluator) and serves them to a browser viewer\n\
built into the program.\n\
\n\
The package also holds decal_reader, the static library that opens and\n\
validates decal packages, with its headers and CMake configuration.")
set(CPACK_STRIP_FILES ON)
# One .deb whatever the install components.
set(CPACK_DEB_COMPONENT_INSTALL OFF)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
# Depends: what dpkg-shlibdeps finds the installed programs and shared
# libraries linked against; never a hand-written list.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# A shared library installed later gets a shlibs file, and the ldconfig
# trigger (cmake/debian/ldconfig_trigger.cmake looks for one in what was
# installed).
set(CPACK_DEBIAN_PACKAGE_GENERATE_SHLIBS ON)
set(CPACK_DEBIAN_PACKAGE_GENERATE_SHLIBS_POLICY ">=")
set(CPACK_DECALPREP_TRIGGERS_FILE ${CMAKE_CURRENT_LIST_DIR}/debian/triggers)
set(CPACK_PRE_BUILD_SCRIPTS ${CMAKE_CURRENT_LIST_DIR}/debian/ldconfig_trigger.cmake)
# Recommends: GL rendering (render without --cpu) loads an EGL driver through
# libglvnd at run time, which no link shows; Mesa's is the one that draws
# without a GPU (llvmpipe).
if(DECALPREP_GL)
  set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "libegl-mesa0, libgl1-mesa-dri")
endif()
# Suggests: `view --screenshot` runs a headless Chromium; a project that
# builds against decal_reader (find_package) needs zstd's and xxHash's
# development files and pkg-config, as decal_readerConfig.cmake says.
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "chromium, cmake, pkg-config, libzstd-dev, libxxhash-dev")
include(CPack)
