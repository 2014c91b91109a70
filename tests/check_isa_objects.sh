#!/bin/sh
# The objects compiled for AVX2 and AVX-512 (src/crystal/flow_point_batch_avx*.cpp, and the grain
# steps of src/crystal/grain_step_isa.hpp, each set linked into one object) must define no code
# that another object could take instead of its own: every global or weak symbol they define
# names its instruction set (the kernels' own functions, templates instantiated with xsimd's
# architecture types, the grain steps' isa_avx2:: and isa_avx512:: entry points). An inline
# function of a header compiled there with wide instructions, such as std::array's operator[],
# would be one definition among identical ones, and the linker's pick could put AVX-512 code on a
# path that runs on machines without it.
# Usage: check_isa_objects.sh "obj1;obj2" ENTRY_REGEX [COUNT] (CMake's $<TARGET_OBJECTS:...> or a
# list; ENTRY_REGEX: what each object's global functions must include, e.g. its kernels' names;
# COUNT: how many objects there must be, 2 by default).
set -eu
objects=$(printf '%s' "$1" | tr ';' ' ')
entry=$2
expected=${3:-2}
status=0
count=0
for o in $objects; do
  count=$((count + 1))
  # Code that other objects can link to: global (T), weak (W) and indirect (i) functions. (Data,
  # such as the constant tables of xsimd's sine, is the same whatever the instruction set.)
  stray=$(nm -C --defined-only "$o" | awk '$2 ~ /^[TWi]$/' | grep -v -i 'avx' || true)
  if [ -n "$stray" ]; then
    echo "$o defines symbols not tied to its instruction set:"
    echo "$stray"
    status=1
  fi
  nm -C --defined-only "$o" | grep -q -E " [TW] .*($entry)" ||
    { echo "$o: no kernel defined"; status=1; }
done
[ "$count" -eq "$expected" ] || { echo "expected $expected objects, got $count"; status=1; }
exit $status
