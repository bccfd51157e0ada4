# Entry points of the repository. Everything goes through scripts/setup.sh (the one set-up path).
SHELL := /bin/bash
ROOT := $(abspath $(dir $(lastword $(MAKEFILE_LIST))))
VENV := $(ROOT)/.venv

# Extra arguments for pytest, e.g. `make test PYTEST_ARGS="-k valve -x"`.
PYTEST_ARGS ?=

# Keep DDS discovery on this machine unless the caller says otherwise.
ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST
export ROS_AUTOMATIC_DISCOVERY_RANGE

.PHONY: setup test demo clean

setup:
	@bash "$(ROOT)/scripts/setup.sh"

# Runs every package's test/ folder (testpaths = */test in pytest.ini). pytest's exit code 5
# (no test collected) is non-zero, so it fails the target like any other failure.
test: setup
	cd "$(ROOT)" && AMENT_PREFIX_PATH="$(VENV)" PATH="$(VENV)/bin:$$PATH" \
		"$(VENV)/bin/python" -m pytest $(PYTEST_ARGS)

demo: setup
	cd "$(ROOT)" && AMENT_PREFIX_PATH="$(VENV)" PATH="$(VENV)/bin:$$PATH" \
		bash "$(ROOT)/scripts/demo.sh"

clean:
	rm -rf "$(ROOT)/build" "$(VENV)"
