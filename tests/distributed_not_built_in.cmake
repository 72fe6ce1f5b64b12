# In a build without MPI, `tandem render --distributed` must say that it is
# not built in and exit with status 1 (run by ctest as
# app_distributed_not_built_in).
execute_process(COMMAND ${TANDEM} render builtin:cornell --distributed
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 1)
  message(FATAL_ERROR "expected exit status 1, got ${rc}: ${out}${err}")
endif()
if(NOT err MATCHES "distributed rendering is not built in")
  message(FATAL_ERROR "expected 'not built in', got: ${err}")
endif()
