# Read by ctest after the tests gtest_discover_tests found (tests/CMakeLists.txt).
# The MPI tests (test_mpi.cpp) run alone, none beside them.
foreach(test IN LISTS subslip_tests_TESTS)
  if(test MATCHES "^Mpi\\.")
    set_tests_properties(${test} PROPERTIES RUN_SERIAL TRUE)
  endif()
endforeach()
# The slowest tests start first. ctest starts tests in descending COST, and a fresh build has no
# timings of its own: one of these started late runs on alone while the other core idles. The
# costs are their seconds in the sanitizer build (CI, 2 cores); only their order matters.
set(slow_tests
    "AccuracyCrystal.PressureSensitiveSwitchStepsFollowTheTolerance\;224"
    "CrystalFit.RecoversTheCrssAndTheHardeningFromThreeOrientations\;160"
    "AdaptiveContact.ExtrapolatedErrorFollowsTheTolerance\;72"
    "Calibration.RecoversThePaperConstantsFromFiveSpeedsWithNoise\;66"
    "CrystalTaylor.RateIndependentTaylorAggregateUnderMixedControl\;60"
    "CrystalCli.RunsTheDefaultSceneIntoATempFile\;45"
    "AccuracyCrystal.ExtrapolatedErrorFollowsTheToleranceOnEveryGrainsState\;41")
foreach(entry IN LISTS slow_tests)
  list(GET entry 0 test)
  list(GET entry 1 cost)
  list(FIND subslip_tests_TESTS ${test} found)  # (ctest reads this without CMake's policies)
  if(found GREATER -1)
    set_tests_properties(${test} PROPERTIES COST ${cost})
  endif()
endforeach()
