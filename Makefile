# One obvious way to run things. Every target does its own set-up on first use.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
# Isolation for anything that starts ROS 2 nodes from make (tests set their own per worker).
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST
# numpy (imported by every rclpy process) starts an OpenBLAS thread per core that spins for
# a while: 0.1 s of CPU per process, and the tests, the demo and the benchmarks start many.
export OPENBLAS_NUM_THREADS ?= 1
unexport RMW_IMPLEMENTATION

.PHONY: all venv ros cpp cpp-demo demo demo-rescue test test-slow test-rclcpp test-core explore fuzz wheel bench lint clean observe dashboard print-rclcpp-sources

all: test

# The package (editable) and the ROS 2 wheels: what the demo needs. uv installs them (from
# the package index, like pip, 3x faster here); pip comes with the dev tools (tests build
# the wheel with it).
# --compile-bytecode: uv writes no .pyc by default, and where PYTHONDONTWRITEBYTECODE is set
# (as on these machines) every process then compiles rclpy and numpy again: 1.2 s of CPU
# per ROS process instead of 0.7 s (the test suite starts hundreds of them).
UV := $(VENV)/bin/uv pip install --quiet --compile-bytecode --python $(PY)
# The same for what is installed without uv (the messages) and the project's own sources
# (incremental: only what changed is compiled again).
BYTECODE := $(PY) -m compileall -q -j 0
$(VENV)/.stamp-base: pyproject.toml
	$(PYTHON) -m venv --without-pip $(VENV)
	$(PYTHON) -m pip --python $(PY) install --quiet 'uv>=0.9'
	$(UV) 'scikit-build-core>=0.11,<2' -r pyproject.toml --extra ros --extra ros-build --extra observe
	$(UV) --no-build-isolation --no-deps -e .
	touch $@

# The tools of the tests and the linters, on top.
$(VENV)/.stamp-dev: $(VENV)/.stamp-base
	$(UV) -r pyproject.toml --extra dev
	touch $@

# cmake and ninja: the machine's, else the package index's, into the venv (on PATH below).
BUILD_PATH := PATH="$(abspath $(VENV))/bin:$$PATH"
$(VENV)/.stamp-buildtools: $(VENV)/.stamp-base
	command -v cmake >/dev/null && command -v ninja >/dev/null \
	  || $(UV) 'cmake>=3.22,<5' 'ninja>=1.10'
	touch $@

# The rosidl messages, built as the wheel builds them
# (packaging/wheel, in build/wheel, which tests/install's wheel build then reuses); the
# messages are installed into the venv (C++: build/cpp, below).
WHEEL_BUILD := build/wheel
$(VENV)/.stamp-interfaces: $(VENV)/.stamp-buildtools $(shell find interfaces/contextros_interfaces interfaces/cmake packaging/wheel -type f)
	$(BUILD_PATH) cmake -S packaging/wheel -B $(WHEEL_BUILD) -G Ninja \
	  -DPython3_EXECUTABLE=$(abspath $(PY)) >/dev/null
	$(BUILD_PATH) cmake --build $(WHEEL_BUILD) --target interfaces
	cmake --install $(WHEEL_BUILD)/interfaces --prefix $(abspath $(VENV)) >/dev/null
	$(BYTECODE) $$($(PY) -c "import sysconfig; print(sysconfig.get_paths()['purelib'])")/contextros_interfaces >/dev/null
	env -u _ROS_WHEELS_BOOTSTRAP_COMPLETE -u LD_LIBRARY_PATH $(PY) -c \
	  "from contextros_interfaces.msg import LayerState; LayerState(epoch=1)"
	touch $@

# The C++ part with its tests and examples (cpp/: runtime, participant, example node, tests)
# against the wheels. Configured once; from then on ninja rebuilds what changed (and
# re-configures by itself when a CMakeLists.txt changes). `make demo` builds only its node.
CPP_BUILD := build/cpp
$(CPP_BUILD)/build.ninja: $(VENV)/.stamp-interfaces
	$(BUILD_PATH) cmake -S cpp -B $(CPP_BUILD) -G Ninja -DCONTEXTROS_ROS_WHEELS=$(abspath $(VENV))
	touch $@

cpp: $(CPP_BUILD)/build.ninja
	$(BUILD_PATH) cmake --build $(CPP_BUILD) --parallel 2

cpp-demo: $(CPP_BUILD)/build.ninja
	$(BUILD_PATH) cmake --build $(CPP_BUILD) --parallel 2 --target cleaner_localization

# The core's C dispatcher (src/contextros/core/_dispatch.c), built by the wheel's CMake tree
# and copied next to its source (the editable install uses the sources in place). A failed
# build leaves the pure-Python dispatchers in use, says so and leaves no stamp: the next make
# tries again.
$(VENV)/.stamp-dispatch: $(VENV)/.stamp-interfaces src/contextros/core/_dispatch.c
	rm -f src/contextros/core/_dispatch.*.so
	if $(BUILD_PATH) cmake --build $(WHEEL_BUILD) --target dispatch_extension \
	  && cp $(WHEEL_BUILD)/dispatch/_dispatch.*.so src/contextros/core/; then touch $@; \
	else echo "contextros: WARNING: the C dispatcher was not built; pure-Python dispatch"; fi

venv: $(VENV)/.stamp-base
ros: $(VENV)/.stamp-interfaces $(VENV)/.stamp-dispatch

demo: ros cpp-demo
	$(BYTECODE) src examples >/dev/null
	$(PY) -m examples.demo

# The rescue robot: rules, a parameter-bound layer, a lifecycle node, a namespace.
demo-rescue: ros
	$(PY) -m examples.rescue.demo

# Debian's Chromium, for the dashboard's test in a real browser (tests/observe), when the
# machine has none (a fresh CI machine has none).
BROWSER := /usr/bin/chromium
SUDO := $(if $(filter 0,$(shell id -u)),,sudo)
$(BROWSER):
	command -v apt-get >/dev/null || { echo "the dashboard's test needs Chromium at $@"; exit 1; }
	$(SUDO) env DEBIAN_FRONTEND=noninteractive apt-get update -qq
	$(SUDO) env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null

# The live page of the demos: both robots (the cleaner in /, the rescue robot in /rescue1),
# in the demos' domain ($$ROS_DOMAIN_ID, else 42, as examples/launch.py). Start it first.
dashboard: ros
	ROS_DOMAIN_ID=$${ROS_DOMAIN_ID:-42} $(VENV)/bin/contextros dashboard --namespace / /rescue1

# docs/observability.md's walkthrough: the rescue robot watched, recorded and replayed; writes
# its screenshot and plots into docs/images.
observe: ros $(VENV)/.stamp-dev $(BROWSER)
	$(PY) -m examples.rescue.observe

# tests/cpp runs the C++ tests (ctest) and checks the C++ headers; pytest's summary ends it.
# Four workers on two cores: most tests wait on real processes and the network, not the CPU
# (pytest used 1.2 cores with two workers). A worker with nothing left takes tests queued
# for a busy one (worksteal): 120-128 s against 145 s for the default split, one after
# the other on one machine. The rclcpp tests are `make test-rclcpp`'s (not collected here,
# so that nothing is reported skipped).
RCLCPP_TESTS := --ignore=tests/ros/test_rclcpp.py
test: ros cpp $(VENV)/.stamp-dev $(BROWSER)
	$(BYTECODE) src tests examples >/dev/null
	$(PY) -m pytest -n 4 --dist worksteal -q -m "not slow" $(RCLCPP_TESTS)

# What takes minutes: a colcon workspace built from scratch (CI runs it after `make test`).
test-slow: ros cpp $(VENV)/.stamp-dev
	$(BYTECODE) src tests examples >/dev/null
	$(PY) -m pytest -q -m slow $(RCLCPP_TESTS)

# rclcpp, rclcpp_lifecycle and rclcpp_components have no wheel: built from their vendored,
# unmodified sources (rclcpp 29.3.0; RCLCPP_SOURCES) into build/rclcpp/prefix, against this
# venv's wheels (cpp/ros/rclcpp/build_prefix.sh: 3 to 8 min on 2 cores, once; it needs
# Debian's libconsole-bridge-dev), or a system ROS 2's: `make test-rclcpp
# RCLCPP_PREFIX=/opt/ros/<distro>`. Then an rclcpp node, a lifecycle node and two components
# follow the manager beside a Python node (tests/ros/test_rclcpp.py; docs/cpp.md).
# The tarball lies in the workplace's shared/vendor (beside the checkout, or at /work/shared).
RCLCPP_TARBALL := vendor/rclcpp/rclcpp-29.3.0-src.tar.gz
RCLCPP_SOURCES ?= $(firstword $(wildcard ../shared/$(RCLCPP_TARBALL) /work/shared/$(RCLCPP_TARBALL)) \
  ../shared/$(RCLCPP_TARBALL))
RCLCPP_PREFIX ?=
# With a system ROS 2 (sourced, with contextros_interfaces built by colcon: docs/install.md)
# the C++ side is found as in a colcon workspace, without the wheels.
RCLCPP_BUILD := $(if $(RCLCPP_PREFIX),build/cpp-rclcpp-system,build/cpp-rclcpp)
# The CMake packages rclcpp's builds use that the other extras do not bring (some are
# undeclared dependencies of ament_cmake_ros), and rclcpp_lifecycle's.
RCLCPP_BUILD_WHEELS := ros-ament-cmake-ros==0.14.5 ros-ament-cmake-gmock==2.7.3 \
  ros-ament-cmake-gtest==2.7.3 ros-ament-cmake-pytest==2.7.3 \
  ros-ament-cmake-vendor-package==2.7.3 ros-rcl-lifecycle==10.1.3 ros-lifecycle-msgs==2.3.0
$(VENV)/.stamp-rclcpp-build: $(VENV)/.stamp-buildtools
	$(UV) $(RCLCPP_BUILD_WHEELS)
	touch $@
CONSOLE_BRIDGE := /usr/include/console_bridge/console.h
$(CONSOLE_BRIDGE):
	command -v apt-get >/dev/null || { echo "class_loader needs console_bridge (libconsole-bridge-dev)"; exit 1; }
	$(SUDO) env DEBIAN_FRONTEND=noninteractive apt-get update -qq
	$(SUDO) env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libconsole-bridge-dev >/dev/null
RCLCPP_USED_PREFIX := $(abspath $(or $(RCLCPP_PREFIX),build/rclcpp/prefix))

test-rclcpp: ros $(VENV)/.stamp-dev $(if $(RCLCPP_PREFIX),,$(VENV)/.stamp-rclcpp-build $(CONSOLE_BRIDGE))
	$(if $(RCLCPP_PREFIX),,$(BUILD_PATH) cpp/ros/rclcpp/build_prefix.sh $(RCLCPP_SOURCES) $(VENV) build/rclcpp)
	$(BUILD_PATH) cmake -S cpp -B $(RCLCPP_BUILD) -G Ninja \
	  -DCONTEXTROS_ROS_WHEELS=$(if $(RCLCPP_PREFIX),,$(abspath $(VENV))) \
	  -DCONTEXTROS_BUILD_EXAMPLES=OFF -DCONTEXTROS_RCLCPP_TESTS=ON \
	  -DCONTEXTROS_RCLCPP_PREFIX=$(RCLCPP_USED_PREFIX) >/dev/null
	$(BUILD_PATH) nice -n 10 cmake --build $(RCLCPP_BUILD) --parallel 2 --target \
	  contextros_test_rclcpp_node contextros_test_lifecycle_node contextros_test_load_component \
	  contextros_test_rclcpp_components
	CONTEXTROS_RCLCPP_BUILD=$(abspath $(RCLCPP_BUILD)) CONTEXTROS_RCLCPP_PREFIX=$(RCLCPP_USED_PREFIX) \
	  $(PY) -m pytest -q -p no:cacheprovider tests/ros/test_rclcpp.py

# Every interleaving of the pure protocol up to a larger bound than `make test` explores
# (docs/protocol.md, "Exhaustive exploration"): states explored, depth and time.
explore: $(VENV)/.stamp-dev
	$(PY) -m contextros.protocol.explorer --participants 2 --depth 6
	$(PY) -m contextros.protocol.explorer --participants 3 --depth 5

# The layer-language fuzzers on many more inputs than `make test` gives them.
fuzz: $(VENV)/.stamp-dev
	CONTEXTROS_FUZZ_EXAMPLES=5000 $(PY) -m pytest -q tests/language/test_fuzz.py \
	  tests/language/test_cpp_diagnostics.py::test_mutated_files_only_raise_the_languages_errors \
	  tests/language/test_mutation_corpus.py

# The platform wheel into dist/ (docs/install.md), from the build tree `make` keeps.
wheel: ros $(VENV)/.stamp-dev
	$(PY) -m pip wheel --quiet --no-build-isolation --no-deps --wheel-dir dist .

# The ROS-free part only (fast inner loop).
test-core: $(VENV)/.stamp-dev
	$(PY) -m pytest -q -m "not ros"

# What the sections need beyond the demo's set-up (the bench extra: ContextPy3, matplotlib,
# py-spy, playwright for the dashboard's section, which drives Debian's Chromium), so that a
# fresh clone's `make bench` does not stop at its last section. A section that fails anyway is
# reported; the others are written (python -m benchmarks --help).
$(VENV)/.stamp-bench: $(VENV)/.stamp-base pyproject.toml
	$(UV) -r pyproject.toml --extra bench
	touch $@

bench: ros cpp $(VENV)/.stamp-bench $(BROWSER)
	$(PY) -m benchmarks

lint: $(VENV)/.stamp-dev
	$(VENV)/bin/ruff check src tests benchmarks examples
	$(VENV)/bin/ruff format --check src tests benchmarks examples
	$(VENV)/bin/mypy

clean:
	rm -rf $(VENV) build dist src/*.egg-info .pytest_cache .mypy_cache .ruff_cache

# Where make test-rclcpp takes rclcpp's sources from (.ci/run asks).
print-rclcpp-sources:
	@echo $(abspath $(RCLCPP_SOURCES))
