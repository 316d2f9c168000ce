# Writes OUT_DIR/man1: decalprep.1.gz from `decalprep --help`, and
# decalprep-<command>.1.gz from `decalprep <command> --help` for every
# subcommand the tool lists under "Subcommands:", by help2man; then
# OUT_DIR/stamp. Pages are compressed with gzip -9n, as Debian wants.
# Usage: cmake -DTOOL=... -DHELP2MAN=... -DVERSION=... -DOUT_DIR=... -P manpages.cmake
foreach(var TOOL HELP2MAN VERSION OUT_DIR)
  if(NOT ${var})
    message(FATAL_ERROR "manpages.cmake: ${var} is not set")
  endif()
endforeach()
find_program(GZIP gzip REQUIRED)

# help2man prints the usage lines as the program prints them, argv[0]
# included; the tool is run by name from PATH so that they read
# "decalprep ...", not a build path.
get_filename_component(tool_dir ${TOOL} DIRECTORY)
set(bin_dir ${OUT_DIR}/bin)
file(REMOVE_RECURSE ${OUT_DIR}/man1 ${bin_dir})
file(MAKE_DIRECTORY ${OUT_DIR}/man1 ${bin_dir})
set(ENV{PATH} "${bin_dir}:${tool_dir}:$ENV{PATH}")
# Column-wrapped help text: a fixed width, whatever the terminal.
set(ENV{COLUMNS} 80)

execute_process(COMMAND decalprep --help OUTPUT_VARIABLE help RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "manpages.cmake: decalprep --help exited ${rc}")
endif()

# "Subcommands:" then one "  name   description" line each, to a blank line.
string(REGEX MATCH "\nSubcommands:\n(([ ]+[^\n]*\n)+)" block "${help}")
string(REPLACE "\n" ";" lines "${CMAKE_MATCH_1}")
set(commands "")
foreach(line IN LISTS lines)
  if(line MATCHES "^[ ]+([a-z][a-z0-9-]*)[ ]+(.+)$")
    list(APPEND commands ${CMAKE_MATCH_1})
    set(summary_${CMAKE_MATCH_1} "${CMAKE_MATCH_2}")
  endif()
endforeach()
if(NOT commands)
  message(FATAL_ERROR "manpages.cmake: no subcommands in decalprep --help:\n${help}")
endif()

set(see_also ".BR decalprep (1)")
foreach(c IN LISTS commands)
  string(APPEND see_also ",\n.BR decalprep\\-${c} (1)")
endforeach()
file(WRITE ${OUT_DIR}/see-also.h2m "[SEE ALSO]\n${see_also}\n")

# help2man NAME PROGRAM SUMMARY
function(man_page name program summary)
  execute_process(
    COMMAND ${HELP2MAN} --no-info --no-discard-stderr --section=1
            --version-string=${VERSION} --name=${summary}
            --include=${OUT_DIR}/see-also.h2m --output=${OUT_DIR}/man1/${name}.1 ${program}
    RESULT_VARIABLE rc ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "manpages.cmake: help2man for ${name} failed (${rc}): ${err}")
  endif()
  execute_process(COMMAND ${GZIP} -9nf ${OUT_DIR}/man1/${name}.1 RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "manpages.cmake: gzip ${name}.1 failed (${rc})")
  endif()
endfunction()

man_page(decalprep decalprep "GIS vector data to GPU-ready decal packages")
foreach(c IN LISTS commands)
  # help2man runs a program; this one runs the subcommand.
  file(WRITE ${bin_dir}/decalprep-${c} "#!/bin/sh\nexec decalprep ${c} \"$@\"\n")
  file(CHMOD ${bin_dir}/decalprep-${c} PERMISSIONS OWNER_READ OWNER_WRITE OWNER_EXECUTE)
  man_page(decalprep-${c} decalprep-${c} "${summary_${c}}")
endforeach()
file(WRITE ${OUT_DIR}/stamp "")
