# End-to-end test of `magvine calibrate` (issue 29): the bundled fluid-vine calibration fits the Ø4 mm vine's critical
# distance (the thesis's ≈160 mm) and writes the contract outputs with every held-out prediction; the calibrated
# scene runs under `magvine run`; bad calibration files and measurements exit 2 with one line naming the file and key,
# and write nothing.
# Run by CTest with -DMAGVINE=... -DWORK=... -DSRC=... -DPYTHON=...
include(${CMAKE_CURRENT_LIST_DIR}/cli_common.cmake)

execute_process(COMMAND ${MAGVINE} calibrate ${SRC}/assets/scenes/calibrate_fluid_vine.yaml --out ${WORK}/fluid
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
expect_rc(${rc} 0 "calibrate: ${err}")
execute_process(COMMAND ${MAGVINE} run ${WORK}/fluid/scene.yaml --out ${WORK}/fluid_run RESULT_VARIABLE rc
                ERROR_VARIABLE err)
expect_rc(${rc} 0 "run of the calibrated scene: ${err}")
execute_process(COMMAND ${PYTHON} -c "
import csv, json
d = json.load(open('${WORK}/fluid/calibration.json'))
for key in ('parameters', 'covariance_si', 'correlation', 'chi2', 'fitted', 'held_out', 'iterations', 'evaluations',
            'equilibria', 'runtime_s', 'converged', 'message', 'history_chi'):
    assert key in d, key
assert d['converged'] and d['fitted'] == 1 and d['held_out'] == 5, d
(p,) = d['parameters']
assert p['key'] == 'robot.fill.volume_fraction' and p['min'] <= p['value'] <= p['max'] and p['sigma'] > 0, p
rows = list(csv.DictReader(open('${WORK}/fluid/predictions.csv')))
assert len(rows) == 6 and [r['use'] for r in rows].count('fit') == 1
fit = rows[0]
# One parameter, one measurement: the fit meets it to the equilibria's precision (the bisection's 1e-12 m).
assert abs(float(fit['predicted']) - 160.0) < 1e-6, fit
assert abs(float(fit['predicted_sigma']) - 5.0) < 1e-6, fit   # σ_θ maps back onto the one measurement's σ
for r in rows:
    assert float(r['predicted_sigma']) > 0 and r['reached'] == '1', r
m = json.load(open('${WORK}/fluid_run/metrics.json'))
assert m['converged'], m
" RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "calibrate outputs: ${err}")

# Bad files: exit 2, one line naming the file and key, no output folder.
file(READ ${SRC}/assets/scenes/calibrate_fluid_vine.yaml good)
file(READ ${SRC}/assets/scenes/fluid_vine_thesis.csv measured)
string(REPLACE "measurements: fluid_vine_thesis.csv" "measurements: ${WORK}/measured.csv" good "${good}")
file(WRITE ${WORK}/measured.csv "${measured}")
string(REPLACE "fill.volume_fraction: {min" "fill.iron: {min" unknown "${good}")
string(REPLACE "fill.volume_fraction: {min" "wall.density: {min: 0, max: 2000}\n    fill.volume_fraction: {min" both "${good}")
string(REPLACE "density: 1000}" "}" absent "${both}")
string(REPLACE "{min: 0.02, max: 0.5}" "{min: 0.3, max: 0.5}" outside "${good}")
string(REPLACE "  - {kind: cylinder" "  - {kind: uniform, field: [0.01, 0, 0]}\n  - {kind: cylinder" twomagnets "${good}")
string(REPLACE "measured.csv" "bad_value.csv" bad_value "${good}")
string(REPLACE "4,35,critical_distance,,160,5,fit" "4,35,critical_distance,,nan,5,fit" bad_value_csv "${measured}")
string(REPLACE "measured.csv" "bad_use.csv" bad_use "${good}")
string(REPLACE "160,5,holdout" "160,5,maybe" bad_use_csv "${measured}")
string(REPLACE "measured.csv" "far.csv" far "${good}")
string(REPLACE "4,35,chord_angle,104" "4,35,chord_angle,400" far_csv "${measured}")
string(REPLACE "measured.csv" "burst.csv" burst "${good}")
string(REPLACE "7,11.428571428571429,critical_distance" "7,80,critical_distance" burst_csv "${measured}")
string(REPLACE "kind: vine" "kind: rod" rod "${good}")
foreach(name unknown absent outside twomagnets bad_value bad_use far burst rod)
  file(WRITE ${WORK}/${name}.yaml "${${name}}")
endforeach()
foreach(name bad_value bad_use far burst)
  file(WRITE ${WORK}/${name}.csv "${${name}_csv}")
endforeach()
foreach(case "unknown.yaml|calibrate.parameters.fill.iron: is not a parameter calibrate fits"
             "absent.yaml|robot.wall.density is not in the scene"
             "outside.yaml|lies outside [min, max]" "twomagnets.yaml|exactly one magnet"
             "bad_value.yaml|bad_value.csv:9: value: 'nan' is not a finite number"
             "bad_use.yaml|bad_use.csv:10: use: must be fit or holdout"
             "far.yaml|magnets[0].position: the approach starts at d0 = 300 mm, closer than the measurement at 400 mm"
             "burst.yaml|Ø7 mm at 80 kPa" "rod.yaml|robot")
  string(REPLACE "|" ";" parts "${case}")
  list(GET parts 0 file)
  list(GET parts 1 expect)
  expect_bad_file(calibrate ${file} "${expect}")
endforeach()
