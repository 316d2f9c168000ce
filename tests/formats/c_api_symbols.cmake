# ctest driver: the dynamic symbols libdecal defines are exactly the
# functions formats/include/decal/decal.h declares (DECAL_API ... decal_*),
# plus the version node of its linker version script (formats/src/decal.map);
# and its SONAME is libdecal.so.<C API major>.
# -D LIBRARY (the built libdecal.so...), HEADER (decal.h) required.
cmake_minimum_required(VERSION 3.25)
execute_process(COMMAND nm -D --defined-only ${LIBRARY} RESULT_VARIABLE rc OUTPUT_VARIABLE nm_out
                ERROR_VARIABLE nm_err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "nm -D --defined-only ${LIBRARY} failed: ${nm_err}")
endif()
string(REGEX MATCHALL "[^\n]+" lines "${nm_out}")
set(exported "")
foreach(line ${lines})
  # "<address> <type> <name>[@@version]"
  if(NOT line MATCHES "^[0-9a-fA-F]* *([A-Za-z]) ([^ @]+)(@.*)?$")
    message(FATAL_ERROR "unexpected nm line: ${line}")
  endif()
  set(type ${CMAKE_MATCH_1})
  set(name ${CMAKE_MATCH_2})
  # The version node is an absolute symbol: DECAL_<major>.
  if(type STREQUAL "A" AND name MATCHES "^DECAL_[0-9]+$")
    set(version_node ${name})
    continue()
  endif()
  list(APPEND exported ${name})
endforeach()

file(READ ${HEADER} header)
string(REGEX MATCHALL "DECAL_API[^;(]*[ *](decal_[a-z0-9_]+)\\(" declarations "${header}")
set(declared "")
foreach(d ${declarations})
  string(REGEX REPLACE ".*[ *](decal_[a-z0-9_]+)\\($" "\\1" name "${d}")
  list(APPEND declared ${name})
endforeach()
string(REGEX MATCH "#define DECAL_C_API_VERSION_MAJOR ([0-9]+)" ignored "${header}")
set(major ${CMAKE_MATCH_1})

list(SORT exported)
list(SORT declared)
list(LENGTH declared n)
if(n LESS 10)
  message(FATAL_ERROR "found only ${n} DECAL_API functions in ${HEADER}: ${declared}")
endif()
if(NOT exported STREQUAL declared)
  set(extra ${exported})
  list(REMOVE_ITEM extra ${declared})
  set(missing ${declared})
  list(REMOVE_ITEM missing ${exported})
  message(FATAL_ERROR "${LIBRARY} exports symbols other than decal.h's functions\n"
                      "  not in decal.h: ${extra}\n  not exported: ${missing}")
endif()
if(NOT version_node STREQUAL "DECAL_${major}")
  message(FATAL_ERROR "version node '${version_node}', expected DECAL_${major}")
endif()

execute_process(COMMAND objdump -p ${LIBRARY} OUTPUT_VARIABLE dyn RESULT_VARIABLE rc)
if(NOT rc EQUAL 0 OR NOT dyn MATCHES "SONAME +libdecal\\.so\\.${major}\n")
  message(FATAL_ERROR "SONAME of ${LIBRARY} is not libdecal.so.${major}:\n${dyn}")
endif()
list(LENGTH exported n)
message("${LIBRARY}: exports exactly the ${n} decal_* functions of decal.h, version node "
        "DECAL_${major}, SONAME libdecal.so.${major}")
