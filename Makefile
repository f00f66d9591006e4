# One obvious way to run things. Every target does its own set-up on first use.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
# Isolation for anything that starts ROS 2 nodes from make (tests set their own per worker).
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST
unexport RMW_IMPLEMENTATION

.PHONY: all venv ros demo test test-core bench lint clean

all: test

# The package, its dev tools and the ROS 2 wheels, in an editable install.
$(VENV)/.stamp-base: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev,ros,ros-build]'
	touch $@

# The rosidl interface package, built against the wheels into the venv prefix.
$(VENV)/.stamp-interfaces: $(VENV)/.stamp-base $(shell find interfaces/contextros_interfaces interfaces/cmake -type f) interfaces/build.sh
	bash interfaces/build.sh $(abspath $(VENV))
	touch $@

venv: $(VENV)/.stamp-base
ros: $(VENV)/.stamp-interfaces

demo: ros
	$(PY) -m examples.demo

test: ros
	$(PY) -m pytest -n 2 -q

# The ROS-free part only (fast inner loop).
test-core: venv
	$(PY) -m pytest -q -m "not ros"

$(VENV)/.stamp-bench: $(VENV)/.stamp-base
	$(PY) -m pip install --quiet -e '.[bench]'
	touch $@

bench: ros $(VENV)/.stamp-bench
	$(PY) -m benchmarks

lint: venv
	$(VENV)/bin/ruff check src tests benchmarks examples
	$(VENV)/bin/ruff format --check src tests benchmarks examples
	$(VENV)/bin/mypy

clean:
	rm -rf $(VENV) build src/*.egg-info .pytest_cache .mypy_cache .ruff_cache
