# End-to-end test of `magvine phantom`: phantoms/generate.sh writes every standard phantom; each is watertight, one
# component, genus 0 by `magvine mesh check`; the graphs and metadata equal the ones committed in phantoms/ (the
# generator is deterministic, so the committed ground truth must be what the code writes); bad parameters and a bad
# --out exit 2 with one line and leave no files.
# Run by CTest with -DMAGVINE=... -DWORK=... -DSRC=... -DPYTHON=...
include(${CMAKE_CURRENT_LIST_DIR}/cli_common.cmake)

execute_process(COMMAND bash ${SRC}/phantoms/generate.sh ${MAGVINE} ${WORK}/gen
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
expect_rc(${rc} 0 "phantoms/generate.sh: ${err}")

file(GLOB stls ${WORK}/gen/*.stl)
list(LENGTH stls count)
if(count LESS 8)
  message(FATAL_ERROR "generate.sh wrote ${count} phantoms, expected 8")
endif()
foreach(stl ${stls})
  get_filename_component(name ${stl} NAME_WE)
  execute_process(COMMAND ${MAGVINE} mesh check ${stl} --units mm --out ${WORK}/${name}.check.json
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  expect_rc(${rc} 0 "mesh check ${name}: ${err}")
endforeach()

file(WRITE ${WORK}/check.py [=[
import glob, json, math, os, sys
work, committed = sys.argv[1], sys.argv[2]

def near(a, b, path):
    if isinstance(b, float) or isinstance(a, float):
        assert abs(a - b) <= 1e-9 * max(1.0, abs(b)), f"{path}: {a} != {b}"
    elif isinstance(b, dict):
        assert sorted(a) == sorted(b), f"{path}: keys {sorted(a)} != {sorted(b)}"
        for k in b:
            near(a[k], b[k], f"{path}.{k}")
    elif isinstance(b, list):
        assert len(a) == len(b), f"{path}: length {len(a)} != {len(b)}"
        for i, (x, y) in enumerate(zip(a, b)):
            near(x, y, f"{path}[{i}]")
    else:
        assert a == b, f"{path}: {a!r} != {b!r}"

checks = sorted(glob.glob(os.path.join(work, "*.check.json")))
for check in checks:
    name = os.path.basename(check)[: -len(".check.json")]
    report = json.load(open(check))
    assert report["watertight"] and report["boundary_edges"] == 0 and report["non_manifold_edges"] == 0, name
    assert report["components"] == 1 and report["genus"] == 0, (name, report["components"], report["genus"])
    meta = json.load(open(os.path.join(work, "gen", name + ".meta.json")))
    assert meta["units"] == "mm" and meta["triangles"] == report["triangles"], name
    # The metadata volume (mm³, from the double-precision mesh) is the enclosed volume of the STL, whose float32
    # coordinates (relative rounding 6e-8 of the extent) move it by ~1e-7 relative: 1e-5 leaves room for that only.
    assert abs(meta["volume_mm3"] * 1e-9 - report["volume_m3"]) <= 1e-5 * report["volume_m3"], name
    for kind in ("graph", "meta"):
        got = json.load(open(os.path.join(work, "gen", f"{name}.{kind}.json")))
        want = json.load(open(os.path.join(committed, f"{name}.{kind}.json")))
        near(got, want, f"{name}.{kind}.json")
print(f"{len(checks)} phantoms watertight, genus 0, equal to the committed ground truth")
]=])
execute_process(COMMAND ${PYTHON} ${WORK}/check.py ${WORK} ${SRC}/phantoms
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
expect_rc(${rc} 0 "phantom checks:\n${out}${err}")
message(STATUS "${out}")

# Bad input: a parameter out of range, an unknown option, an --out that is not STL. Exit 2, one line, no files.
foreach(case "constriction;--gap-mm;20;bad_gap.stl" "tube;--diameter-mm;nan;bad_nan.stl"
             "tube;--colour;red;bad_option.stl" "tube;--length-mm;100;bad_out.obj")
  list(GET case 0 kind)
  list(GET case 1 option)
  list(GET case 2 value)
  list(GET case 3 file)
  execute_process(COMMAND ${MAGVINE} phantom ${kind} ${option} ${value} --out ${WORK}/bad/${file}
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  expect_rc(${rc} 2 "phantom ${kind} ${option} ${value}")
  string(STRIP "${err}" err)
  string(FIND "${err}" "\n" newline)
  if(NOT newline EQUAL -1 OR err STREQUAL "")
    message(FATAL_ERROR "phantom ${kind} ${option} ${value}: expected one error line, got:\n${err}")
  endif()
endforeach()
if(EXISTS ${WORK}/bad)
  file(GLOB left ${WORK}/bad/*)
  if(left)
    message(FATAL_ERROR "failed runs left files: ${left}")
  endif()
endif()
