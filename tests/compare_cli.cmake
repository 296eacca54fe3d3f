# End-to-end tests of `lumesh compare`. Included from tests/CMakeLists.txt after
# cli_tests.cmake (it uses lumesh_cli_test) and beside the compare_test program.
#
# The images come from a ctest fixture: `compare_test --write-cli-images DIR`
# writes DIR/a.exr and DIR/b.exr (4x3 RGB, different) and DIR/small.exr (2x2)
# and does nothing else, so the CLI tests do not depend on the unit checks
# passing, and `ctest -R cli_compare` runs the fixture first on its own.
set(CMP_DIR ${CMAKE_CURRENT_BINARY_DIR}/compare_cli)
add_test(NAME compare_cli_images COMMAND compare_test --write-cli-images ${CMP_DIR})
set_tests_properties(compare_cli_images PROPERTIES FIXTURES_SETUP compare_cli_images)

lumesh_cli_test(compare_help_text 0 ARGS compare --help
  OUT "^usage: lumesh compare.*--heatmap FILE.*ΔE 0.*10 and above")
lumesh_cli_test(compare_self 0 ARGS compare ${CMP_DIR}/a.exr ${CMP_DIR}/a.exr
  OUT "RMSE +0 \\(linear\\)\n.*relMSE +0 .*PSNR +inf dB.*max error +0 .*ΔE mean +0 .*ΔE 99% +0\n.*OIIO RMSE +0 ")
lumesh_cli_test(compare_pair 0 ARGS compare ${CMP_DIR}/a.exr ${CMP_DIR}/b.exr
  OUT "pixels +12 compared, 0 left out.*max error +0\\.51 \\(linear\\) at x 2, y 1, channel G")
lumesh_cli_test(compare_json 0 ARGS compare ${CMP_DIR}/a.exr ${CMP_DIR}/b.exr --json --exposure -1
  OUT "^{\n.*\"rmse\":[\t ]*[0-9.e-]+,\n.*\"relmse\":[\t ]*[0-9.e-]+,\n.*\"psnr_db\":[\t ]*[0-9.e-]+,\n.*\"max_abs_error\":[\t ]*0\\.51[0-9]*,\n.*\"exposure\":[\t ]*-1,\n.*\"delta_e_mean\":.*\"delta_e_p99\":.*\"oiio\":[\t ]*{.*\"rms_error\":.*}\n}\n$")
lumesh_cli_test(compare_json_identical 0 ARGS compare --json ${CMP_DIR}/b.exr ${CMP_DIR}/b.exr
  OUT "\"rmse\":[\t ]*0,.*\"psnr_db\":[\t ]*\"inf\"")
lumesh_cli_test(compare_heatmap 0 ARGS compare ${CMP_DIR}/a.exr ${CMP_DIR}/b.exr --heatmap ${CMP_DIR}/heat.png
  OUT "heat map +.*heat.png")
lumesh_cli_test(compare_size_mismatch 2 ARGS compare ${CMP_DIR}/a.exr ${CMP_DIR}/small.exr
  ONE_ERR_LINE ERR "^lumesh: .*a\\.exr is 4x3 but the reference .*small\\.exr is 2x2\n$")
lumesh_cli_test(compare_missing 2 ARGS compare ${CMP_DIR}/no-such-file.exr ${CMP_DIR}/b.exr
  ONE_ERR_LINE ERR "^lumesh: .*no-such-file\\.exr: cannot open")
lumesh_cli_test(compare_missing_reference 2 ARGS compare ${CMP_DIR}/a.exr ${CMP_DIR}/no-such-file.exr
  ONE_ERR_LINE ERR "^lumesh: .*no-such-file\\.exr: cannot open")
lumesh_cli_test(compare_heatmap_not_png 1 ARGS compare ${CMP_DIR}/a.exr ${CMP_DIR}/b.exr --heatmap x.jpg
  ERR "heat map must end in \\.png")
lumesh_cli_test(compare_bad_exposure 1 ARGS compare ${CMP_DIR}/a.exr ${CMP_DIR}/b.exr --exposure x
  ERR "--exposure wants a number")
set_tests_properties(cli_compare_self cli_compare_pair cli_compare_json cli_compare_json_identical
  cli_compare_heatmap cli_compare_size_mismatch cli_compare_missing_reference
  PROPERTIES FIXTURES_REQUIRED compare_cli_images)
