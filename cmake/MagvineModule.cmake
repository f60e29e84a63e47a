# magvine_add_module(<name> SOURCES ... [PUBLIC_DEPS ...] [PRIVATE_DEPS ...])
# One library per src/<name>, exported as magvine::<name>, public headers in src/<name>/include.
function(magvine_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor)
  if(MAGVINE_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

function(magvine_add_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(magvine_${name} STATIC ${ARG_SOURCES})
  add_library(magvine::${name} ALIAS magvine_${name})
  target_include_directories(magvine_${name} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include
                                                    ${PROJECT_BINARY_DIR}/generated)
  target_link_libraries(magvine_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  set_target_properties(magvine_${name} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  magvine_warnings(magvine_${name})
endfunction()
