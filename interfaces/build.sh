#!/usr/bin/env bash
# Build and install the contextros_interfaces rosidl package into a venv that holds the
# pip ROS 2 wheels (the `ros` and `ros-build` extras), with plain cmake + ninja or make
# (~15 s).
# Usage: bash interfaces/build.sh /absolute/path/to/venv
# Idempotent: re-running rebuilds only what changed. Fails loudly on any error.
set -euo pipefail

if [[ $# -ne 1 || "$1" != /* ]]; then
  echo "usage: $0 /absolute/path/to/venv" >&2
  exit 2
fi
venv="$1"
python="$venv/bin/python"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
source_dir="$here/contextros_interfaces"
build_dir="$here/build/contextros_interfaces"

[[ -x "$python" ]] || { echo "error: no python at $python (create the venv first: make venv)" >&2; exit 1; }
for tool in cmake cc; do
  command -v "$tool" >/dev/null || { echo "error: '$tool' not found; install cmake and a C compiler" >&2; exit 1; }
done
# Ninja when there is one, else make; a build dir keeps the generator it was made with.
if [[ -f "$build_dir/CMakeCache.txt" ]]; then
  generator="$(sed -n 's/^CMAKE_GENERATOR:INTERNAL=//p' "$build_dir/CMakeCache.txt")"
elif command -v ninja >/dev/null; then
  generator="Ninja"
elif command -v make >/dev/null; then
  generator="Unix Makefiles"
else
  echo "error: neither ninja nor make found; install one of them" >&2
  exit 1
fi
"$python" -c "import rosidl_adapter" 2>/dev/null \
  || { echo "error: the ROS build wheels are missing in $venv (pip install -e '.[ros,ros-build]')" >&2; exit 1; }

# A user's other ROS environment must not leak into this build or into the generated code.
unset RMW_IMPLEMENTATION AMENT_PREFIX_PATH COLCON_PREFIX_PATH CMAKE_PREFIX_PATH
export AMENT_PREFIX_PATH="$venv"
export PATH="$venv/bin:$PATH"

cmake -S "$source_dir" -B "$build_dir" -G "$generator" \
  -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$venv" \
  -DCMAKE_INSTALL_PREFIX="$venv" \
  -DPython3_EXECUTABLE="$python" \
  -DPython3_FIND_VIRTUALENV=ONLY \
  -DBUILD_TESTING=OFF \
  -DCMAKE_PROJECT_INCLUDE="$here/cmake/fix_rosidl_generator_py_includes.cmake"
cmake --build "$build_dir" --parallel
cmake --install "$build_dir"

# Prove the result works through the wheels' own bootstrap (fresh interpreter, no env leak).
env -u _ROS_WHEELS_BOOTSTRAP_COMPLETE -u LD_LIBRARY_PATH "$python" -c \
  "from contextros_interfaces.msg import LayerState; from contextros_interfaces.srv import Activate; LayerState(epoch=1); Activate.Request()" \
  || { echo "error: contextros_interfaces was installed but does not import" >&2; exit 1; }
echo "contextros_interfaces installed into $venv"
