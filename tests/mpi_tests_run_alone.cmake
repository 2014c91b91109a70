# Read by ctest after the tests gtest_discover_tests found (tests/CMakeLists.txt): the MPI tests
# (test_mpi.cpp) run alone, none beside them.
foreach(test IN LISTS subslip_tests_TESTS)
  if(test MATCHES "^Mpi\\.")
    set_tests_properties(${test} PROPERTIES RUN_SERIAL TRUE)
  endif()
endforeach()
