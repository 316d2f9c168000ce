# CPACK_PRE_BUILD_SCRIPTS: runs in cpack after the install into the staging
# folder, before the .deb is made. When the package holds a shared library,
# adds the control file `triggers` (activate-noawait ldconfig): dpkg then runs
# ldconfig once after the install, as Debian wants (lintian:
# lacks-ldconfig-trigger). Without one, no trigger (lintian:
# package-has-unnecessary-activation-of-ldconfig-trigger).
file(GLOB_RECURSE shared_objects LIST_DIRECTORIES false
     "${CPACK_TEMPORARY_INSTALL_DIRECTORY}/*.so.*" "${CPACK_TEMPORARY_INSTALL_DIRECTORY}/*.so")
if(shared_objects)
  list(APPEND CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA "${CPACK_DECALPREP_TRIGGERS_FILE}")
endif()
