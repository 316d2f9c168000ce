# ctest driver: installs the decal_reader component of the build tree into a
# fresh prefix, configures and builds examples/cmake against that
# prefix alone, and runs it on checked-in seed packages (fuzz/corpus/read/),
# valid ones must open and broken ones must be refused.
# -D BUILD_DIR, SOURCE_DIR, WORK_DIR, CMAKE_GENERATOR_NAME required.
file(REMOVE_RECURSE ${WORK_DIR})
set(prefix ${WORK_DIR}/prefix)

function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
  message("${out}")
  if(NOT rc EQUAL 0)
    string(REPLACE ";" " " cmd "${ARGN}")
    message(FATAL_ERROR "failed (${rc}): ${cmd}")
  endif()
endfunction()

run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix} --component decal_reader)
# Nothing else of decalprep may land in the prefix: the component is the reader.
file(GLOB_RECURSE installed RELATIVE ${prefix} ${prefix}/*)
foreach(f ${installed})
  if(NOT f MATCHES "^(include/decal/|lib[^/]*/(libdecal_reader\\.a|cmake/decal_reader/))")
    message(FATAL_ERROR "unexpected file in the decal_reader component: ${f}")
  endif()
endforeach()

# CMAKE_FIND_USE_PACKAGE_REGISTRY off and only the prefix on the path, so the
# build tree cannot stand in for the installed package.
run(${CMAKE_COMMAND} -S ${SOURCE_DIR}/examples/cmake -B ${WORK_DIR}/build -G ${CMAKE_GENERATOR_NAME}
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH=${prefix} -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF)
run(${CMAKE_COMMAND} --build ${WORK_DIR}/build)
file(GLOB seeds ${SOURCE_DIR}/fuzz/corpus/read/*.decals)
list(LENGTH seeds n)
if(n LESS 3)
  message(FATAL_ERROR "expected the seed packages in fuzz/corpus/read/, found ${n}")
endif()
run(${WORK_DIR}/build/consumer ${seeds})
