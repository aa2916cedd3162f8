# Generates the GL 4.5 core loader with python3-glad at configure time.
# Nothing is downloaded (--reproducible uses the spec bundled with glad).
# Each context backend hands glad its own get-proc-address (gladLoadGL).
find_program(GLAD_EXECUTABLE glad REQUIRED)
set(GLAD_OUT ${CMAKE_BINARY_DIR}/glad)
if(NOT EXISTS ${GLAD_OUT}/src/gl.c)
  message(STATUS "Generating GL loader with ${GLAD_EXECUTABLE}")
  execute_process(
    COMMAND ${GLAD_EXECUTABLE} --api gl:core=4.5 --extensions GL_KHR_debug
            --out-path ${GLAD_OUT} --reproducible --quiet c
    RESULT_VARIABLE glad_result OUTPUT_QUIET ERROR_VARIABLE glad_err)
  if(NOT glad_result EQUAL 0)
    message(FATAL_ERROR "glad failed: ${glad_err}")
  endif()
endif()
add_library(glad_gl STATIC ${GLAD_OUT}/src/gl.c)
target_include_directories(glad_gl SYSTEM PUBLIC ${GLAD_OUT}/include)
set_target_properties(glad_gl PROPERTIES POSITION_INDEPENDENT_CODE ON)
