# ctest driver of examples/c (see CMakeLists.txt).
# -D BUILD_DIR, SOURCE_DIR, WORK_DIR, DECALPREP, LIBDIR, INCLUDEDIR required.
cmake_minimum_required(VERSION 3.25)
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})
set(prefix ${WORK_DIR}/prefix)

# run(<output variable> command...): runs it, fails the test on a nonzero exit.
function(run out)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE stdout ERROR_VARIABLE stderr)
  if(NOT rc EQUAL 0)
    string(REPLACE ";" " " cmd "${ARGN}")
    message(FATAL_ERROR "failed (${rc}): ${cmd}\n${stdout}\n${stderr}")
  endif()
  set(${out} "${stdout}" PARENT_SCOPE)
endfunction()

# 1. Install the C API component; it holds exactly the library (with its
#    SONAME and development symlinks), the header and the pkg-config file.
run(ignored ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix} --component decal)
file(GLOB_RECURSE installed LIST_DIRECTORIES false RELATIVE ${prefix} ${prefix}/*)
list(SORT installed)
set(expected ${INCLUDEDIR}/decal/decal.h ${LIBDIR}/libdecal.so ${LIBDIR}/libdecal.so.1)
file(GLOB real RELATIVE ${prefix} ${prefix}/${LIBDIR}/libdecal.so.1.*)
list(APPEND expected ${real} ${LIBDIR}/pkgconfig/decal.pc)
list(SORT expected)
if(NOT installed STREQUAL expected OR NOT real)
  message(FATAL_ERROR "the decal component installed\n  ${installed}\nexpected\n  ${expected}")
endif()
foreach(link libdecal.so libdecal.so.1)
  if(NOT IS_SYMLINK ${prefix}/${LIBDIR}/${link})
    message(FATAL_ERROR "${LIBDIR}/${link} is not a symbolic link")
  endif()
endforeach()

# 2. Compile print_blobs.c against that prefix alone: pkg-config sees only
#    the prefix's decal.pc, and its flags must name the prefix.
set(ENV{PKG_CONFIG_LIBDIR} ${prefix}/${LIBDIR}/pkgconfig)
set(ENV{PKG_CONFIG_PATH} "")
run(flags pkg-config --cflags --libs decal)
string(STRIP "${flags}" flags)
if(NOT flags STREQUAL "-I${prefix}/${INCLUDEDIR} -L${prefix}/${LIBDIR} -ldecal")
  message(FATAL_ERROR "pkg-config --cflags --libs decal gave '${flags}'")
endif()
separate_arguments(flags UNIX_COMMAND "${flags}")
set(exe ${WORK_DIR}/print_blobs)
run(ignored cc -std=c99 -Wall -Wextra -pedantic -Werror ${SOURCE_DIR}/examples/c/print_blobs.c
    ${flags} -Wl,-rpath,${prefix}/${LIBDIR} -o ${exe})
# It must load the installed library, not one from the build tree.
run(deps ldd ${exe})
if(NOT deps MATCHES "libdecal\\.so\\.1 => ${prefix}/${LIBDIR}/libdecal\\.so\\.1 ")
  message(FATAL_ERROR "print_blobs does not load ${prefix}/${LIBDIR}/libdecal.so.1:\n${deps}")
endif()

# 3. Packages: the valid seeds, and one decalprep builds from samples/monaco.
file(GLOB packages ${SOURCE_DIR}/fuzz/corpus/read/valid_*.decals)
run(ignored ${DECALPREP} build ${SOURCE_DIR}/samples/monaco/scene.toml -o ${WORK_DIR}/monaco.decals)
list(APPEND packages ${WORK_DIR}/monaco.decals)

# 4. Every row of print_blobs against `decalprep info --json`.
set(fields index id name type stride count codec stored_size raw_size)
set(rows_checked 0)
foreach(package ${packages})
  run(table ${exe} ${package})
  run(json ${DECALPREP} info --json ${package})
  string(JSON major GET "${json}" version major)
  string(JSON minor GET "${json}" version minor)
  string(JSON n LENGTH "${json}" blobs)
  string(REPLACE "\n" ";" lines "${table}")
  list(POP_BACK lines last)  # the empty string after the final newline
  list(POP_FRONT lines head)
  if(NOT last STREQUAL "" OR NOT head STREQUAL "package ${package} ${major}.${minor} ${n}")
    message(FATAL_ERROR "${package}: first line '${head}', expected 'package ${package} "
                        "${major}.${minor} ${n}'")
  endif()
  list(LENGTH lines rows)
  if(NOT rows EQUAL n)
    message(FATAL_ERROR "${package}: print_blobs printed ${rows} rows, info --json has ${n} blobs")
  endif()
  set(i 0)
  foreach(line ${lines})
    # Row i is blob i (file order), and its first column says so.
    string(REPLACE "\t" ";" got "${line}")
    set(want "")
    foreach(field ${fields})
      string(JSON value GET "${json}" blobs ${i} ${field})
      list(APPEND want "${value}")
    endforeach()
    if(NOT got STREQUAL want)
      message(FATAL_ERROR "${package}: blob ${i}\n  print_blobs:    ${got}\n  info --json:    ${want}")
    endif()
    math(EXPR rows_checked "${rows_checked} + 1")
    math(EXPR i "${i} + 1")
  endforeach()
endforeach()
list(LENGTH packages n_packages)
message("print_blobs agrees with decalprep info --json on ${rows_checked} blobs of ${n_packages} packages")
