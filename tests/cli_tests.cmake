# End-to-end tests of the `lumesh` command line (exit codes and output scripts rely on).
set(RUN_CLI ${CMAKE_CURRENT_SOURCE_DIR}/run_cli.cmake)
set(LUMESH_EXE $<TARGET_FILE:lumesh_cli>)

function(lumesh_cli_test name exit)
  cmake_parse_arguments(A "ONE_ERR_LINE" "OUT;ERR;ENV" "ARGS;FILES;NO_FILES" ${ARGN})
  set(defs -DEXPECT_EXIT=${exit})
  if(A_OUT)
    list(APPEND defs "-DEXPECT_OUT=${A_OUT}")
  endif()
  if(A_ERR)
    list(APPEND defs "-DEXPECT_ERR=${A_ERR}")
  endif()
  if(A_ONE_ERR_LINE)
    list(APPEND defs -DONE_ERR_LINE=1)
  endif()
  if(A_FILES)
    string(REPLACE ";" "|" files "${A_FILES}")
    list(APPEND defs "-DEXPECT_FILES=${files}")
  endif()
  if(A_NO_FILES)
    string(REPLACE ";" "|" files "${A_NO_FILES}")
    list(APPEND defs "-DEXPECT_NO_FILES=${files}")
  endif()
  set(env "")
  if(A_ENV)  # one NAME=VALUE for the command's environment
    set(env ${CMAKE_COMMAND} -E env ${A_ENV})
  endif()
  string(REPLACE ";" "|" cmd "${LUMESH_EXE};${A_ARGS}")
  add_test(NAME cli_${name} COMMAND ${env} ${CMAKE_COMMAND} "-DCMD=${cmd}" ${defs} -P ${RUN_CLI})
endfunction()

lumesh_cli_test(version 0 ARGS --version OUT "^lumesh [0-9]+\\.[0-9]+\\.[0-9]+\n$")
lumesh_cli_test(help 0 ARGS --help OUT "usage: lumesh COMMAND.*info.*render.*reference.*compare.*converge.*view")
lumesh_cli_test(no_command 1 ERR "usage: lumesh COMMAND")
lumesh_cli_test(unknown_command 1 ARGS frobnicate ERR "'frobnicate' is not a command")
foreach(c info render reference compare converge view)
  lumesh_cli_test(${c}_help 0 ARGS ${c} --help OUT "^usage: lumesh ${c}")
endforeach()
lumesh_cli_test(info_unknown_option 1 ARGS info --frob ERR "unknown option '--frob'")
lumesh_cli_test(render_needs_output 1 ARGS render ERR "output image is required")
lumesh_cli_test(render_bad_width 1 ARGS render -o x.png --width 0 --height 5 ERR "--width wants a whole number")
lumesh_cli_test(render_seconds_and_samples 1 ARGS render -o x.png --seconds 1 --samples 5 ERR "not both")
lumesh_cli_test(reference_bad_transport 1 ARGS reference -o x.exr --spp 4 --transport magic ERR "'model' or 'full'")
lumesh_cli_test(reference_bad_glossy 1 ARGS reference -o x.exr --spp 4 --glossy shiny ERR "'indirect' or 'direct'")
lumesh_cli_test(reference_full_glossy 1 ARGS reference -o x.exr --spp 4 --transport full --glossy direct
  ERR "--glossy applies to --transport model")
lumesh_cli_test(reference_spp_and_seconds 1 ARGS reference -o x.exr --spp 4 --seconds 2 ERR "exactly one of --spp or --seconds")
lumesh_cli_test(compare_needs_two 1 ARGS compare a.exr ERR "two images")

# The built-in scene: the Cornell box written from the published measurements.
lumesh_cli_test(info_builtin 0 ARGS info
  OUT "builtin:/cornell-box.json.*triangles   38 .*lights      1 \\(1 area, 0 point\\).*radiance \\(17, 12, 4\\).*facing -Y \\(down\\).*cornell .*512x512")

# Pending engines: arguments and scene are checked, then a plain "not available yet".
lumesh_cli_test(render_png 0 ARGS render -o ${CMAKE_CURRENT_BINARY_DIR}/render.png --width 64 --height 64 --seconds 20 --residual off
  --stats ${CMAKE_CURRENT_BINARY_DIR}/render.json
  OUT "^wrote .*render\\.png: 64x64, [0-9.]+ s, (converged \\(at [0-9.]+ s\\)|stopped) after [0-9]+ leaves tested")
# With --seconds, what is left after the cache has finished corrects the picture with
# path samples (the built-in box at 32x32 finishes in about 0.4 s here).
lumesh_cli_test(render_residual 0 ARGS render -o ${CMAKE_CURRENT_BINARY_DIR}/residual.png --width 32 --height 32
  --seconds 10 OUT "(stopped|converged) after .*; then [0-9]+\\.\\.[0-9]+ path samples a pixel corrected [0-9.]+% of its blocks")
lumesh_cli_test(render_bad_residual 1 ARGS render -o x.png --residual maybe ERR "--residual takes on or off")
lumesh_cli_test(render_bad_exposure 1 ARGS render -o x.png --exposure 99 ERR "--exposure")
lumesh_cli_test(render_exr_samples 0 ARGS render -o ${CMAKE_CURRENT_BINARY_DIR}/render.exr --width 48 --height 36 --samples 500
  OUT "48x36, .* after 500 leaves tested")
# --debug-meshes DIR: leaves and samples of each mesh (the built-in scene has no glossy material).
set(DBG ${CMAKE_CURRENT_BINARY_DIR}/debug_meshes)
lumesh_cli_test(render_debug_meshes 0 ARGS render -o ${CMAKE_CURRENT_BINARY_DIR}/debug.png --width 96 --height 96
  --samples 2000 --debug-meshes ${DBG}
  OUT "wrote .*light0-leaves\\.png: [0-9]+ of [0-9]+ leaf edges shown.*light0-samples\\.png: [0-9]+ samples shown.*direct-leaves.*direct-samples.*indirect-leaves.*indirect-samples"
  FILES ${DBG}/light0-leaves.png ${DBG}/light0-samples.png ${DBG}/direct-leaves.png ${DBG}/direct-samples.png
        ${DBG}/indirect-leaves.png ${DBG}/indirect-samples.png)
# The image module (OpenImageIO, src/image/image_internal.h) is opened when an EXR
# is written: a broken one is one line naming it, and no file is left behind.
set(BAD_MODULE_DIR ${CMAKE_CURRENT_BINARY_DIR}/bad_image_module)
file(WRITE ${BAD_MODULE_DIR}/lumesh_oiio.so "not a shared object\n")
lumesh_cli_test(render_broken_image_module 3 ENV LUMESH_MODULE_DIR=${BAD_MODULE_DIR}
  ARGS render -o ${CMAKE_CURRENT_BINARY_DIR}/no-module.exr --width 32 --height 32 --samples 50
  ONE_ERR_LINE ERR "no-module\\.exr: the image module .*bad_image_module/lumesh_oiio\\.so cannot be used: .*"
  NO_FILES ${CMAKE_CURRENT_BINARY_DIR}/no-module.exr)
# A PNG needs no module (src/image/image_png_write.c): written with the broken one.
lumesh_cli_test(render_png_without_module 0 ENV LUMESH_MODULE_DIR=${BAD_MODULE_DIR}
  ARGS render -o ${CMAKE_CURRENT_BINARY_DIR}/png-no-module.png --width 32 --height 32 --samples 50
  OUT "^wrote .*png-no-module\\.png: 32x32" FILES ${CMAKE_CURRENT_BINARY_DIR}/png-no-module.png)
# An empty LUMESH_MODULE_DIR (no module there) falls through to the program's own folder.
lumesh_cli_test(render_module_dir_without_module 0 ENV LUMESH_MODULE_DIR=${CMAKE_CURRENT_BINARY_DIR}
  ARGS render -o ${CMAKE_CURRENT_BINARY_DIR}/module-fallback.exr --width 32 --height 32 --samples 50
  OUT "^wrote .*module-fallback\\.exr: 32x32" FILES ${CMAKE_CURRENT_BINARY_DIR}/module-fallback.exr)
lumesh_cli_test(render_unknown_camera 2 ARGS render -o ${CMAKE_CURRENT_BINARY_DIR}/x.png --camera nope ONE_ERR_LINE ERR "no camera named 'nope'")

set(CB ${LUMESH_SCENES}/cornell-box)
if(EXISTS ${CB}/CornellBox-Original.obj)
  lumesh_cli_test(info_original 0 ARGS info ${CB}/CornellBox-Original.obj
    OUT "triangles   32 .*dropped     4 duplicate.*area 0   'light': 2 triangles, area 0.1786, radiance \\(17, 12, 4\\).*facing -Y \\(down\\).*dropped 2 duplicate triangles of material 'shortBox'.*dropped 2 duplicate triangles of material 'tallBox'")
  lumesh_cli_test(info_mirror_refraction 0 ARGS info ${CB}/CornellBox-Mirror.obj
    OUT "material 'tallBox': refraction \\(OBJ illum 4-9\\) approximated")
  foreach(v Empty-CO:12 Empty-RG:12 Empty-Squashed:12 Empty-White:12 Glossy:1112 Sphere:2188 Water:7088 Mirror:32)
    string(REPLACE ":" ";" parts ${v})
    list(GET parts 0 variant)
    list(GET parts 1 tris)
    lumesh_cli_test(info_cornell_${variant} 0 ARGS info ${CB}/CornellBox-${variant}.obj
      OUT "triangles   ${tris} .*lights      1 \\(1 area, 0 point\\)")
  endforeach()
  # The Veach door (bench/scenes/veach-door.json, converted from its scene.xml): one
  # lamp, turned to face the door (+Z after the file's Z-up rotation), and its camera.
  lumesh_cli_test(info_veach_door 0 ARGS info ${CMAKE_SOURCE_DIR}/bench/scenes/veach-door.json
    OUT "triangles   20764 .*lights      1 \\(1 area, 0 point\\).*'lamp': 2 triangles, area 9095.18, radiance \\(1420, 1552, 1642\\).*facing \\+Z.*main .*fov_y 32.3792°, 320x180")
  # The same scene from its own scene.xml (Mitsuba 0.4), as it is: the lamp's emitting
  # side from lamp.obj's normals, textures as their mean colours, the approximations listed.
  lumesh_cli_test(info_veach_door_xml 0 ARGS info ${LUMESH_SCENES}/veach-door/scene.xml
    OUT "triangles   20764 .*bumpmetal .*\\(approximated: see notes\\).*lights      1 \\(1 area, 0 point\\).*'lamp': 2 triangles, area 9095.18, radiance \\(1420, 1552, 1642\\).*facing \\+Z.*sensor .*fov_y 32.3792°, 1280x720.*roughconductor Al: specular 0.73 0.738 0.739; roughness 0.15 as Phong n 86.8889; bump ignored.*texture 'data/marble.jpg' approximated by its mean colour 0.811 0.795 0.903.*dielectric: opaque, no transmission")
  lumesh_cli_test(info_bunny 0 ARGS info ${LUMESH_SCENES}/stanford-bunny/stanford-bunny.obj
    OUT "triangles   69451 .*lights      0 \\(0 area, 0 point\\).*none: no triangle emits")
endif()

# The bad-input corpus through the command line: exit 2 and exactly one line, or,
# for files accepted with a note (exit 0), the note in `info`'s output.
file(STRINGS ${CMAKE_CURRENT_SOURCE_DIR}/badinput/expect.txt corpus)
foreach(line IN LISTS corpus)
  if(line MATCHES "^#" OR line STREQUAL "")
    continue()
  endif()
  string(REPLACE "|" ";" f "${line}")
  list(GET f 0 file)
  list(GET f 1 command)
  list(GET f 2 code)
  set(args ${command} ${CMAKE_CURRENT_SOURCE_DIR}/badinput/${file})
  if(command STREQUAL "compare") # an image compared with itself
    list(APPEND args ${CMAKE_CURRENT_SOURCE_DIR}/badinput/${file})
  endif()
  if(command STREQUAL "render")
    list(APPEND args -o ${CMAKE_CURRENT_BINARY_DIR}/never-written.png)
  endif()
  if(code STREQUAL "0") # accepted with a note that `info` prints
    list(GET f 3 text)
    lumesh_cli_test(badinput_${file} 0 ARGS ${args} OUT "- [^\n]*${file}[^\n]*${text}")
  else()
    lumesh_cli_test(badinput_${file} ${code} ARGS ${args} ONE_ERR_LINE ERR "lumesh: .*${file}")
  endif()
endforeach()

# The mesh reader runs in a child process (src/scene/scene_isolate.c): a reader
# that crashes or never returns becomes one line and exit 2 (fault injection).
foreach(fault crash hang)
  set(want "crashed on this file")
  if(fault STREQUAL "hang")
    set(want "ran out of time")
  endif()
  add_test(NAME cli_reader_${fault} COMMAND ${CMAKE_COMMAND} -E env LUMESH_FAULT_INJECT=reader-${fault}
           ${CMAKE_COMMAND} "-DCMD=${LUMESH_EXE}|info" # the built-in scene's OBJ
           -DEXPECT_EXIT=2 "-DEXPECT_ERR=cornell-box.obj: the file reader \\(Assimp\\) ${want}"
           -DONE_ERR_LINE=1 -P ${RUN_CLI})
endforeach()
# A child that sleeps for good (a lock the fork copied while another thread held
# it: view's reload under ASan): noticed after LUMESH_READER_STALL_SECONDS without
# CPU time or output, forked again; asleep every time, one line and exit 3; asleep
# the first time only, the scene loads (its camera is listed).
add_test(NAME cli_reader_sleep COMMAND ${CMAKE_COMMAND} -E env LUMESH_FAULT_INJECT=reader-sleep
         LUMESH_READER_STALL_SECONDS=0.5 ${CMAKE_COMMAND} "-DCMD=${LUMESH_EXE}|info" -DEXPECT_EXIT=3
         "-DEXPECT_ERR=cornell-box.obj: the file reader's process \\(Assimp\\) slept for 0.5 s without using the CPU or sending anything, 3 times in a row"
         -DONE_ERR_LINE=1 -P ${RUN_CLI})
add_test(NAME cli_reader_sleep_once COMMAND ${CMAKE_COMMAND} -E env LUMESH_FAULT_INJECT=reader-sleep-once
         LUMESH_READER_STALL_SECONDS=0.5 ${CMAKE_COMMAND} "-DCMD=${LUMESH_EXE}|info" -DEXPECT_EXIT=0
         "-DEXPECT_OUT=cornell +from \\[278, 273, -800\\]" -P ${RUN_CLI})
# A child that spins for good (a spin lock the fork copied held: ASan's, the load
# after GL work in rend_session_test) runs out of CPU time and is forked once more;
# spinning the first time only, the scene loads. (Spinning every time is
# cli_reader_hang: two children, then the line above.)
add_test(NAME cli_reader_hang_once COMMAND ${CMAKE_COMMAND} -E env LUMESH_FAULT_INJECT=reader-hang-once
         ${CMAKE_COMMAND} "-DCMD=${LUMESH_EXE}|info" -DEXPECT_EXIT=0
         "-DEXPECT_OUT=cornell +from \\[278, 273, -800\\]" -P ${RUN_CLI})

# --sampler and --gl: fixed spellings, checked before the scene is read.
lumesh_cli_test(render_bad_sampler 1 ARGS render -o x.png --sampler cuda ERR "--sampler must be gl, embree or auto, not 'cuda'")
lumesh_cli_test(converge_bad_gl 1 ARGS converge --reference r.exr --seconds 1 --out d --gl glx ERR "--gl must be egl or osmesa")
lumesh_cli_test(converge_needs_reference 1 ARGS converge --seconds 1 --out d ERR "--reference, --seconds and --out are required")
lumesh_cli_test(converge_bad_snapshots 1 ARGS converge --reference r.exr --seconds 1 --out d --snapshots 0.5,0.2
  ERR "--snapshots takes increasing positive seconds")
lumesh_cli_test(converge_missing_reference 2 ARGS converge --reference ${CMAKE_CURRENT_BINARY_DIR}/no-such.exr --seconds 1
  --out ${CMAKE_CURRENT_BINARY_DIR}/conv-never ONE_ERR_LINE ERR "no-such\\.exr")
lumesh_cli_test(converge_bad_method 1 ARGS converge --reference r.exr --seconds 1 --out d --methods cache,photons
  ERR "--methods takes each of cache, vpl, bdir, vpl-ism, bdir-ism, path-tracer at most once, separated by commas \\('photons' is not one\\)")
lumesh_cli_test(view_bad_indirect 1 ARGS view --indirect photons
  ERR "--indirect takes cache, vpl, bdir, vpl-ism or bdir-ism, not 'photons'")
lumesh_cli_test(converge_repeated_method 1 ARGS converge --reference r.exr --seconds 1 --out d --methods vpl,vpl
  ERR "'vpl' is repeated")
lumesh_cli_test(converge_methods_and_vs 1 ARGS converge --reference r.exr --seconds 1 --out d --methods vpl
  --vs-path-tracer ERR "--vs-path-tracer is short for --methods cache,path-tracer: give one")
lumesh_cli_test(converge_bad_vpl_clamp 1 ARGS converge --reference r.exr --seconds 1 --out d --methods vpl
  --vpl-clamp 2 ERR "--vpl-clamp takes a fraction of the scene's size in \\(0, 1\\), or none")
lumesh_cli_test(render_deterministic_needs_samples 1 ARGS render -o x.exr --deterministic ERR "--deterministic needs --samples")
lumesh_cli_test(render_bad_components 1 ARGS render -o x.exr --components direct,glow
  ERR "--components takes a comma-separated list of direct, indirect, specular and emission, not 'direct,glow'")
lumesh_cli_test(render_bad_accumulate 1 ARGS render -o x.exr --accumulate 9
  ERR "--accumulate wants a whole number from 1 to 8, not '9'")
lumesh_cli_test(view_width_without_height 1 ARGS view --sampler embree --gl osmesa --width 640
  ERR "give both --width and --height")
lumesh_cli_test(view_camera_and_width 1 ARGS view --camera main --width 640 ERR "give both --width and --height")
# A bad script fails before any window opens, naming the file and line.
file(WRITE ${CMAKE_CURRENT_BINARY_DIR}/view-bad-script.txt "wait 1\njump 3\n")
lumesh_cli_test(view_bad_script 2 ARGS view --script ${CMAKE_CURRENT_BINARY_DIR}/view-bad-script.txt ONE_ERR_LINE
  ERR "view-bad-script\\.txt:2: unknown command 'jump'")
# --width and --height together are accepted (the script is checked after them).
lumesh_cli_test(view_width_and_height 2 ARGS view --width 64 --height 48 --script ${CMAKE_CURRENT_BINARY_DIR}/view-bad-script.txt
  ONE_ERR_LINE ERR "view-bad-script\\.txt:2: unknown command 'jump'")

# OpenImageIO (and its ~260 libraries) is not loaded with the program, only with
# the image module when an image is read or written (docs/memory.md).
add_test(NAME program_loads_no_openimageio
  COMMAND sh -c "ldd \"$1\" > \"$2\" && grep -q libembree \"$2\" && ! grep -q OpenImageIO \"$2\"" sh
          ${LUMESH_EXE} ${CMAKE_CURRENT_BINARY_DIR}/lumesh-ldd.txt)
