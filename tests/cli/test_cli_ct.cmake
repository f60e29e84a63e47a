# End-to-end test of `magvine ct import`: a capped tube written as a gzipped NIfTI label map (by Python, from the
# format's layout) imports to the four files; report.json is `mesh check --json` of airway.stl byte for byte and
# graph.json `mesh graph`'s; --frame lps turns the box about z; bad files exit 2 with one line and no folder.
# Run by CTest with -DMAGVINE=... -DWORK=... -DPYTHON=...
include(${CMAKE_CURRENT_LIST_DIR}/cli_common.cmake)

file(WRITE ${WORK}/make_tube.py [=[
import gzip, struct, sys
import numpy as np
# A tube of radius 5 mm along k, 60 mm long, capped, in 0.5 x 0.5 x 0.7 mm voxels placed by the qform at
# (-30, 40, 900) mm (scanner coordinates).
nx, ny, nz = 30, 30, 100
dx, dy, dz = 0.5, 0.5, 0.7
i, j, k = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
inside = ((i * dx - 7.25) ** 2 + (j * dy - 7.25) ** 2 <= 25.0) & (k * dz >= 5.0) & (k * dz <= 65.0)
data = inside.astype(np.int16).transpose(2, 1, 0).tobytes()  # i fastest
h = bytearray(352)
struct.pack_into("<i", h, 0, 348)
struct.pack_into("<8h", h, 40, 3, nx, ny, nz, 1, 1, 1, 1)
struct.pack_into("<hh", h, 70, 4, 16)
struct.pack_into("<8f", h, 76, 1.0, dx, dy, dz, 1, 1, 1, 1)
struct.pack_into("<f", h, 108, 352.0)
struct.pack_into("<h", h, 252, 1)
struct.pack_into("<6f", h, 256, 0, 0, 0, -30.0, 40.0, 900.0)
h[344:348] = b"n+1\0"
with gzip.open(sys.argv[1], "wb") as f:
    f.write(bytes(h) + data)
]=])
execute_process(COMMAND ${PYTHON} ${WORK}/make_tube.py ${WORK}/tube.nii.gz RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "writing the tube label map: ${err}")

execute_process(COMMAND ${MAGVINE} ct import ${WORK}/tube.nii.gz --out ${WORK}/tube
                RESULT_VARIABLE rc OUTPUT_VARIABLE summary ERROR_VARIABLE err)
expect_rc(${rc} 0 "ct import: ${err}")
file(GLOB written RELATIVE ${WORK}/tube ${WORK}/tube/*)
list(SORT written)
if(NOT written STREQUAL "airway.stl;graph.json;import.json;report.json")
  message(FATAL_ERROR "ct import wrote ${written}")
endif()

# report.json is what `mesh check --json` says of airway.stl, byte for byte; graph.json what `mesh graph` writes.
execute_process(COMMAND ${MAGVINE} mesh check ${WORK}/tube/airway.stl --json RESULT_VARIABLE rc OUTPUT_VARIABLE check)
expect_rc(${rc} 0 "mesh check of the imported surface")
file(READ ${WORK}/tube/report.json report)
if(NOT report STREQUAL check)
  message(FATAL_ERROR "report.json differs from mesh check --json:\n${report}\n---\n${check}")
endif()
execute_process(COMMAND ${MAGVINE} mesh graph ${WORK}/tube/airway.stl --out ${WORK}/graph_again.json RESULT_VARIABLE rc)
expect_rc(${rc} 0 "mesh graph of the imported surface")
file(READ ${WORK}/tube/graph.json graph)
file(READ ${WORK}/graph_again.json graph_again)
if(NOT graph STREQUAL graph_again)
  message(FATAL_ERROR "graph.json differs from mesh graph's")
endif()

execute_process(COMMAND ${MAGVINE} ct import ${WORK}/tube.nii.gz --out ${WORK}/lps --frame lps RESULT_VARIABLE rc)
expect_rc(${rc} 0 "ct import --frame lps")

# The values: the tube where the qform puts it (RAS), LPS turned about z, closed, volume of a capped cylinder.
file(WRITE ${WORK}/check.py [=[
import json, math, sys
ras, lps, imp = (json.load(open(f)) for f in sys.argv[1:4])
assert ras["watertight"] and ras["genus"] == 0 and ras["components"] == 1, ras
# Voxel centres: x in -30 + [2.25, 12.25] mm, z in 900 + [5, 65] mm; the surface lies half a voxel beyond the last
# inside centres, so within a voxel of the tube's own extent.
lo, hi = ras["bbox_min_m"], ras["bbox_max_m"]
for got, want in zip(lo + hi, [-0.03 + 0.00225, 0.04 + 0.00225, 0.905, -0.03 + 0.01225, 0.04 + 0.01225, 0.965]):
    assert abs(got - want) < 0.7e-3, (lo, hi)
for a, b in zip(lps["bbox_min_m"][:2] + lps["bbox_max_m"][:2], [-hi[0], -hi[1], -lo[0], -lo[1]]):
    assert abs(a - b) < 1e-9, (lps["bbox_min_m"], lps["bbox_max_m"])
v = math.pi * 0.005 ** 2 * 0.060
assert abs(ras["volume_m3"] / v - 1) < 0.06, ras["volume_m3"] / v  # half-voxel staircase at the caps and rim
assert imp["frame"] == "RAS" and imp["frame_source"] == "qform" and imp["components"] and imp["notes"], imp
print("ct import values ok")
]=])
execute_process(COMMAND ${PYTHON} ${WORK}/check.py ${WORK}/tube/report.json ${WORK}/lps/report.json
                ${WORK}/tube/import.json RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "ct import values:\n${out}\n${err}")
endif()

# Bad input: exit 2, one line naming the file, no output folder.
file(WRITE ${WORK}/text.nii.gz "not a label map\n")
expect_bad_file("ct;import" text.nii.gz "not a NIfTI file")
file(REMOVE_RECURSE ${WORK}/bad)
execute_process(COMMAND ${MAGVINE} ct import ${WORK}/tube.nii.gz --label 7 --out ${WORK}/bad
                RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 2 "absent label: ${err}")
string(FIND "${err}" "no voxel carries label 7" pos)
if(pos EQUAL -1 OR EXISTS ${WORK}/bad)
  message(FATAL_ERROR "absent label: '${err}', or output written")
endif()
