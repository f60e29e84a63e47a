# Shared by the end-to-end CLI tests (included with -P scripts): a fresh work folder and exit-code checks.
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK})

function(expect_rc rc expected what)
  if(NOT rc EQUAL expected)
    message(FATAL_ERROR "${what}: exit code ${rc}, expected ${expected}")
  endif()
endfunction()
