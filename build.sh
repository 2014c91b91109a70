#!/usr/bin/env bash
# The two commands of README.md. Each installs what it needs (Debian packages), builds, and then
#   ./build.sh run  [SCENE.yaml]  runs a scene (default: inputs/default.yaml, the main job) into
#                                 results/<scene>.h5 and prints its summary;
#   ./build.sh test               runs every test (ctest).
set -euo pipefail
cd "$(dirname "$0")"

packages=(cmake g++ make libeigen3-dev libhdf5-dev hdf5-tools libyaml-cpp-dev libcli11-dev
          libgtest-dev)
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

cmake -S . -B build -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build build -j"$(nproc)"

case "${1:-}" in
  run)
    scene="${2:-inputs/default.yaml}"
    out="results/$(basename "${scene%.*}").h5"
    # --force: this command is documented to refresh results/<scene>.h5 each time it is run.
    build/src/subslip run "$scene" -o "$out" --force
    ;;
  test)
    ctest --test-dir build --output-on-failure -j"$(nproc)"
    ;;
  *)
    echo "usage: ./build.sh run [SCENE.yaml] | ./build.sh test" >&2
    exit 2
    ;;
esac
