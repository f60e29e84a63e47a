# End-to-end test of `magvine run` (issues 4 and 6): the exact rod scene of the issue gives the contract outputs and the
# elastica's tip; bad scenes exit 2 with one line and write nothing; a body pulled into the magnet exits 3.
# Run by CTest with -DMAGVINE=... -DWORK=... -DSRC=... -DPYTHON=...
include(${CMAKE_CURRENT_LIST_DIR}/cli_common.cmake)

# 1. The issue's rod scene. Reference: the elastica solver (test_rod) puts the tip at (34.30, 42.94) mm; the
#    acceptance tolerance is 1 % of L = 0.6 mm.
execute_process(COMMAND ${MAGVINE} run ${SRC}/assets/scenes/rod_uniform_field.yaml --out ${WORK}/rod
                RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "rod scene: ${err}")
execute_process(COMMAND ${PYTHON} -c "
import csv, json, math, sys
m = json.load(open('${WORK}/rod/metrics.json'))
for key in ('tip_position_m', 'tip_tangent', 'bend_angle_deg', 'converged', 'iterations', 'runtime_s'):
    assert key in m, key
tip = m['tip_position_m']
err = math.hypot(tip[0] - 0.03430, tip[1] - 0.04294)
assert err < 0.6e-3, f'tip {tip} is {err*1e3:.3f} mm from the elastica'
assert m['converged'] is True
t = m['tip_tangent']
angle = math.degrees(math.acos(max(-1.0, min(1.0, t[0]))))
assert abs(angle - m['bend_angle_deg']) < 1e-9
rows = list(csv.reader(open('${WORK}/rod/shape.csv')))
assert rows[0] == ['s_m', 'x', 'y', 'z'], rows[0]
assert len(rows) == 52, len(rows)
assert abs(float(rows[-1][0]) - 0.06) < 1e-12
" RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "rod outputs: ${err}")

# 2. Bad scenes: exit 2, one line naming file and key, no output folder contents.
file(READ ${SRC}/assets/scenes/rod_uniform_field.yaml rod)
file(READ ${SRC}/assets/scenes/skin_vine_epm.yaml vine)
string(REPLACE "shear_modulus: 120000" "shear_modulus: -120000" negative "${rod}")
string(REPLACE "length: 60\n" "length: 0\n" zero "${rod}")
string(REPLACE "density: 1882" "densty: 1882" unknown "${rod}")
string(REPLACE "pressure: 6\n" "pressure: 60\n" burst "${vine}")
file(WRITE ${WORK}/negative.yaml "${negative}")
file(WRITE ${WORK}/zero.yaml "${zero}")
file(WRITE ${WORK}/unknown.yaml "${unknown}")
file(WRITE ${WORK}/burst.yaml "${burst}")
foreach(case "negative.yaml|robot.shear_modulus: must be in (0, " "zero.yaml|robot.length: must be in (0, "
             "unknown.yaml|robot.densty: unknown key (did you mean 'density'" "burst.yaml|robot.pressure: vine: pressure")
  string(REPLACE "|" ";" parts "${case}")
  list(GET parts 0 scene)
  list(GET parts 1 expect)
  expect_bad_file(run ${scene} "${expect}")
endforeach()

# 3. No equilibrium in free space: the vine 90 mm from the magnet's centre is pulled into the magnet body; the
#    solver gives up with a named cause and exit 3, and the metrics say converged: false.
string(REPLACE "position: [140, 0, 65]" "position: [90, 0, 65]" inside "${vine}")
file(WRITE ${WORK}/inside.yaml "${inside}")
execute_process(COMMAND ${MAGVINE} run ${WORK}/inside.yaml --out ${WORK}/inside RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 3 "vine pulled into the magnet: ${err}")
string(FIND "${err}" "numerical failure: static equilibrium" pos)
if(pos EQUAL -1)
  message(FATAL_ERROR "exit 3 without the cause: '${err}'")
endif()
file(READ ${WORK}/inside/metrics.json metrics)
string(FIND "${metrics}" "\"converged\": false" pos)
if(pos EQUAL -1)
  message(FATAL_ERROR "metrics.json of the failed run does not say converged: false")
endif()
# The rule for failed runs (docs/cli.md): metrics.json only, complete, saying failed: true.
expect_failed_run(${WORK}/inside "vine pulled into the magnet"
                  "tip_position_m;bend_angle_deg;iterations;pressure_radius_m;collapse_moment_Nm;creased")

# 4. A growth experiment (a scene with anatomy:): the bundled demo reaches its target; the contract files exist;
#    a misspelt control key exits 2 with one line naming file and key and writes nothing.
execute_process(COMMAND ${MAGVINE} run ${SRC}/assets/scenes/y_bifurcation_fluid_vine.yaml --out ${WORK}/experiment
                RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "experiment scene: ${err}")
execute_process(COMMAND ${PYTHON} -c "
import csv, json
m = json.load(open('${WORK}/experiment/metrics.json'))
assert m['success'] is True, m
assert m['branches_reached'][-1] == '0-0', m['branches_reached']
rows = list(csv.reader(open('${WORK}/experiment/tip_trajectory.csv')))
assert rows[0][:4] == ['t_s', 'x_m', 'y_m', 'z_m'], rows[0]
assert len(rows) == round(m['simulated_s'] / 0.02) + 1, (len(rows), m['simulated_s'])
# each step's largest line load; the run's is the largest of them (10 significant digits in the CSV)
k = rows[0].index('max_line_load_N_per_mm')
peak = max(float(r[k]) for r in rows[1:])
assert peak > 0 and abs(peak - m['max_wall_line_load_N_per_mm']) <= 1e-9 * peak, (peak, m['max_wall_line_load_N_per_mm'])
events = json.load(open('${WORK}/experiment/events.json'))
assert all('kind' in e and 'time_s' in e for e in events)
" RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "experiment outputs: ${err}")
file(READ ${SRC}/assets/scenes/y_bifurcation_fluid_vine.yaml experiment)
string(REPLACE "  pressure: [[0, 35]]" "  presure: [[0, 35]]" misspelt "${experiment}")
file(WRITE ${WORK}/misspelt.yaml "${misspelt}")
execute_process(COMMAND ${MAGVINE} run ${WORK}/misspelt.yaml --out ${WORK}/misspelt RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 2 "misspelt experiment: ${err}")
string(FIND "${err}" "control.presure: unknown key (did you mean 'pressure'" pos)
string(STRIP "${err}" stripped)
string(FIND "${stripped}" "\n" nl)
if(pos EQUAL -1 OR NOT nl EQUAL -1 OR EXISTS ${WORK}/misspelt)
  message(FATAL_ERROR "misspelt experiment: want one line naming control.presure and no output, got '${err}'")
endif()

# 5. Its plot (tools/plot_experiment.py): a PNG from the run; a missing run folder exits 2 with one line.
execute_process(COMMAND ${PYTHON} ${SRC}/tools/plot_experiment.py ${WORK}/experiment --out ${WORK}/experiment.png
                RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "plot_experiment: ${err}")
if(NOT EXISTS ${WORK}/experiment.png)
  message(FATAL_ERROR "plot_experiment wrote no PNG")
endif()
execute_process(COMMAND ${PYTHON} ${SRC}/tools/plot_experiment.py ${WORK}/no_such_run --out ${WORK}/none.png
                RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 2 "plot_experiment on a missing folder: ${err}")
if(EXISTS ${WORK}/none.png)
  message(FATAL_ERROR "plot_experiment wrote a PNG for a missing run")
endif()

# 6. magvine trials: the tree navigator towards both main bronchi, once each on two threads: the summary table and
#    the per-trial CSV; an unknown branch exits 2 with one line.
execute_process(COMMAND ${MAGVINE} trials ${SRC}/assets/scenes/bronchial_tree_navigator.yaml --targets 0-0,0-1
                        --repeats 1 --jobs 2 --out ${WORK}/trials
                RESULT_VARIABLE rc OUTPUT_VARIABLE table ERROR_VARIABLE err)
expect_rc(${rc} 0 "trials: ${err}")
string(FIND "${table}" "| target | path length [mm] | success | mean time [s] | SD [s] |" pos)
if(pos EQUAL -1)
  message(FATAL_ERROR "trials printed no summary table: '${table}'")
endif()
execute_process(COMMAND ${PYTHON} -c "
import csv
rows = list(csv.DictReader(open('${WORK}/trials/trials.csv')))
assert [r['target'] for r in rows] == ['0-0', '0-1'], rows
assert all(r['success'] == '1' for r in rows), rows
assert {'max_normal_N', 'retractions'} <= set(rows[0]) and 'unsettled_steps' not in rows[0], rows[0]
s = list(csv.DictReader(open('${WORK}/trials/summary.csv')))
assert [r['success_rate'] for r in s] == ['1.000', '1.000'], s
" RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "trials outputs: ${err}")
# Its plot (tools/plot_trials.py): a PNG; a folder without the tables exits 2 with one line and no PNG.
execute_process(COMMAND ${PYTHON} ${SRC}/tools/plot_trials.py ${WORK}/trials --out ${WORK}/trials.png
                RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "plot_trials: ${err}")
if(NOT EXISTS ${WORK}/trials.png)
  message(FATAL_ERROR "plot_trials wrote no PNG")
endif()
execute_process(COMMAND ${PYTHON} ${SRC}/tools/plot_trials.py ${WORK}/rod --out ${WORK}/trials_none.png
                RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 2 "plot_trials on a folder without trials: ${err}")
if(EXISTS ${WORK}/trials_none.png)
  message(FATAL_ERROR "plot_trials wrote a PNG for a folder without trials")
endif()
execute_process(COMMAND ${MAGVINE} trials ${SRC}/assets/scenes/bronchial_tree_navigator.yaml --targets 0-9
                        --out ${WORK}/trials_bad RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 2 "trials towards an unknown branch: ${err}")
string(FIND "${err}" "no branch '0-9'" pos)
if(pos EQUAL -1 OR EXISTS ${WORK}/trials_bad)
  message(FATAL_ERROR "trials towards 0-9: want one line naming the branch and no output, got '${err}'")
endif()
