#!/usr/bin/env bash
# The two commands of README.md. Each installs what it needs (Debian packages), builds, and then
#   ./build.sh run  [SCENE.yaml]  builds the Release program (build/) and the Python module
#                                 (build/python/), and runs a scene (default:
#                                 inputs/default.yaml, the main job) into results/<scene>.h5;
#   ./build.sh test [--quick]     builds the GoogleTest suite with AddressSanitizer + UBSan
#                                 (build-asan/, optimised: -O1 -g1) and runs it (ctest), then runs
#                                 each fuzz target for FUZZ_SECONDS (default 30) on its seed
#                                 corpus (build-fuzz/, clang + libFuzzer). CI runs this command.
#                                 --quick: the suite of the Release build (build/) only.
# (The suite is built once per command: building it twice, Release and sanitized, would take CI
# past its 45 minutes on 2 cores.)
set -euo pipefail
cd "$(dirname "$0")"

packages=(cmake g++ make libeigen3-dev libhdf5-dev hdf5-tools libyaml-cpp-dev libcli11-dev
          libgtest-dev libxsimd-dev  # SIMD batches of slip systems in the grain solver
          libopenmpi-dev openmpi-bin  # MPI over grains (mpirun -np N subslip run)
          libhdf5-openmpi-dev  # ranks writing one result file together (parallel HDF5)
          python3-h5py python3-matplotlib python3-numpy  # scripts/subslip_plots.py and its test
          python3-dev pybind11-dev python3-yaml  # the Python module subslip._core (docs/python.md)
          libceres-dev)  # sensitivities (Jet) and the bounded least squares of `subslip fit`
# The tests of `test` include a Fortran driver of the FE library's UMAT (tests/fe/umat_driver.f90).
# and an offline pip install of the Python package (tests/python/test_bindings.py).
if [ "${1:-}" = test ]; then
  packages+=(gfortran python3-pip python3-setuptools python3-wheel)
fi
# The sanitizer and fuzz stages of `test` build the fuzz targets with clang (libFuzzer, OpenMP).
if [ "${1:-}" = test ] && [ "${2:-}" != --quick ]; then
  packages+=(clang libclang-rt-14-dev libomp-dev)
fi
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  echo "build.sh: installing ${missing[*]}"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# The CVODE peer of the accuracy study (libsundials-dev pulls in PETSc and MPI, ~1.4 GB) stays
# out of these builds and CI; SUBSLIP_WITH_CVODE=AUTO ./build.sh ... uses it when installed.
cvode="-DSUBSLIP_WITH_CVODE=${SUBSLIP_WITH_CVODE:-OFF}"

# The Release build of the given targets (all when none are given).
release_build() {
  cmake -S . -B build -DCMAKE_BUILD_TYPE=Release "$cvode" > /dev/null
  cmake --build build -j"$(nproc)" ${1:+--target "$@"}
}

# Prints how long a stage took (CI must stay under 45 minutes on 2 cores).
stage_done() {
  echo "build.sh: $1 took $((SECONDS - $2)) s"
}

# The whole suite, built with AddressSanitizer + UBSan; any report fails the test that made it.
sanitizer_tests() {
  local start=$SECONDS
  # -g1 (line tables: enough for the reports' stack traces) compiles the Eigen-heavy kernel 20 %
  # faster than -g; -O1 (AddressSanitizer's own advice) compiles the suite in 59 % of -O2's
  # compile-seconds (docs/internals.md, "Where CI's time goes").
  cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSUBSLIP_SANITIZE=ON "$cvode" \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" > /dev/null
  cmake --build build-asan -j"$(nproc)" --target subslip_test_programs  # not the benchmarks
  ASAN_OPTIONS=halt_on_error=1:detect_leaks=1:strict_string_checks=1 \
    UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
    ctest --test-dir build-asan --output-on-failure -j"$(nproc)"
  stage_done "sanitizer build and tests" "$start"
}

# Runs fuzz target $1 for FUZZ_SECONDS on the seed directories $2...; new inputs it finds go to
# build-fuzz/corpus/$1, a crashing input to build-fuzz/artifacts/.
run_fuzzer() {
  local name=$1 max_len=$2
  shift 2
  local log=build-fuzz/$name.log
  mkdir -p "build-fuzz/corpus/$name" build-fuzz/artifacts
  if ! "build-fuzz/fuzz/$name" -max_total_time="${FUZZ_SECONDS:-30}" -timeout=10 \
      -rss_limit_mb=2048 -max_len="$max_len" -dict="fuzz/${name%_fuzzer}.dict" \
      -artifact_prefix="build-fuzz/artifacts/$name-" -print_final_stats=1 \
      "build-fuzz/corpus/$name" "$@" > "$log" 2>&1; then
    tail -n 60 "$log"
    echo "build.sh: $name found a problem (input in build-fuzz/artifacts/, log in $log)" >&2
    exit 1
  fi
  echo "build.sh: $name: $(grep -E '^stat::number_of_executed_units' "$log" | awk '{print $2}') inputs, no findings"
}

fuzz_tests() {
  local start=$SECONDS
  CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DSUBSLIP_FUZZ=ON -DSUBSLIP_BUILD_TESTS=OFF -DSUBSLIP_WITH_CVODE=OFF -DSUBSLIP_WITH_MPI=OFF \
    > /dev/null
  cmake --build build-fuzz -j"$(nproc)" --target scene_fuzzer orientation_fuzzer
  # libFuzzer runs one process: the two targets run side by side, one per core.
  run_fuzzer scene_fuzzer 8192 fuzz/seeds/scene inputs tests/data/scenes tests/data/crystal_scenes \
    tests/data/bad &
  local scene_pid=$!
  run_fuzzer orientation_fuzzer 2048 tests/data/orientations orientations &
  local orientation_pid=$!
  local failed=0
  wait "$scene_pid" || failed=1
  wait "$orientation_pid" || failed=1
  ((failed == 0)) || exit 1
  stage_done "fuzz build and runs" "$start"
}

case "${1:-}" in
  run)
    # The program and the Python module (subslip.run, the material points): neither the tests
    # nor the benchmarks.
    release_build subslip subslip_python
    scene="${2:-inputs/default.yaml}"
    out="results/$(basename "${scene%.*}").h5"
    # --force: this command is documented to refresh results/<scene>.h5 each time it is run.
    build/src/subslip run "$scene" -o "$out" --force
    ;;
  test)
    if [ "${2:-}" = --quick ]; then
      start=$SECONDS
      release_build
      ctest --test-dir build --output-on-failure -j"$(nproc)"
      stage_done "Release build and tests" "$start"
    else
      sanitizer_tests
      fuzz_tests
    fi
    ;;
  *)
    echo "usage: ./build.sh run [SCENE.yaml] | ./build.sh test [--quick]" >&2
    exit 2
    ;;
esac
