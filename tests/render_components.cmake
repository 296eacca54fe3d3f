# `lumesh render --components`: the terms drawn one at a time add up to the whole
# image. On the built-in Cornell box, deterministic (the same cache each run),
# 48x36, one render per term and one of all; image_sum_check then checks the
# whole against the sum of the parts, and that each part has light. The box has
# no material with ks > 0, so its specular term is zero and left out. A name it
# does not know is a usage error (cli_tests.cmake).
#   -DLUMESH=path -DCHECK=image_sum_check -DDIR=work directory
cmake_minimum_required(VERSION 3.19)
file(REMOVE_RECURSE ${DIR})
file(MAKE_DIRECTORY ${DIR})
set(parts)
foreach(c all direct indirect emission)
  set(args)
  if(NOT c STREQUAL "all")
    set(args --components ${c})
    list(APPEND parts ${DIR}/${c}.exr)
  endif()
  execute_process(COMMAND ${LUMESH} render -o ${DIR}/${c}.exr --width 48 --height 36 --samples 400 --deterministic
                          ${args} RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e TIMEOUT 120)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "render --components ${c} failed (${rc}): ${o}${e}")
  endif()
endforeach()
execute_process(COMMAND ${CHECK} ${DIR}/all.exr ${parts} RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the terms do not add up to the whole image: ${o}${e}")
endif()
message(STATUS "ok: direct + indirect + emission = the whole image\n${o}")
