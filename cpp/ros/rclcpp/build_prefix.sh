#!/usr/bin/env bash
# Builds rclcpp, rclcpp_lifecycle and rclcpp_components (29.3.0, with the packages they need
# that have no wheel) from the unmodified sources of a tarball, against the ROS 2 wheels of
# a venv, into <work dir>/prefix. Their sources are unpacked at build time, never kept in
# this repository; the only adaptation is wheels_project_include.cmake (which reuses
# cmake/ContextrosRosWheels.cmake). `make test-rclcpp` runs it; what it does and how long it
# takes: docs/cpp.md ("Run here: rclcpp built from source against the wheels").
# usage: build_prefix.sh <tarball> <venv> <work dir>
# Needs cmake >= 3.21, ninja, g++ and Debian's libconsole-bridge-dev (class_loader).
set -euo pipefail
tarball=$(realpath "$1"); venv=$(realpath "$2"); work=$3
here=$(cd "$(dirname "$0")" && pwd)
fix=$here/wheels_project_include.cmake
repairs=$here/../../cmake/ContextrosRosWheels.cmake   # included by $fix
mkdir -p "$work"; work=$(realpath "$work")
prefix=$work/prefix
if [[ -e $prefix/.complete && $prefix/.complete -nt $tarball && $prefix/.complete -nt $fix &&
      $prefix/.complete -nt $repairs ]]; then
  exit 0
fi
if [[ ! -e /usr/include/console_bridge/console.h ]]; then
  echo "build_prefix.sh: class_loader needs console_bridge: apt-get install libconsole-bridge-dev" >&2
  exit 1
fi
rm -rf "$work/src" "$prefix"
mkdir -p "$work/src"
tar xzf "$tarball" -C "$work/src" --strip-components=1
src=$work/src
export AMENT_PREFIX_PATH=$prefix:$venv
unset RMW_IMPLEMENTATION

build() {  # build <name> <source dir>
  local started=$SECONDS log=$work/log-$1.txt
  {
    nice -n 10 cmake -S "$2" -B "$work/build/$1" -G Ninja -DCMAKE_BUILD_TYPE=Release \
      -DCMAKE_INSTALL_PREFIX="$prefix" "-DCMAKE_PREFIX_PATH=$prefix;$venv" \
      -DPython3_EXECUTABLE="$venv/bin/python" -DPython3_FIND_VIRTUALENV=ONLY \
      -DCONTEXTROS_ROS_WHEELS="$venv" -DCMAKE_PROJECT_INCLUDE="$fix" -DBUILD_TESTING=OFF
    nice -n 10 cmake --build "$work/build/$1" -j2
    cmake --install "$work/build/$1"
  } >"$log" 2>&1 || { tail -n 30 "$log" >&2; echo "build_prefix.sh: $1 failed (log: $log)" >&2; exit 1; }
  echo "  $1: $((SECONDS - started)) s"
}
echo "rclcpp 29.3.0 into $prefix (against $venv)"
build statistics_msgs $src/rcl_interfaces/statistics_msgs
build libstatistics_collector $src/libstatistics_collector
build rclcpp $src/rclcpp/rclcpp
build rclcpp_lifecycle $src/rclcpp/rclcpp_lifecycle
build console_bridge_vendor $src/console_bridge_vendor
build class_loader $src/class_loader
build composition_interfaces $src/rcl_interfaces/composition_interfaces
build rclcpp_components $src/rclcpp/rclcpp_components
echo "  total: $SECONDS s"
touch "$prefix/.complete"
