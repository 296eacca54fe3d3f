# End-to-end tests of `lumesh reference` (small images: seconds in CI).
set(REF_DIR ${CMAKE_CURRENT_BINARY_DIR}/reference_cli)
file(MAKE_DIRECTORY ${REF_DIR})

lumesh_cli_test(reference_model 0 ARGS reference -o ${REF_DIR}/a.exr --spp 4 --seed 9 --width 40 --height 30
  OUT "^wrote .*a\\.exr: 40x30, transport model, 4 spp, .* Mrays/s, mean relative standard error [0-9.]+%\n$")
lumesh_cli_test(reference_model_again 0 ARGS reference -o ${REF_DIR}/b.exr --spp 4 --seed 9 --width 40 --height 30 --threads 1
  OUT "40x30, transport model, 4 spp")
set_tests_properties(cli_reference_model cli_reference_model_again PROPERTIES FIXTURES_SETUP reference_pair)
# Same seed and sample count, different thread counts: the same image.
lumesh_cli_test(reference_same_seed_same_image 0 ARGS compare ${REF_DIR}/a.exr ${REF_DIR}/b.exr --json
  OUT "\"rmse\":[\t ]*0,.*\"max_abs_error\":[\t ]*0,")
set_tests_properties(cli_reference_same_seed_same_image PROPERTIES FIXTURES_REQUIRED reference_pair)
lumesh_cli_test(reference_full_seconds 0 ARGS reference ${LUMESH_SCENES}/cornell-box/CornellBox-Glossy.obj
  -o ${REF_DIR}/full.exr --seconds 1 --transport full --width 32 --height 24
  OUT "32x24, transport full, [0-9]+\\+? spp")
lumesh_cli_test(reference_needs_light 2 ARGS reference ${LUMESH_SCENES}/stanford-bunny/stanford-bunny.obj -o ${REF_DIR}/x.exr --spp 1
  ONE_ERR_LINE ERR "no light")
lumesh_cli_test(reference_unknown_camera 2 ARGS reference -o ${REF_DIR}/x.exr --spp 1 --camera nope
  ONE_ERR_LINE ERR "no camera named 'nope'")
lumesh_cli_test(reference_png_refused 1 ARGS reference -o ${REF_DIR}/x.png --spp 1 ERR "must end in .exr")
add_test(NAME cli_reference_sigint COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/reference_sigint.sh $<TARGET_FILE:lumesh_cli> ${REF_DIR})
