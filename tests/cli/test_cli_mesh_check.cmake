# End-to-end test of `magvine mesh check`: the JSON contract keys and values for a closed and an open mesh, exit 0
# with warnings for a usable mesh, exit 2 with one line for unusable files, and no report file left on failure.
# Run by CTest with -DMAGVINE=... -DWORK=... -DPYTHON=...
include(${CMAKE_CURRENT_LIST_DIR}/cli_common.cmake)

# A 10 mm cube (closed) and the same cube without its top (one square opening, normal +z).
set(cube_vertices "v 0 0 0\nv 10 0 0\nv 10 10 0\nv 0 10 0\nv 0 0 10\nv 10 0 10\nv 10 10 10\nv 0 10 10\n")
set(sides "f 1 4 3 2\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n")
file(WRITE ${WORK}/cube.obj "${cube_vertices}${sides}f 5 6 7 8\n")
file(WRITE ${WORK}/open.obj "${cube_vertices}${sides}")

execute_process(COMMAND ${MAGVINE} mesh check ${WORK}/cube.obj --units mm --json
                RESULT_VARIABLE rc OUTPUT_VARIABLE json ERROR_VARIABLE err)
expect_rc(${rc} 0 "closed cube")
file(WRITE ${WORK}/cube.json "${json}")
execute_process(COMMAND ${MAGVINE} mesh check ${WORK}/open.obj --out ${WORK}/open.json
                RESULT_VARIABLE rc OUTPUT_VARIABLE summary ERROR_VARIABLE err)
expect_rc(${rc} 0 "open cube (usable, with a warning)")
string(FIND "${summary}" "warning: open mesh" pos)
if(pos EQUAL -1)
  message(FATAL_ERROR "summary lacks the open-mesh warning:\n${summary}")
endif()

# Contract keys and the values known by construction (SI units).
file(WRITE ${WORK}/check.py [=[
import json, math, sys
keys = ["triangles", "vertices", "bbox_min_m", "bbox_max_m", "area_m2", "volume_m3", "watertight", "boundary_edges",
        "non_manifold_edges", "components", "genus", "degenerate_removed", "openings", "warnings"]
cube, open_ = (json.load(open(f)) for f in sys.argv[1:3])
for report in (cube, open_):
    missing = [k for k in keys if k not in report]
    assert not missing, f"missing keys {missing}"
def near(a, b, tol=1e-12):
    assert abs(a - b) <= tol * max(1.0, abs(b)), (a, b)
assert cube["triangles"] == 12 and cube["vertices"] == 8, cube
assert cube["watertight"] is True and cube["boundary_edges"] == 0 and cube["genus"] == 0 and cube["components"] == 1
near(cube["volume_m3"], 1e-6)
near(cube["area_m2"], 6e-4)
assert cube["bbox_max_m"] == [0.01, 0.01, 0.01], cube["bbox_max_m"]
assert cube["openings"] == [] and cube["warnings"] == []
assert open_["volume_m3"] is None and open_["watertight"] is False and open_["boundary_edges"] == 4
assert len(open_["openings"]) == 1
o = open_["openings"][0]
for got, want in zip(o["centroid_m"], [0.005, 0.005, 0.01]):
    near(got, want)
for got, want in zip(o["normal"], [0.0, 0.0, 1.0]):
    near(got, want)
near(o["diameter_m"], 2 * math.sqrt(1e-4 / math.pi))  # equivalent diameter of the 10 mm square
assert any("open mesh" in w for w in open_["warnings"])
print("mesh check JSON ok")
]=])
execute_process(COMMAND ${PYTHON} ${WORK}/check.py ${WORK}/cube.json ${WORK}/open.json
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "JSON contract check failed:\n${out}\n${err}")
endif()

# Unusable files: exit 2, exactly one line on stderr naming the file, no report written.
file(WRITE ${WORK}/empty.stl "")
file(WRITE ${WORK}/lines.obj "v 0 0 0\nv 1 0 0\nl 1 2\n")
file(WRITE ${WORK}/nan.obj "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
file(WRITE ${WORK}/model.vtk "# vtk DataFile Version 3.0\nmodel\nASCII\nDATASET POLYDATA\n")
file(MAKE_DIRECTORY ${WORK}/folder.stl)
foreach(case "empty.stl|file is empty" "lines.obj|no triangles" "nan.obj|non-finite" "model.vtk|legacy VTK"
             "folder.stl|directory" "missing.ply|not found")
  string(REPLACE "|" ";" parts "${case}")
  list(GET parts 0 name)
  list(GET parts 1 expect)
  file(REMOVE ${WORK}/fail.json)
  execute_process(COMMAND ${MAGVINE} mesh check ${WORK}/${name} --out ${WORK}/fail.json
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  expect_rc(${rc} 2 "${name}")
  string(FIND "${err}" "${WORK}/${name}" pos_file)
  string(FIND "${err}" "${expect}" pos)
  string(STRIP "${err}" stripped)
  string(FIND "${stripped}" "\n" newline)
  if(pos EQUAL -1 OR pos_file EQUAL -1 OR NOT newline EQUAL -1)
    message(FATAL_ERROR "${name}: expected one line naming the file with '${expect}', got:\n${err}")
  endif()
  if(EXISTS ${WORK}/fail.json)
    message(FATAL_ERROR "${name}: a report was written for an unusable mesh")
  endif()
endforeach()
execute_process(COMMAND ${MAGVINE} mesh check ${WORK}/cube.obj --units inch RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 2 "--units inch")

# `magvine mesh graph` (issue 8): the generated Y bifurcation's centreline graph from its mesh alone: three
# branches named from the root (0, 0-0, 0-1), written as graph JSON; a bad --out exits 2 and writes nothing.
execute_process(COMMAND ${MAGVINE} phantom y_bifurcation --out ${WORK}/y.stl RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "phantom y_bifurcation: ${err}")
execute_process(COMMAND ${MAGVINE} mesh graph ${WORK}/y.stl --out ${WORK}/y_extracted.json
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
expect_rc(${rc} 0 "mesh graph: ${err}")
execute_process(COMMAND ${PYTHON} -c "
import json
g = json.load(open('${WORK}/y_extracted.json'))
assert g['format'] == 'magvine-airway-graph' and g['units'] == 'mm', g.get('format')
names = sorted(b['name'] for b in g['branches'])
assert names == ['0', '0-0', '0-1'], names
gens = {b['name']: b['generation'] for b in g['branches']}
assert gens == {'0': 0, '0-0': 1, '0-1': 1}, gens
" RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "mesh graph output: ${err}")
execute_process(COMMAND ${MAGVINE} mesh graph ${WORK}/y.stl --out ${WORK}/y_extracted.txt
                RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 2 "mesh graph --out .txt: ${err}")
if(EXISTS ${WORK}/y_extracted.txt)
  message(FATAL_ERROR "mesh graph wrote a graph under a bad --out")
endif()
