# End-to-end test of `magvine field`: the contract columns, exit code 2 with one line for bad input, and no
# output file left behind on failure. Run by CTest with -DMAGVINE=... -DWORK=... -DSRC=...
include(${CMAKE_CURRENT_LIST_DIR}/cli_common.cmake)

# 1. Good run.
execute_process(COMMAND ${MAGVINE} field --magnets ${SRC}/assets/magnets/epm_n52.yaml
                        --points ${SRC}/tests/data/probe_points.csv --out ${WORK}/out.csv
                RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "good run")
file(STRINGS ${WORK}/out.csv lines)
list(LENGTH lines n)
if(NOT n EQUAL 4)
  message(FATAL_ERROR "expected header + 3 rows, got ${n}")
endif()
list(GET lines 0 header)
if(NOT header STREQUAL "x,y,z,Bx,By,Bz,G11,G12,G13,G21,G22,G23,G31,G32,G33")
  message(FATAL_ERROR "header: ${header}")
endif()
# On the axis at 160 mm the exact cylinder gives Bz = 48.43 mT (closed form in test_cylinder).
list(GET lines 1 row)
string(REPLACE "," ";" cols "${row}")
list(GET cols 5 bz)
if(bz LESS 0.0484 OR bz GREATER 0.0485)
  message(FATAL_ERROR "Bz on the axis at 160 mm = ${bz} T, expected 0.04843")
endif()

# 2. Bad inputs: exit 2, one line on stderr naming the file, no output file.
file(WRITE ${WORK}/nan.csv "x,y,z\n0,0,0.1\n0,nan,0.2\n")
file(WRITE ${WORK}/empty.csv "")
file(WRITE ${WORK}/bad.yaml "units: {length: mm}\nmagnets:\n  - kind: cylinder\n    diameter: -5\n")
file(WRITE ${WORK}/unknown.yaml "units: {length: mm}\nmagnets:\n  - kind: uniform\n    feild: [0, 0, 1]\n")
foreach(case "nan.csv|epm_n52.yaml|nan.csv:3: column y" "empty.csv|epm_n52.yaml|empty.csv: empty file"
             "probe|bad.yaml|bad.yaml:4: magnets[0].diameter: must be in (0, 2000] mm"
             "probe|unknown.yaml|unknown.yaml:4: magnets[0].feild: unknown key (did you mean 'field'")
  string(REPLACE "|" ";" parts "${case}")
  list(GET parts 0 pts)
  list(GET parts 1 mag)
  list(GET parts 2 expect)
  if(pts STREQUAL "probe")
    set(pts ${SRC}/tests/data/probe_points.csv)
  else()
    set(pts ${WORK}/${pts})
  endif()
  if(mag STREQUAL "epm_n52.yaml")
    set(mag ${SRC}/assets/magnets/epm_n52.yaml)
  else()
    set(mag ${WORK}/${mag})
  endif()
  file(REMOVE ${WORK}/fail.csv)
  execute_process(COMMAND ${MAGVINE} field --magnets ${mag} --points ${pts} --out ${WORK}/fail.csv
                  RESULT_VARIABLE rc ERROR_VARIABLE err OUTPUT_VARIABLE out)
  expect_rc(${rc} 2 "${expect}")
  string(FIND "${err}" "${expect}" pos)
  if(pos EQUAL -1)
    message(FATAL_ERROR "stderr '${err}' does not contain '${expect}'")
  endif()
  string(STRIP "${err}" err_stripped)
  string(FIND "${err_stripped}" "\n" nl)
  if(NOT nl EQUAL -1)
    message(FATAL_ERROR "stderr is more than one line: '${err}'")
  endif()
  file(GLOB leftovers ${WORK}/fail.csv*)
  if(leftovers)
    message(FATAL_ERROR "output left behind after a failure: ${leftovers}")
  endif()
endforeach()

# 3. Unknown option / missing file: exit 2.
execute_process(COMMAND ${MAGVINE} field --magnets ${WORK}/none.yaml --points ${WORK}/none.csv RESULT_VARIABLE rc ERROR_QUIET)
expect_rc(${rc} 2 "missing files")
execute_process(COMMAND ${MAGVINE} field --bogus RESULT_VARIABLE rc ERROR_QUIET)
expect_rc(${rc} 2 "unknown option")
# 4. field-map: a 5 × 5 grid writes 25 rows and the JSON; a bad plane is exit 2 with nothing written.
execute_process(COMMAND ${MAGVINE} field-map --magnets ${SRC}/assets/magnets/epm_n52.yaml --resolution 5
                        --out ${WORK}/map RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "field-map")
file(STRINGS ${WORK}/map/field_map.csv lines)
list(LENGTH lines n)
if(NOT n EQUAL 26 OR NOT EXISTS ${WORK}/map/field_map.json)
  message(FATAL_ERROR "field-map wrote ${n} lines")
endif()
execute_process(COMMAND ${MAGVINE} field-map --magnets ${SRC}/assets/magnets/epm_n52.yaml --plane xx
                        --out ${WORK}/badmap RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 2 "field-map bad plane")
if(EXISTS ${WORK}/badmap)
  message(FATAL_ERROR "field-map created its output folder despite a bad plane")
endif()
# 5. The plot of a field map (the demo's second step): a PNG; a missing input is exit 2 with no PNG.
execute_process(COMMAND ${PYTHON} ${SRC}/tools/plot_field_map.py ${WORK}/map/field_map.csv --out ${WORK}/map.png
                RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "plot_field_map: ${err}")
if(NOT EXISTS ${WORK}/map.png)
  message(FATAL_ERROR "plot_field_map wrote no PNG")
endif()
execute_process(COMMAND ${PYTHON} ${SRC}/tools/plot_field_map.py ${WORK}/none.csv --out ${WORK}/none.png
                RESULT_VARIABLE rc ERROR_QUIET)
expect_rc(${rc} 2 "plot_field_map missing input")
if(EXISTS ${WORK}/none.png)
  message(FATAL_ERROR "plot_field_map left a PNG after a failure")
endif()
message(STATUS "cli_field: all checks passed")
