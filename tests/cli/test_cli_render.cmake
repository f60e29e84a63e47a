# End-to-end test of the render verbs (issue 7, render module only): `magvine render` on a generated tube (the
# endoscope's image and depth, the overview), its bad inputs (exit 2, one line, nothing written), and a short run
# with a tip video and PNG frames drawn into a strip by tools/plot_frames.py.
# Run by CTest with -DMAGVINE=... -DWORK=... -DSRC=... -DPYTHON=...
include(${CMAKE_CURRENT_LIST_DIR}/cli_common.cmake)

execute_process(COMMAND ${MAGVINE} phantom tube --out ${WORK}/tube.stl RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "phantom tube: ${err}")

# 0. The render module is a plugin (docs/rendering.md): the executable itself loads no OpenCV library (ldd lists
#    every library the dynamic loader maps at start, direct or not); the plugin does.
execute_process(COMMAND ldd ${MAGVINE} OUTPUT_VARIABLE libs RESULT_VARIABLE rc)
expect_rc(${rc} 0 "ldd magvine")
if(libs MATCHES "libopencv")
  message(FATAL_ERROR "magvine loads OpenCV at start:\n${libs}")
endif()
get_filename_component(bin ${MAGVINE} DIRECTORY)
execute_process(COMMAND ldd ${bin}/libmagvine_video.so OUTPUT_VARIABLE plugin_libs RESULT_VARIABLE rc)
expect_rc(${rc} 0 "ldd libmagvine_video.so")
if(NOT plugin_libs MATCHES "libopencv_videoio")
  message(FATAL_ERROR "the video plugin does not link OpenCV's video writer:\n${plugin_libs}")
endif()

# 1. The endoscope inside the tube (Ø12 mm along +x, 120 mm long): every ray hits the wall; the 16-bit depth map
#    holds the far end cap at 110 mm ahead, beyond the 100 mm range, so the centre reads 65535 (clamped).
execute_process(COMMAND ${MAGVINE} render ${WORK}/tube.stl --eye 10,0,0 --look 50,0,0 --out ${WORK}/view.png
                        --depth ${WORK}/depth.png RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "render endoscope: ${err}")
string(FIND "${err}" "100 % of the rays hit the wall" pos)
if(pos EQUAL -1)
  message(FATAL_ERROR "render from inside the tube: want every ray on the wall, got '${err}'")
endif()
execute_process(COMMAND ${PYTHON} -c "
import struct, zlib
def png(path):
    data = open(path, 'rb').read()
    assert data[:8] == b'\\x89PNG\\r\\n\\x1a\\n', path
    w, h, depth, colour = struct.unpack('>IIBB', data[16:26])
    return w, h, depth, colour
assert png('${WORK}/view.png') == (320, 320, 8, 2), png('${WORK}/view.png')
assert png('${WORK}/depth.png') == (320, 320, 16, 0), png('${WORK}/depth.png')
" RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "render outputs: ${err}")
execute_process(COMMAND ${MAGVINE} render ${WORK}/tube.stl --eye 60,-150,0 --look 60,0,0 --view overview
                        --out ${WORK}/overview.png RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "render overview: ${err}")
if(NOT EXISTS ${WORK}/overview.png)
  message(FATAL_ERROR "render --view overview wrote no PNG")
endif()

# 2. Bad inputs: exit 2, one line naming the option, nothing written.
foreach(bad "--look;10,0,0;the viewing direction is zero"
            "--out;${WORK}/bad.jpg;is not a .png path"
            "--fov;400;field of view"
            "--size;8,8;between 16 and 8192")
  list(GET bad 0 option)
  list(GET bad 1 value)
  list(GET bad 2 message)
  set(args ${WORK}/tube.stl --eye 10,0,0 --look 50,0,0 --out ${WORK}/bad.png)
  if(option STREQUAL "--look")
    set(args ${WORK}/tube.stl --eye 10,0,0 --look ${value} --out ${WORK}/bad.png)
  elseif(option STREQUAL "--out")
    set(args ${WORK}/tube.stl --eye 10,0,0 --look 50,0,0 --out ${value})
  else()
    list(APPEND args ${option} ${value})
  endif()
  execute_process(COMMAND ${MAGVINE} render ${args} RESULT_VARIABLE rc ERROR_VARIABLE err)
  expect_rc(${rc} 2 "render ${option} ${value}: ${err}")
  string(FIND "${err}" "${message}" pos)
  string(REGEX MATCHALL "\n" lines "${err}")
  list(LENGTH lines n)
  if(pos EQUAL -1 OR NOT n EQUAL 1 OR EXISTS ${WORK}/bad.png OR EXISTS ${WORK}/bad.jpg)
    message(FATAL_ERROR "render ${option} ${value}: want one line with '${message}' and no file, got '${err}'")
  endif()
endforeach()

# 3. A 0.4 s run of the Y-bifurcation scene with a 64 × 64 tip video and its frames; then a strip of two frames.
file(READ ${SRC}/assets/scenes/y_bifurcation_fluid_vine.yaml scene)
string(REPLACE "duration: 8," "duration: 0.4," scene "${scene}")
string(APPEND scene "outputs: {video: {camera: tip, size: [64, 64], fps: 10, frames: true}}\n")
file(WRITE ${WORK}/filmed.yaml "${scene}")
execute_process(COMMAND ${MAGVINE} run ${WORK}/filmed.yaml --out ${WORK}/filmed RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "run with a video: ${err}")
foreach(f tip.mp4 tip_frames/000000.png tip_frames/000004.png)
  if(NOT EXISTS ${WORK}/filmed/${f})
    message(FATAL_ERROR "run with a video wrote no ${f}")
  endif()
endforeach()
execute_process(COMMAND ${PYTHON} ${SRC}/tools/plot_frames.py ${WORK}/filmed --camera tip --frames 0,4
                        --out ${WORK}/strip.png RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "plot_frames: ${err}")
execute_process(COMMAND ${PYTHON} ${SRC}/tools/plot_frames.py ${WORK}/filmed --camera tip --frames 0,99
                        --out ${WORK}/strip_bad.png RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 2 "plot_frames with a missing frame: ${err}")
if(NOT EXISTS ${WORK}/strip.png OR EXISTS ${WORK}/strip_bad.png)
  message(FATAL_ERROR "plot_frames: want strip.png and no strip_bad.png")
endif()

# 3b. A 2 s camera-guided run (the bundled scene cut short): guidance.csv with a row per 0.1 s placement, annotated
#     frames where it saw several lumens, metrics.json's guidance entry; drawn by tools/plot_guidance.py, whose bad
#     input is refused with exit 2 and no PNG.
file(READ ${SRC}/assets/scenes/bronchial_tree_camera_navigator.yaml scene)
string(REPLACE "duration: 20," "duration: 2," scene "${scene}")
string(REGEX REPLACE "outputs:.*" "" scene "${scene}")
file(WRITE ${WORK}/guided.yaml "${scene}")
execute_process(COMMAND ${MAGVINE} run ${WORK}/guided.yaml --out ${WORK}/guided RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "camera-guided run: ${err}")
file(STRINGS ${WORK}/guided/guidance.csv rows)
list(LENGTH rows n)
if(NOT n EQUAL 21)
  message(FATAL_ERROR "guidance.csv: want a header and 20 placements, got ${n} lines")
endif()
file(READ ${WORK}/guided/metrics.json metrics)
string(JSON placements GET "${metrics}" guidance placements)
if(NOT placements EQUAL 20)
  message(FATAL_ERROR "metrics.json guidance.placements: want 20, got ${placements}")
endif()
execute_process(COMMAND ${PYTHON} ${SRC}/tools/plot_guidance.py ${WORK}/guided --out ${WORK}/guided.png
                RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "plot_guidance: ${err}")
execute_process(COMMAND ${PYTHON} ${SRC}/tools/plot_guidance.py ${WORK}/filmed --out ${WORK}/guided_bad.png
                RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 2 "plot_guidance without guidance.csv: ${err}")
if(NOT EXISTS ${WORK}/guided.png OR EXISTS ${WORK}/guided_bad.png)
  message(FATAL_ERROR "plot_guidance: want guided.png and no guided_bad.png")
endif()

# 4. `magvine mesh graph --png`: the extracted graph drawn over the mesh.
execute_process(COMMAND ${MAGVINE} mesh graph ${WORK}/tube.stl --out ${WORK}/tube_graph.json --png ${WORK}/tube_graph.png
                RESULT_VARIABLE rc ERROR_VARIABLE err)
expect_rc(${rc} 0 "mesh graph --png: ${err}")
if(NOT EXISTS ${WORK}/tube_graph.png OR NOT EXISTS ${WORK}/tube_graph.json)
  message(FATAL_ERROR "mesh graph --png wrote no picture or no graph")
endif()
