# lumesh view under Xvfb (registered only when xvfb-run is found): the window
# opens on the built-in scene, frames are drawn, screenshots are taken before and
# after an orbit; exit 0, the screenshots exist and are not uniform
# (view_image_check), and the direct-diffuse sample count after the move is not
# lower than before (the view-independent caches are kept across camera moves),
# nor after pan, fly, look and a named camera (moved.png, and the linear
# moved.exr beside it).
# Light edit, refinement paused (nothing else publishes): `light 0 0.5` gives one
# new snapshot (generation + 1) with the same light-mesh sample count and a darker
# image; hiding the indirect term (key 3) darkens it again.
# The direct mesh's leaf overlay (key o) and the HUD change the window (window-shot
# against the screenshot of the same frame); a reload (key r) gives a new worker
# that refines again (a screenshot after it has direct samples).
# The resting picture: paused on a converged snapshot, the picture shown (and
# rest.exr) is the mean of all 16 jittered draws; on one not converged, a plain
# draw (0) (both at 160x120). Ten seconds later the converged mean is corrected by path
# samples (the residual: at least 32 a pixel).
# Exposure (key plus, paused): the worker judges the new colours (one more
# snapshot, its estimate at +0.5).
# The peers (key i, --indirect; docs/peers.md): the still view rendered by VPLs,
# then again after an orbit (their picture of the new view), then by BDIR, then
# both with imperfect shadow maps (vpl-ism, bdir-ism), each shown from a complete
# pass (peer spp 1 or more) with VPLs made: the script waits for that picture
# (peer-picture, at most 20 s: under TSan a first pass with maps takes 3-5 s);
# a fifth i shows the cache again. The moving view (docs/peers.md), at 480x270:
# right after a move the peer's picture stays shown (of the view before, until the
# new one's), the new view's first picture is the peer's over a grid of its pixels
# (a whole pass there takes longer than the grid's 0.05 s), filled in between, and
# its tone-mapped mean is within 20% of the complete pass's that follows (linear,
# the lamp would set the mean: a coarse grid hits or misses it).
# -DXVFB_RUN= -DLUMESH= -DCHECK= -DDIR=
file(REMOVE_RECURSE ${DIR})
file(MAKE_DIRECTORY ${DIR})
file(WRITE ${DIR}/script.txt "# view_cli.cmake
next-snapshot 120
wait 0.5
screenshot ${DIR}/before.png
orbit 25 10
frames 3
wait 1
screenshot ${DIR}/after.png
camera 0
pan 0.05 0.02
fly 20 5 -5
look 3 -2
frames 3
screenshot ${DIR}/moved.png
screenshot ${DIR}/moved.exr
key p
frames 2
screenshot ${DIR}/lit.png
light 0 0.5
next-snapshot 120
screenshot ${DIR}/dim.png
light-color 0 1 0.3 0.3
next-snapshot 120
screenshot ${DIR}/red.png
light-color 0 1 1 1
next-snapshot 120
screenshot ${DIR}/white.png
key b
next-snapshot 120
screenshot ${DIR}/onebounce.png
key 3
frames 1
screenshot ${DIR}/noindirect.png
key 3
key plus
next-snapshot 120
screenshot ${DIR}/brighter.png
key minus
next-snapshot 120
key p
zoom 1.2
key f
frames 2
screenshot ${DIR}/framed.png
key o
wait 1
window-shot ${DIR}/overlay.png
screenshot ${DIR}/plain.png
key o
key r
wait 2
screenshot ${DIR}/reloaded.png
minimise
wait 0.3
restore
resize 640 360
wait 1
screenshot ${DIR}/resized.png
resize 160 120
wait 4
key p
wait 2
screenshot ${DIR}/rest.exr
wait 10
screenshot ${DIR}/residual.exr
key i
peer-picture 20
screenshot ${DIR}/peer.exr
orbit 10 0
frames 1
wait 1
peer-picture 20
screenshot ${DIR}/peer-moved.png
resize 480 270
frames 2
wait 0.5
peer-picture 20
orbit 4 0
frames 1
screenshot ${DIR}/peer-moving.png
peer-preview 20
screenshot ${DIR}/peer-preview.png
peer-picture 20
screenshot ${DIR}/peer-whole.png
resize 160 120
key i
peer-picture 20
screenshot ${DIR}/bdir.png
key i
peer-picture 20
screenshot ${DIR}/vpl-ism.png
key i
peer-picture 20
screenshot ${DIR}/bdir-ism.png
key i
frames 2
screenshot ${DIR}/back.png
quit
")
execute_process(
  COMMAND ${XVFB_RUN} -a -s "-screen 0 1280x720x24" ${LUMESH} view --script ${DIR}/script.txt
          --stats ${DIR}/stats.json
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 300)
message("${out}${err}")
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "lumesh view exited with '${rc}'")
endif()
foreach(f before.png after.png framed.png lit.png dim.png noindirect.png moved.png moved.exr overlay.png plain.png
        reloaded.png resized.png)
  if(NOT EXISTS ${DIR}/${f})
    message(FATAL_ERROR "no ${DIR}/${f}")
  endif()
endforeach()
if(NOT EXISTS ${DIR}/stats.json)
  message(FATAL_ERROR "no ${DIR}/stats.json")
endif()
file(READ ${DIR}/stats.json stats)
string(JSON command GET "${stats}" command)
if(NOT command STREQUAL "view")
  message(FATAL_ERROR "stats.json: command is '${command}', not 'view'")
endif()
execute_process(COMMAND ${CHECK} ${DIR}/before.png ${DIR}/after.png ${DIR}/framed.png ${DIR}/lit.png
                        ${DIR}/dim.png ${DIR}/noindirect.png ${DIR}/moved.png ${DIR}/moved.exr RESULT_VARIABLE crc
                OUTPUT_VARIABLE cout ERROR_VARIABLE cerr)
message("${cout}${cerr}")
if(NOT crc EQUAL 0)
  message(FATAL_ERROR "a screenshot is missing, unreadable, uniform, or unchanged by the orbit")
endif()
# screenshot_fields(F REGEX VAR...): from the screenshot line of ${DIR}/F.png in
# ${out}, REGEX's groups into VAR_F... (the caller's scope); a missing line fails.
function(screenshot_fields f regex)
  if(NOT out MATCHES "screenshot [^\n]*/${f}\\.png: [^\n]*${regex}")
    message(FATAL_ERROR "no screenshot line for ${f}.png matching '${regex}'")
  endif()
  set(i 1)
  foreach(v ${ARGN})
    set(${v}_${f} ${CMAKE_MATCH_${i}} PARENT_SCOPE)
    math(EXPR i "${i} + 1")
  endforeach()
endfunction()

foreach(f before after moved)
  screenshot_fields(${f} "direct samples ([0-9]+)" direct)
endforeach()
if(direct_after LESS direct_before OR direct_moved LESS direct_after)
  message(FATAL_ERROR "direct samples dropped across camera moves: ${direct_before} -> ${direct_after} -> ${direct_moved}")
endif()
if(direct_before EQUAL 0)
  message(FATAL_ERROR "no direct samples in the first snapshot")
endif()

# The light edit, paused: one new snapshot, no light sample, a darker image.
foreach(f lit dim)
  screenshot_fields(${f} "light samples ([0-9]+)[^\n]*generation ([0-9]+)" light gen)
endforeach()
math(EXPR gen_expected "${gen_lit} + 1")
if(NOT gen_dim EQUAL gen_expected)
  message(FATAL_ERROR "light edit while paused: generation ${gen_lit} -> ${gen_dim}, expected ${gen_expected}")
endif()
if(NOT light_dim EQUAL light_lit OR light_lit EQUAL 0)
  message(FATAL_ERROR "light edit took light samples: ${light_lit} -> ${light_dim}")
endif()
foreach(f lit dim noindirect)
  if(NOT cout MATCHES "/${f}\\.png: [0-9]+x[0-9]+, mean ([0-9.]+)")
    message(FATAL_ERROR "no mean for ${f}.png")
  endif()
  set(mean_${f} ${CMAKE_MATCH_1})
endforeach()
message("light edit: light samples ${light_lit} -> ${light_dim}, generation ${gen_lit} -> ${gen_dim}, "
        "mean ${mean_lit} -> ${mean_dim}, without indirect ${mean_noindirect}")
if(NOT mean_dim LESS mean_lit)
  message(FATAL_ERROR "the image did not get darker with light 0 at half power: ${mean_lit} -> ${mean_dim}")
endif()
if(NOT mean_noindirect LESS mean_dim)
  message(FATAL_ERROR "hiding the indirect term did not darken the image: ${mean_dim} -> ${mean_noindirect}")
endif()

# Key b while paused (auto -> 1 bounce): one more snapshot, no light sample, one
# bounce where auto showed several, and a darker picture.
foreach(f white onebounce)
  screenshot_fields(${f} "light samples ([0-9]+)[^\n]*bounces ([0-9]+)" light bounces)
endforeach()
execute_process(COMMAND ${CHECK} ${DIR}/white.png ${DIR}/onebounce.png RESULT_VARIABLE brc OUTPUT_VARIABLE bout
                ERROR_VARIABLE berr)
foreach(f white onebounce)
  if(NOT bout MATCHES "/${f}\\.png: [0-9]+x[0-9]+, mean ([0-9.]+)")
    message(FATAL_ERROR "no mean for ${f}.png: ${bout}${berr}")
  endif()
  set(mean_${f} ${CMAKE_MATCH_1})
endforeach()
message("key b: bounces ${bounces_white} -> ${bounces_onebounce}, light samples ${light_white} -> ${light_onebounce}, "
        "mean ${mean_white} -> ${mean_onebounce}")
if(NOT bounces_onebounce EQUAL 1 OR NOT bounces_white GREATER 1)
  message(FATAL_ERROR "key b: bounces ${bounces_white} -> ${bounces_onebounce}, expected auto (> 1) -> 1")
endif()
if(NOT light_onebounce EQUAL light_white)
  message(FATAL_ERROR "key b took light samples: ${light_white} -> ${light_onebounce}")
endif()
if(NOT mean_onebounce LESS mean_white)
  message(FATAL_ERROR "one bounce is not darker than auto's: ${mean_white} -> ${mean_onebounce}")
endif()

# Key plus while paused: the exposure (+0.5 stop) goes to the worker like an
# edit: one more snapshot, whose estimate was made at the new exposure
# (cache_set_exposure; docs/viewer.md, "Exposure"). One press: two presses are
# one snapshot or two, as the worker happens to wake between them.
foreach(f onebounce brighter)
  screenshot_fields(${f} "generation ([0-9]+)[^\n]*exposure ([-0-9.e]+), judged at ([-0-9.e]+)" gen shown judged)
endforeach()
message("key plus: exposure ${shown_onebounce} (judged at ${judged_onebounce}) -> ${shown_brighter} (judged at "
        "${judged_brighter}), generation ${gen_onebounce} -> ${gen_brighter}")
if(NOT shown_brighter STREQUAL "0.5" OR NOT judged_brighter STREQUAL "0.5" OR NOT judged_onebounce STREQUAL "0")
  message(FATAL_ERROR "key plus: the cache judged at ${judged_onebounce} -> ${judged_brighter}, the view showed "
                      "${shown_onebounce} -> ${shown_brighter}")
endif()
if(NOT gen_brighter GREATER gen_onebounce)
  message(FATAL_ERROR "key plus while paused: no new snapshot (generation ${gen_onebounce} -> ${gen_brighter})")
endif()

# The overlay and the HUD: the window differs from the picture of the same frame.
execute_process(COMMAND ${CHECK} ${DIR}/overlay.png ${DIR}/plain.png RESULT_VARIABLE orc OUTPUT_VARIABLE oout
                ERROR_VARIABLE oerr)
message("${oout}${oerr}")
if(NOT orc EQUAL 0)
  message(FATAL_ERROR "the window with the mesh overlay and the HUD looks like the plain picture")
endif()
# The reload: a new worker refined the reloaded scene.
if(NOT out MATCHES "reloaded [^\n]*: [0-9]+ triangles")
  message(FATAL_ERROR "no 'reloaded' line after key r")
endif()
if(NOT out MATCHES "screenshot [^\n]*/reloaded\\.png: [^\n]*direct samples ([0-9]+)")
  message(FATAL_ERROR "no screenshot line for reloaded.png")
endif()
if(CMAKE_MATCH_1 EQUAL 0)
  message(FATAL_ERROR "no direct samples 2 s after the reload")
endif()

# A colour edit while paused: one more snapshot, still no light sample.
if(NOT out MATCHES "screenshot [^\n]*/red\\.png: [^\n]*light samples ([0-9]+)[^\n]*generation ([0-9]+)")
  message(FATAL_ERROR "no screenshot line for red.png")
endif()
if(NOT CMAKE_MATCH_1 EQUAL light_dim)
  message(FATAL_ERROR "the colour edit took light samples: ${light_dim} -> ${CMAKE_MATCH_1}")
endif()
math(EXPR gen_red_expected "${gen_dim} + 1")
if(NOT CMAKE_MATCH_2 EQUAL gen_red_expected)
  message(FATAL_ERROR "colour edit while paused: generation ${gen_dim} -> ${CMAKE_MATCH_2}")
endif()

# Minimised and restored, then resized: the picture follows the new framebuffer.
if(NOT out MATCHES "screenshot [^\n]*/resized\\.png: 640x360,")
  message(FATAL_ERROR "the screenshot after 'resize 640 360' is not 640x360")
endif()

# The resting picture (view_app.c, draw_picture): complete after 2 s paused on a
# converged snapshot, none on one still refining.
if(NOT out MATCHES "screenshot [^\n]*/rest\\.exr: [^\n]*converged ([01]), rest draws ([0-9]+)")
  message(FATAL_ERROR "no screenshot line for rest.exr")
endif()
if(CMAKE_MATCH_1 EQUAL 1 AND NOT CMAKE_MATCH_2 EQUAL 16)
  message(FATAL_ERROR "paused on a converged snapshot, the picture averages ${CMAKE_MATCH_2} draws, not 16")
endif()
if(CMAKE_MATCH_1 EQUAL 0 AND NOT CMAKE_MATCH_2 EQUAL 0)
  message(FATAL_ERROR "on a snapshot still refining, the picture averages ${CMAKE_MATCH_2} draws, not one plain draw")
endif()
message("rest.exr: converged ${CMAKE_MATCH_1}, ${CMAKE_MATCH_2} draws averaged")

# The resting picture corrected by path samples (view_residual.h): still paused
# (at 160x120, as rest.exr), 10 s later, on a converged snapshot the correction is shown (at least
# rend_residual's 32 samples a pixel, on the complete mean); on one still refining
# there is no resting picture to correct.
if(NOT out MATCHES "screenshot [^\n]*/residual\\.exr: 160x120, [^\n]*converged ([01]), rest draws ([0-9]+), residual spp ([0-9]+)")
  message(FATAL_ERROR "no screenshot line for residual.exr")
endif()
if(CMAKE_MATCH_1 EQUAL 1 AND (CMAKE_MATCH_3 LESS 32 OR NOT CMAKE_MATCH_2 EQUAL 16))
  message(FATAL_ERROR "paused on a converged snapshot: ${CMAKE_MATCH_3} path samples a pixel on ${CMAKE_MATCH_2} draws")
endif()
if(CMAKE_MATCH_1 EQUAL 0 AND NOT CMAKE_MATCH_3 EQUAL 0)
  message(FATAL_ERROR "a snapshot still refining was corrected (${CMAKE_MATCH_3} path samples a pixel)")
endif()
message("residual.exr: converged ${CMAKE_MATCH_1}, ${CMAKE_MATCH_3} path samples a pixel")

# The peers shown at rest (key i): VPLs, VPLs after an orbit, BDIR, both with
# imperfect shadow maps, then the cache again; each shown with VPLs made.
foreach(pair "peer.exr;vpl" "peer-moved.png;vpl" "bdir.png;bdir" "vpl-ism.png;vpl-ism" "bdir-ism.png;bdir-ism")
  list(GET pair 0 f)
  list(GET pair 1 m)
  string(REPLACE "." "\\." fre "${f}")
  if(NOT out MATCHES "screenshot [^\n]*/${fre}: [^\n]*indirect ${m}, peer spp ([0-9]+), peer vpls ([0-9]+)")
    message(FATAL_ERROR "no screenshot line for ${f} with indirect ${m}")
  endif()
  if(CMAKE_MATCH_1 LESS 1 OR CMAKE_MATCH_2 LESS 1)
    message(FATAL_ERROR "${f}: the ${m} picture is not shown (peer spp ${CMAKE_MATCH_1}, VPLs ${CMAKE_MATCH_2})")
  endif()
  message("${f}: ${m}, ${CMAKE_MATCH_1} samples a pixel, ${CMAKE_MATCH_2} VPLs")
endforeach()
if(NOT out MATCHES "screenshot [^\n]*/back[.]png: [^\n]*indirect cache, peer spp 0")
  message(FATAL_ERROR "a fifth i did not show the cache's picture again")
endif()
execute_process(COMMAND ${CHECK} ${DIR}/peer.exr ${DIR}/peer-moved.png RESULT_VARIABLE crc OUTPUT_VARIABLE cout
                ERROR_VARIABLE cerr)
if(NOT crc EQUAL 0)
  message(FATAL_ERROR "the VPL pictures are missing, uniform or the same before and after the orbit: ${cout}${cerr}")
endif()
# The moving view: the peer's picture throughout, a grid's first, then whole.
foreach(f peer-moving.png peer-preview.png peer-whole.png)
  string(REPLACE "." "\\." fre "${f}")
  if(NOT out MATCHES "screenshot [^\n]*/${fre}: [^\n]*indirect vpl, peer spp ([0-9]+), peer vpls [0-9]+, peer grid ([0-9]+), peer earlier ([01])")
    message(FATAL_ERROR "no screenshot line for ${f} with indirect vpl")
  endif()
  set(spp ${CMAKE_MATCH_1})
  set(grid ${CMAKE_MATCH_2})
  set(earlier ${CMAKE_MATCH_3})
  message("${f}: peer spp ${spp}, grid ${grid}, of the view before ${earlier}")
  if(spp LESS 1)
    message(FATAL_ERROR "${f}: the peer's picture is not shown while the view moves (the cache's instead)")
  endif()
  if(NOT f STREQUAL "peer-moving.png" AND NOT earlier EQUAL 0)
    message(FATAL_ERROR "${f}: the picture shown is of the view before the move")
  endif()
  if(f STREQUAL "peer-whole.png" AND NOT grid EQUAL 1)
    message(FATAL_ERROR "peer-whole.png: not a complete pass (grid ${grid})")
  endif()
  if(f STREQUAL "peer-preview.png" AND grid LESS 2)
    message(FATAL_ERROR "peer-preview.png: the new view's first picture is not a grid's (grid ${grid})")
  endif()
endforeach()
execute_process(COMMAND ${CHECK} ${DIR}/peer-preview.png ${DIR}/peer-whole.png RESULT_VARIABLE crc OUTPUT_VARIABLE cout
                ERROR_VARIABLE cerr)
if(NOT crc EQUAL 0)
  message(FATAL_ERROR "the moving view's pictures are missing, uniform or identical: ${cout}${cerr}")
endif()
if(NOT cout MATCHES "mean of the second over the first ([0-9.]+)")
  message(FATAL_ERROR "no means for the moving view's pictures: ${cout}")
endif()
message("the moving view: the complete pass's mean over its first picture's ${CMAKE_MATCH_1}")
if(CMAKE_MATCH_1 LESS 0.8 OR CMAKE_MATCH_1 GREATER 1.25)
  message(FATAL_ERROR "the moving view's first picture is not the peer's light: mean ratio ${CMAKE_MATCH_1}")
endif()

