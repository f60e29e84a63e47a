# End-to-end test of `magvine design` (issue 29): the bundled catheter design gives the contract outputs, and the
# scene it writes reproduces the design's shape under `magvine run` to 1e-6 m (the acceptance); a free field stays
# within its bound; bad design files exit 2 with one line naming the file and key, and write nothing.
# Run by CTest with -DMAGVINE=... -DWORK=... -DSRC=... -DPYTHON=...
include(${CMAKE_CURRENT_LIST_DIR}/cli_common.cmake)

# `magvine design FILE --out WORK/NAME`, then `magvine run` of the scene.yaml it wrote into WORK/NAME_run.
function(design_and_rerun name file)
  execute_process(COMMAND ${MAGVINE} design ${file} --out ${WORK}/${name} RESULT_VARIABLE rc ERROR_VARIABLE err)
  expect_rc(${rc} 0 "design ${name}: ${err}")
  execute_process(COMMAND ${MAGVINE} run ${WORK}/${name}/scene.yaml --out ${WORK}/${name}_run RESULT_VARIABLE rc
                  ERROR_VARIABLE err)
  expect_rc(${rc} 0 "run of the ${name} design's scene.yaml: ${err}")
endfunction()

file(READ ${SRC}/assets/scenes/design_catheter.yaml design)
string(REPLACE "# field: {free: {max: 0.010}}" "field: {free: {max: 0.010}}" free "${design}")
file(WRITE ${WORK}/fixed.yaml "${design}")
file(WRITE ${WORK}/free.yaml "${free}")

foreach(case fixed free)
  design_and_rerun(${case} ${WORK}/${case}.yaml)
  execute_process(COMMAND ${PYTHON} -c "
import csv, json, math
d = json.load(open('${WORK}/${case}/design.json'))
for key in ('rms_m', 'max_error_m', 'iterations', 'evaluations', 'runtime_s', 'converged', 'sections', 'history'):
    assert key in d, key
assert len(d['sections']) == 5
for s in d['sections']:
    assert abs(math.hypot(*s['direction']) - 1.0) < 1e-12, s
# The S is a thesis-like arbitrary shape: A.1.5.1 asks below 2 mm (the fixed field measured 0.70 mm).
assert d['rms_m'] < 2e-3, d['rms_m']
if '${case}' == 'free':
    b = d['field_T']
    assert math.hypot(*b) <= 0.010 * (1 + 1e-12), b   # the thesis's A.1.5.2 bound (half the fixed field)
design = [list(map(float, r)) for r in list(csv.reader(open('${WORK}/${case}/shape.csv')))[1:]]
run = [list(map(float, r)) for r in list(csv.reader(open('${WORK}/${case}_run/shape.csv')))[1:]]
assert len(design) == len(run) == 41
worst = max(math.dist(a[1:], b[1:]) for a, b in zip(design, run))
assert worst < 1e-6, f'magvine run of scene.yaml is {worst} m from the design'
rows = list(csv.DictReader(open('${WORK}/${case}/target.csv')))
assert len(rows) == 9
rms = math.sqrt(sum(float(r['error_m'])**2 for r in rows) / 9)
assert abs(rms - d['rms_m']) < 1e-9, (rms, d['rms_m'])
" RESULT_VARIABLE rc ERROR_VARIABLE err)
  expect_rc(${rc} 0 "design ${case} outputs: ${err}")
endforeach()

# Where the EPM goes as a design variable (the thesis EPM, exact cylinder, in a 100 mm box): the S in its gradient field;
# scene.yaml carries the placed magnet and reproduces the shape.
string(REPLACE "  - {kind: uniform, field: [0, 0.02, 0]}"
               "  - {kind: cylinder, diameter: 101.6, length: 101.6, polarisation: 1.48, position: [20, -150, 0], axis: [0, 1, 0]}"
               epm "${design}")
string(REPLACE "  remanence: 0.125 " "  magnet: {index: 0, min: [-30, -200, -50], max: [70, -100, 50]}\n  starts: 2\n  remanence: 0.125 " epm "${epm}")
file(WRITE ${WORK}/epm.yaml "${epm}")
design_and_rerun(epm ${WORK}/epm.yaml)
execute_process(COMMAND ${PYTHON} -c "
import csv, json, math
d = json.load(open('${WORK}/epm/design.json'))
p = d['magnet_position_m']
assert -0.030 - 1e-12 <= p[0] <= 0.070 + 1e-12 and -0.200 - 1e-12 <= p[1] <= -0.100 + 1e-12, p
assert d['rms_m'] < 0.70e-3, d['rms_m']   # the gradient field shapes the S better than the uniform 20 mT (0.70 mm)
design = [list(map(float, r)) for r in list(csv.reader(open('${WORK}/epm/shape.csv')))[1:]]
run = [list(map(float, r)) for r in list(csv.reader(open('${WORK}/epm_run/shape.csv')))[1:]]
assert max(math.dist(a[1:], b[1:]) for a, b in zip(design, run)) < 1e-6
" RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "EPM design outputs: ${err}")

# Its orientation too (design.magnet.orientation): scene.yaml carries the designed axis and reproduces the shape. The
# axis adds local minima: 2 starts ended at 1.55 mm, 4 at 0.65 mm, 8 at 0.058 mm (the position alone: 0.057 mm from 2).
string(REPLACE "max: [70, -100, 50]}" "max: [70, -100, 50], orientation: true}" epm_axis "${epm}")
string(REPLACE "starts: 2" "starts: 8" epm_axis "${epm_axis}")
file(WRITE ${WORK}/epm_axis.yaml "${epm_axis}")
design_and_rerun(epm_axis ${WORK}/epm_axis.yaml)
execute_process(COMMAND ${PYTHON} -c "
import csv, json, math
d = json.load(open('${WORK}/epm_axis/design.json'))
a = d['magnet_axis']
assert abs(math.hypot(*a) - 1.0) < 1e-12, a
assert d['rms_m'] < 0.70e-3, d['rms_m']
design = [list(map(float, r)) for r in list(csv.reader(open('${WORK}/epm_axis/shape.csv')))[1:]]
run = [list(map(float, r)) for r in list(csv.reader(open('${WORK}/epm_axis_run/shape.csv')))[1:]]
assert max(math.dist(a[1:], b[1:]) for a, b in zip(design, run)) < 1e-6
" RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "EPM pose design outputs: ${err}")

# Follow-the-leader (thesis A.1.5.2): the bundled insertion design, eight steps with a field of at most 10 mT each;
# RMS over all steps within the issue's 1 mm (measured 0.25 mm); the fully inserted scene reproduces the last step.
design_and_rerun(insertion ${SRC}/assets/scenes/design_insertion.yaml)
execute_process(COMMAND ${PYTHON} -c "
import csv, json, math
d = json.load(open('${WORK}/insertion/design.json'))
ins = d['insertion']
assert ins['steps'] == 8 and len(ins['fields_T']) == 8 and len(ins['step_rms_m']) == 8
assert all(math.hypot(*b) <= 0.010 * (1 + 1e-12) for b in ins['fields_T']), ins['fields_T']
assert d['rms_m'] <= 1e-3, d['rms_m']
rows = list(csv.DictReader(open('${WORK}/insertion/insertion.csv')))
assert sorted({int(r['step']) for r in rows}) == list(range(1, 9))
assert len([r for r in rows if r['step'] == '8']) == 57
design = [list(map(float, r)) for r in list(csv.reader(open('${WORK}/insertion/shape.csv')))[1:]]
run = [list(map(float, r)) for r in list(csv.reader(open('${WORK}/insertion_run/shape.csv')))[1:]]
assert max(math.dist(a[1:], b[1:]) for a, b in zip(design, run)) < 1e-6
" RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "insertion outputs: ${err}")

# A patient-specific design (issue 29, item 4): the path from the generated bronchial tree's graph to segmental branch
# 0-0-0-1. The design (RMS 1.00 mm over the twelve steps here; 0.995-1.09 mm over seeds, iteration caps and builds)
# writes experiment.yaml, the designed catheter pushed through the tree with the design's fields. Where its tip ends,
# and so the wall force, turns on which optimum the design found (docs/design.md#patient-specific-designs): designs
# that follow the path press 0.14 mN, one that went astray 31.6 mN and then met the contact solver's lagged-friction
# limit (issue 28), exit 3. So the run must end as a run or as that documented failure (exit 3 with metrics.json
# naming the step), and the navigator-steered catheter of the same size must reach the target.
execute_process(COMMAND ${MAGVINE} design ${SRC}/assets/scenes/design_bronchial_path.yaml --out ${WORK}/airway
                RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "airway-path design: ${err}")
execute_process(COMMAND ${MAGVINE} run ${WORK}/airway/experiment.yaml --out ${WORK}/airway_run
                RESULT_VARIABLE designed_rc ERROR_VARIABLE err)
if(NOT designed_rc EQUAL 0 AND NOT designed_rc EQUAL 3)
  message(FATAL_ERROR "designed catheter in the tree: exit ${designed_rc}: ${err}")
endif()
execute_process(COMMAND ${MAGVINE} run ${SRC}/assets/scenes/bronchial_tree_catheter_navigator.yaml
                        --out ${WORK}/airway_nav RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "navigated catheter in the tree: ${err}")
execute_process(COMMAND ${PYTHON} -c "
import json
d = json.load(open('${WORK}/airway/design.json'))
assert d['rms_m'] < 1.5e-3 and len(d['insertion']['fields_T']) == 12, d['rms_m']
designed = json.load(open('${WORK}/airway_run/metrics.json'))
navigated = json.load(open('${WORK}/airway_nav/metrics.json'))
if ${designed_rc} == 3:
    assert designed['failed'] and designed['failure'].startswith('step '), designed['failure']
else:
    assert designed['converged'] and designed['generation_reached'] >= 3, designed
assert navigated['success'], navigated['failure']
print('designed catheter: success', designed['success'], 'peak', designed['max_wall_normal_N'], 'N; navigated peak',
      navigated['max_wall_normal_N'], 'N')
" RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "designed against navigated catheter: ${err}")

# The MPM check's plumbing (`--mpm-check`): a coarse grid (2 cells across the Ø4 mm rod, 2 particles per cell per axis:
# seconds, not the resolution docs/design.md measures with) writes the MPM scene, its outputs and the comparison.
if(WITH_MPM)
  execute_process(COMMAND ${MAGVINE} design ${WORK}/fixed.yaml --out ${WORK}/mpm --mpm-check --mpm-cell 2
                          --mpm-particles 2
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  expect_rc(${rc} 0 "design --mpm-check: ${err}")
  execute_process(COMMAND ${PYTHON} -c "
import json, os
d = json.load(open('${WORK}/mpm/design.json'))
m = d['mpm_check']
for key in ('rms_m', 'max_m', 'target_rms_m', 'settled', 'simulated_s', 'runtime_s', 'steps', 'particles'):
    assert key in m, key
assert m['failure'] == '' and m['particles'] > 100 and 0.0 < m['rms_m'] < 0.04, m
assert os.path.exists('${WORK}/mpm/mpm_check.yaml') and os.path.exists('${WORK}/mpm/mpm_check/probes.csv')
" RESULT_VARIABLE rc ERROR_VARIABLE err)
  expect_rc(${rc} 0 "design --mpm-check outputs: ${err}")
else()
  execute_process(COMMAND ${MAGVINE} design ${WORK}/fixed.yaml --out ${WORK}/mpm --mpm-check
                  RESULT_VARIABLE rc ERROR_VARIABLE err)
  expect_rc(${rc} 2 "design --mpm-check without the MPM module: ${err}")
endif()

# Bad design files: exit 2, one line naming the file and the key, no output folder.
string(REPLACE "[29.5559, 23.4349, 0]" "[45, 0, 0]" far "${design}")
string(REPLACE "[14.7826, 11.7096, 0]" "[12, 12, 0]" stretched "${design}")
string(REPLACE "[9.1077, 3.5763, 0]" "[9.1077, .nan, 0]" nan "${design}")
string(REPLACE "remanence: 0.125 " "remanence: {min: 0.2, max: 0.1} " bounds "${design}")
string(REPLACE "  target:" "  targets:" missing "${design}")
string(REPLACE "kind: rod" "kind: rods" kind "${design}")
file(READ ${SRC}/assets/scenes/design_bronchial_path.yaml airway)
string(REPLACE "branch: 0-0-0-1," "branch: 0-0-0-7," nobranch "${airway}")
string(REPLACE "position: [0, 0, -119]" "position: [3, 0, -119]" offpath "${airway}")
string(REPLACE "length: 84" "length: 120" toolong "${airway}")
foreach(name far stretched nan bounds missing kind nobranch offpath toolong)
  file(WRITE ${WORK}/${name}.yaml "${${name}}")
endforeach()
foreach(case "far.yaml|design.target.points[8]: is 45" "stretched.yaml|design.target.points[5]: is 6.59 mm from the point before"
             "nan.yaml|design.target.points[2]" "bounds.yaml|design.remanence.min: exceeds max"
             "missing.yaml|design.targets: unknown key (did you mean 'target'" "kind.yaml|robot.kind"
             "nobranch.yaml|design.insertion.path.branch: '0-0-0-7' is not a branch"
             "offpath.yaml|the rod's base must sit on the path to 0-0-0-1"
             "toolong.yaml|shorter than the rod (120 mm)")
  string(REPLACE "|" ";" parts "${case}")
  list(GET parts 0 file)
  list(GET parts 1 expect)
  expect_bad_file(design ${file} "${expect}")
endforeach()
