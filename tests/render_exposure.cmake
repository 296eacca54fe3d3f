# `lumesh render --exposure E`: the picture's exposure reaches the cache, whose
# tests judge the colours at it (cache_set_exposure; docs/viewer.md, "Exposure").
# The built-in Cornell box at 64x48 until the cache has finished, Embree, no
# residual, at the scene's exposure and 3 stops brighter: the stats' estimate says
# which exposure it judged, and the brighter picture, whose dark corners come into
# view, took more leaf tests (measured 4,473 and 5,227). An exposure out of range
# is a usage error (cli_tests.cmake).
#   -DLUMESH=path -DDIR=work directory
cmake_minimum_required(VERSION 3.19)
file(REMOVE_RECURSE ${DIR})
file(MAKE_DIRECTORY ${DIR})
foreach(e 0 3)
  execute_process(COMMAND ${LUMESH} render -o ${DIR}/box${e}.png --width 64 --height 48 --residual off
                          --sampler embree --exposure ${e} --stats ${DIR}/box${e}.json
                  RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE err TIMEOUT 120)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "render --exposure ${e} failed (${rc}): ${o}${err}")
  endif()
  file(READ ${DIR}/box${e}.json j)
  string(JSON judged GET "${j}" estimated_error exposure)
  string(JSON tested${e} GET "${j}" leaves_tested)
  if(NOT judged EQUAL ${e})
    message(FATAL_ERROR "render --exposure ${e}: the cache's estimate was made at exposure ${judged}")
  endif()
endforeach()
if(NOT tested3 GREATER tested0)
  message(FATAL_ERROR "3 stops brighter the cache tested ${tested3} leaves, at the scene's exposure ${tested0}")
endif()
message(STATUS "ok: the estimate at the exposure asked; leaves tested ${tested0} at 0, ${tested3} at +3")
