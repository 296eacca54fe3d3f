# lumesh view --indirect vpl --stats under Xvfb (registered only when xvfb-run is
# found): once a complete VPL pass of the view is shown, the statistics written at
# exit report the peer: its VPLs made, samples a pixel, a complete pass (grid 1)
# of this view, and the time its passes took, VPLs included (docs/stats.md).
# -DXVFB_RUN= -DLUMESH= -DDIR=
file(REMOVE_RECURSE ${DIR})
file(MAKE_DIRECTORY ${DIR})
file(WRITE ${DIR}/script.txt "peer-picture 30\nquit\n")
execute_process(
  COMMAND ${XVFB_RUN} -a -s "-screen 0 640x480x24" ${LUMESH} view --indirect vpl --width 160 --height 120
          --script ${DIR}/script.txt --stats ${DIR}/stats.json
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 120)
message("${out}${err}")
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "lumesh view exited with '${rc}'")
endif()
file(READ ${DIR}/stats.json j)
string(JSON indirect ERROR_VARIABLE e GET "${j}" peer indirect)
if(e)
  message(FATAL_ERROR "no peer object in the statistics: ${e}")
endif()
foreach(k samples_per_pixel grid view_before vpls seconds vpl_seconds)
  string(JSON ${k} GET "${j}" peer ${k})
endforeach()
message("peer ${indirect}: ${samples_per_pixel} samples a pixel, grid ${grid}, view before ${view_before}, "
        "${vpls} VPLs, ${seconds} s of passes, ${vpl_seconds} s making VPLs")
if(NOT indirect STREQUAL "vpl" OR samples_per_pixel LESS 1 OR NOT grid EQUAL 1 OR view_before OR vpls LESS 1)
  message(FATAL_ERROR "the statistics do not report the VPL picture shown")
endif()
if(NOT seconds GREATER 0 OR NOT vpl_seconds GREATER 0 OR vpl_seconds GREATER seconds)
  message(FATAL_ERROR "the peer's times are not reported: ${seconds} s, ${vpl_seconds} s making VPLs")
endif()
