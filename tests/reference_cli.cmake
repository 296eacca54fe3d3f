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
# --add: seeds 9 and 10 pooled either way round give the same image (means
# weighted by their samples), and the file lists both seeds.
lumesh_cli_test(reference_seed10 0 ARGS reference -o ${REF_DIR}/d.exr --spp 4 --seed 10 --width 40 --height 30
  OUT "40x30, transport model, 4 spp")
set_tests_properties(cli_reference_seed10 PROPERTIES FIXTURES_SETUP reference_pair)
lumesh_cli_test(reference_add 0 ARGS reference -o ${REF_DIR}/c.exr --spp 4 --seed 10 --width 40 --height 30
  --add ${REF_DIR}/a.exr OUT "\npooled with .*a\\.exr \\(seeds 9\\): mean relative standard error at most [0-9.]+%\n$")
lumesh_cli_test(reference_add_reversed 0 ARGS reference -o ${REF_DIR}/e.exr --spp 4 --seed 9 --width 40 --height 30
  --add ${REF_DIR}/d.exr OUT "pooled with .*d\\.exr \\(seeds 10\\)")
set_tests_properties(cli_reference_add cli_reference_add_reversed PROPERTIES FIXTURES_REQUIRED reference_pair
  FIXTURES_SETUP reference_pooled)
lumesh_cli_test(reference_pooled_either_way 0 ARGS compare ${REF_DIR}/c.exr ${REF_DIR}/e.exr --json
  OUT "\"rmse\":[\t ]*0,.*\"max_abs_error\":[\t ]*0,")
lumesh_cli_test(reference_add_third_seed 0 ARGS reference -o ${REF_DIR}/f.exr --spp 4 --seed 11 --width 40 --height 30
  --add ${REF_DIR}/c.exr OUT "pooled with .*c\\.exr \\(seeds 9,10\\)")
lumesh_cli_test(reference_add_same_seed 2 ARGS reference -o ${REF_DIR}/x.exr --spp 1 --seed 10 --width 40 --height 30
  --add ${REF_DIR}/c.exr ONE_ERR_LINE ERR "already holds the samples of seed 10: give another --seed")
lumesh_cli_test(reference_add_other_transport 2 ARGS reference -o ${REF_DIR}/x.exr --spp 1 --seed 12 --width 40
  --height 30 --transport full --add ${REF_DIR}/c.exr ONE_ERR_LINE ERR "lumesh:transport model, this reference with full")
lumesh_cli_test(reference_add_other_size 2 ARGS reference -o ${REF_DIR}/x.exr --spp 1 --seed 12 --width 20 --height 30
  --add ${REF_DIR}/c.exr ONE_ERR_LINE ERR "is 40x30, this reference 20x30")
set_tests_properties(cli_reference_pooled_either_way cli_reference_add_third_seed cli_reference_add_same_seed
  cli_reference_add_other_transport cli_reference_add_other_size PROPERTIES FIXTURES_REQUIRED reference_pooled)
lumesh_cli_test(reference_full_seconds 0 ARGS reference ${LUMESH_SCENES}/cornell-box/CornellBox-Glossy.obj
  -o ${REF_DIR}/full.exr --seconds 1 --transport full --width 32 --height 24
  OUT "32x24, transport full, [0-9]+\\+? spp")
lumesh_cli_test(reference_needs_light 2 ARGS reference ${LUMESH_SCENES}/stanford-bunny/stanford-bunny.obj -o ${REF_DIR}/x.exr --spp 1
  ONE_ERR_LINE ERR "no light")
lumesh_cli_test(reference_unknown_camera 2 ARGS reference -o ${REF_DIR}/x.exr --spp 1 --camera nope
  ONE_ERR_LINE ERR "no camera named 'nope'")
lumesh_cli_test(reference_png_refused 1 ARGS reference -o ${REF_DIR}/x.png --spp 1 ERR "must end in .exr")
add_test(NAME cli_reference_sigint COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/reference_sigint.sh $<TARGET_FILE:lumesh_cli> ${REF_DIR})
