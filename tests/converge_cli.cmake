# `lumesh converge` end to end on the built-in Cornell box at 48x48:
#   -DLUMESH=path -DDIR=work directory -DMODE=run|determinism
# run:    a 64-spp reference, then converge for 3 s against it with the path
#         tracer; checks the CSV (header, one complete row per snapshot and
#         method), the JSON (parses, same rows, statistics), the plot, the
#         snapshot images, that the path tracer's relMSE falls with time, that
#         the previewer's last error is below its first, and that no temporary
#         file is left.
# determinism: render --samples N --deterministic twice gives identical images.
# glossy: a reference made with --glossy direct (glossy materials reflect the
#         lights only) has converge model the same: its JSON and note say so.
# peers:  --methods vpl,vpl-ism,path-tracer (no cache): rows for each, the VPLs
#         made growing, instant radiosity's relMSE falling, one imperfect shadow
#         map made a VPL, and each VPL picture's mean dE not far above the path
#         tracer's (a wrong flux or a lost bounce is off by far more; with maps
#         only where not SANITIZED: there one pass takes most of the 2 s).
cmake_minimum_required(VERSION 3.19)
set(ref ${DIR}/ref.exr)
set(out ${DIR}/run)
file(REMOVE_RECURSE ${out})
file(MAKE_DIRECTORY ${DIR})

# check("rc EQUAL 0" "message"): the condition is evaluated as if() code.
macro(check cond msg)
  cmake_language(EVAL CODE "if(${cond})\nset(check_ok 1)\nelse()\nset(check_ok 0)\nendif()")
  if(NOT check_ok)
    message(FATAL_ERROR "${msg}")
  endif()
endmacro()

# hundredths("12.345" out): out = 1234 (a non-negative decimal number, truncated).
macro(hundredths value out)
  string(REGEX MATCH "^([0-9]+)(\\.([0-9]*))?$" _m "${value}")
  check("NOT \"${_m}\" STREQUAL \"\"" "not a plain decimal number: '${value}'")
  set(_frac "${CMAKE_MATCH_3}00")
  string(SUBSTRING "${_frac}" 0 2 _frac)
  math(EXPR ${out} "${CMAKE_MATCH_1} * 100 + 1${_frac} - 100")
endmacro()

if(MODE STREQUAL "determinism")
  foreach(i 1 2)
    execute_process(COMMAND ${LUMESH} render -o ${DIR}/det${i}.exr --width 64 --height 64 --samples 1500
                            --deterministic RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e TIMEOUT 120)
    check("rc EQUAL 0" "render ${i} failed (${rc}): ${o}${e}")
  endforeach()
  execute_process(COMMAND ${LUMESH} compare ${DIR}/det1.exr ${DIR}/det2.exr --json
                  RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e)
  check("rc EQUAL 0" "compare failed: ${o}${e}")
  string(JSON rmse GET "${o}" rmse)
  string(JSON maxe GET "${o}" max_abs_error)
  check("rmse EQUAL 0 AND maxe EQUAL 0" "two deterministic renders differ: rmse ${rmse}, max ${maxe}")
  message(STATUS "ok: two --samples 1500 --deterministic renders are identical")
  return()
endif()

if(MODE STREQUAL "glossy")
  execute_process(COMMAND ${LUMESH} reference ${SCENE_GLOSSY} -o ${DIR}/direct.exr --spp 4 --width 32 --height 24
                          --glossy direct RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e TIMEOUT 120)
  check("rc EQUAL 0" "reference --glossy direct failed: ${o}${e}")
  execute_process(COMMAND ${LUMESH} converge ${SCENE_GLOSSY} --reference ${DIR}/direct.exr --seconds 0.5
                          --snapshots 0.25 --out ${out} --sampler embree --residual off
                          --stats ${out}/stats.json
                  RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e TIMEOUT 180)
  check("rc EQUAL 0" "converge failed (${rc}): ${o}${e}")
  file(READ ${out}/convergence.json j)
  string(JSON glossy GET "${j}" glossy)
  string(JSON note GET "${j}" transport_note)
  check("glossy STREQUAL \"direct\"" "convergence.json: glossy is '${glossy}', not 'direct'")
  check("note MATCHES \"reflect the lights only\"" "transport note: ${note}")
  string(JSON gathers GET "${j}" stats glossy_gathers)
  check("gathers EQUAL 0" "the previewer gathered ${gathers} glossy reflections against a lights-only reference")
  message(STATUS "ok: a --glossy direct reference has converge reflect the lights only")
  return()
endif()

if(MODE STREQUAL "peers")
  execute_process(COMMAND ${LUMESH} reference -o ${ref} --spp 256 --width 48 --height 48
                  RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e TIMEOUT 120)
  check("rc EQUAL 0" "reference failed: ${o}${e}")
  execute_process(COMMAND ${LUMESH} converge --reference ${ref} --seconds 2 --snapshots 0.2,1 --out ${out}
                          --methods vpl,vpl-ism,path-tracer
                  RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e TIMEOUT 180)
  check("rc EQUAL 0" "converge failed (${rc}): ${o}${e}")
  file(STRINGS ${out}/convergence.csv lines)
  list(LENGTH lines n)
  check("n EQUAL 10" "convergence.csv has ${n} lines, expected 10 (3 snapshots of 3 methods):\n${o}")
  list(GET lines 0 header)
  check("header MATCHES \",vpls,image$\"" "no vpls column: ${header}")
  file(READ ${out}/convergence.json j)
  string(JSON nv LENGTH "${j}" methods vpl)
  string(JSON np LENGTH "${j}" methods path-tracer)
  string(JSON ni LENGTH "${j}" methods vpl-ism)
  check("nv EQUAL 3 AND ni EQUAL 3 AND np EQUAL 3" "convergence.json: ${nv} VPL, ${ni} VPL-ISM and ${np} path tracer snapshots")
  # One map a VPL (instant radiosity keeps every VPL it makes), at every
  # snapshot; the first may come before the first pass (under ASan, the GL
  # context and the point cloud take longer than 0.2 s), the last may not.
  foreach(k 0 1 2)
    string(JSON m${k} GET "${j}" methods vpl-ism ${k} ism_maps)
    string(JSON n${k} GET "${j}" methods vpl-ism ${k} vpls)
    check("m${k} EQUAL n${k}" "vpl-ism snapshot ${k}: ${m${k}} imperfect shadow maps for ${n${k}} VPLs")
  endforeach()
  check("m2 GREATER m0 AND m2 GREATER 0" "imperfect shadow maps made: ${m0} -> ${m2}")
  string(JSON has_lumesh ERROR_VARIABLE none GET "${j}" methods lumesh)
  check("NOT none STREQUAL \"NOTFOUND\"" "the cache ran though --methods did not name it")
  string(JSON v_first GET "${j}" methods vpl 0 vpls)
  string(JSON v_last GET "${j}" methods vpl 2 vpls)
  check("v_first GREATER 0 AND v_last GREATER v_first" "VPLs made: ${v_first} -> ${v_last}")
  string(JSON e_first GET "${j}" methods vpl 0 error relmse)
  string(JSON e_last GET "${j}" methods vpl 2 error relmse)
  check("e_last LESS e_first" "instant radiosity's relMSE did not fall: ${e_first} -> ${e_last}")
  # Against the path tracer at the same time and transport: a VPL estimate far
  # off (a wrong flux, a lost bounce) has a mean dE many times the path
  # tracer's; the two are within 1.5x of each other here. Compared in hundredths
  # (math() has integers only).
  string(JSON v_de GET "${j}" methods vpl 2 error delta_e_mean)
  string(JSON p_de GET "${j}" methods path-tracer 2 error delta_e_mean)
  hundredths(${v_de} v100)
  hundredths(${p_de} p100)
  math(EXPR bound "3 * ${p100} + 100")
  check("v100 LESS bound" "instant radiosity's mean dE ${v_de} is far above the path tracer's ${p_de}")
  # With shadow maps, where a pass is quick: a sanitized build (SANITIZED) builds
  # 837 maps in 1.2 s on llvmpipe and makes one pass in the 2 s, a picture of
  # noise; reference_ism_test checks the maps' image there. The maps' own bias
  # (point-splatted depth: light leaks at contacts) puts this picture above the
  # Embree one: mean dE 2.87 with 9,166 maps on an idle machine against the path
  # tracer's 0.91 (bound 3.74), and 3.96 in a CI run whose other test held the
  # cores (fewer maps in the 2 s). So its bound is 1.5 dE wider: still far below
  # what a lost bounce gives (the 64-spp references with and without it differ
  # by mean dE 9.6 here) or a wrong flux.
  string(JSON i_de GET "${j}" methods vpl-ism 2 error delta_e_mean)
  if(NOT SANITIZED)
    hundredths(${i_de} i100)
    math(EXPR ism_bound "${bound} + 150")
    check("i100 LESS ism_bound"
          "instant radiosity's mean dE with shadow maps ${i_de} (${m2} maps) is far above the path tracer's ${p_de}")
  endif()
  message(STATUS "ok: VPLs ${v_first} -> ${v_last}, relMSE ${e_first} -> ${e_last}, mean dE ${v_de}, with maps ${i_de} "
                 "(${m2} maps; path tracer ${p_de})")
  return()
endif()

execute_process(COMMAND ${LUMESH} reference -o ${ref} --spp 64 --width 48 --height 48
                RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e TIMEOUT 120)
check("rc EQUAL 0" "reference failed: ${o}${e}")
# --sampler embree: auto's calibration takes seconds under the sanitizers, and the
# previewer must get past its first snapshot within the run for the checks below.
execute_process(COMMAND ${LUMESH} converge --reference ${ref} --seconds 3 --snapshots 0.05,0.5,1 --out ${out}
                        --vs-path-tracer --stats ${out}/stats.json --sampler embree
                RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e TIMEOUT 180)
check("rc EQUAL 0" "converge failed (${rc}): ${o}${e}")

# The CSV: a header and 4 complete rows per method (0.05, 0.5, 1, 3 s).
file(STRINGS ${out}/convergence.csv lines)
list(LENGTH lines n)
check("n EQUAL 9" "convergence.csv has ${n} lines, expected 9:\n${o}")
list(GET lines 0 header)
string(REGEX MATCHALL "," hc "${header}")
list(LENGTH hc ncomma)
check("header MATCHES \"^method,target_seconds,seconds,state,leaves_tested,samples_light0,samples_direct,samples_indirect,samples_specular,spp_min,spp_max,rays,rmse,relmse,relmse_reference_noise,psnr,mean_abs_error,max_abs_error,delta_e_mean,delta_e_p99,delta_e_max,delta_e_above_jnd,estimated_delta_e_mean,estimated_fraction_above_jnd,estimated_fraction_untested,jnd,residual_weight,residual_corrected,residual_estimated_relmse,vpls,image$\"" "unexpected header: ${header}")
set(lumesh_rows 0)
set(pt_rows 0)
foreach(line IN LISTS lines)
  string(REGEX MATCHALL "," c "${line}")
  list(LENGTH c k)
  check("k EQUAL ncomma" "incomplete row: ${line}")
  if(line MATCHES "^lumesh,")
    math(EXPR lumesh_rows "${lumesh_rows} + 1")
  elseif(line MATCHES "^path-tracer,")
    math(EXPR pt_rows "${pt_rows} + 1")
  endif()
endforeach()
check("lumesh_rows EQUAL 4 AND pt_rows EQUAL 4" "rows: ${lumesh_rows} lumesh, ${pt_rows} path tracer")

# The JSON: the same rows, errors that behave, the statistics.
file(READ ${out}/convergence.json j)
string(JSON nl LENGTH "${j}" methods lumesh)
string(JSON np LENGTH "${j}" methods path-tracer)
check("nl EQUAL 4 AND np EQUAL 4" "convergence.json: ${nl} lumesh and ${np} path tracer snapshots")
string(JSON pt_first GET "${j}" methods path-tracer 0 error relmse)
string(JSON pt_last GET "${j}" methods path-tracer 3 error relmse)
string(JSON pt_spp GET "${j}" methods path-tracer 3 spp_min)
check("pt_last LESS pt_first" "the path tracer's relMSE did not fall: ${pt_first} -> ${pt_last}")
check("pt_spp GREATER 1" "the path tracer took ${pt_spp} samples per pixel in 3 s")
string(JSON lm_first GET "${j}" methods lumesh 0 error delta_e_mean)
string(JSON lm_last GET "${j}" methods lumesh 3 error delta_e_mean)
check("lm_last LESS lm_first" "the previewer's mean dE did not fall: ${lm_first} -> ${lm_last}")
string(JSON first GET "${j}" first_image_seconds)
check("NOT first STREQUAL \"null\"" "no first image was drawn")
string(JSON light_samples GET "${j}" methods lumesh 3 samples light0)
check("light_samples GREATER 0" "no light sample recorded")
# A fresh reference says its glossy materials reflect the room (lumesh:glossy),
# and converge models the same.
string(JSON glossy GET "${j}" glossy)
check("glossy STREQUAL \"indirect\"" "convergence.json: glossy is '${glossy}', not 'indirect'")
string(JSON mesh0 GET "${j}" stats meshes 0 mesh)
check("mesh0 STREQUAL \"light0\"" "statistics: first mesh is '${mesh0}'")
file(READ ${out}/stats.json s)
string(JSON nmesh LENGTH "${s}" meshes)
check("nmesh EQUAL 3" "stats.json lists ${nmesh} meshes, expected light0, direct, indirect (no gloss: no specular)")
# Each radiance mesh's yield (what its tests removed per unit of priority, which
# the scheduler weighs it by; docs/stats.md): a number, 0 or more (0 when the
# rounds since its queue was last made found nothing); a light mesh has none.
foreach(k 1 2)
  string(JSON name GET "${s}" meshes ${k} mesh)
  string(JSON type TYPE "${s}" meshes ${k} yield)
  string(JSON yield GET "${s}" meshes ${k} yield)
  check("type STREQUAL \"NUMBER\" AND NOT yield LESS 0" "stats.json: the ${name} mesh's yield is ${yield} (${type})")
endforeach()
string(JSON light_yield ERROR_VARIABLE no_yield GET "${s}" meshes 0 yield)
check("NOT no_yield STREQUAL \"NOTFOUND\"" "stats.json: the light mesh has a yield (${light_yield})")

foreach(f convergence.png first-image.exr lumesh-00000.050s.exr lumesh-00003.000s.png path-tracer-00001.000s.exr)
  check("EXISTS ${out}/${f}" "${f} was not written")
endforeach()
file(GLOB tmp ${out}/*.tmp)
check("\"${tmp}\" STREQUAL \"\"" "temporary files left: ${tmp}")
message(STATUS "ok: lumesh dE ${lm_first} -> ${lm_last}; path tracer relMSE ${pt_first} -> ${pt_last} (${pt_spp} spp)")
