# Entry points of the repository. Everything goes through scripts/setup.sh (the one set-up path).
SHELL := /bin/bash
ROOT := $(abspath $(dir $(lastword $(MAKEFILE_LIST))))
VENV := $(ROOT)/.venv

# Extra arguments for pytest, e.g. `make test PYTEST_ARGS="-k valve -x"`, and for colcon's package
# selection, e.g. `make test COLCON_ARGS="--packages-select pam_model"`.
PYTEST_ARGS ?=
COLCON_ARGS ?=

# Keep DDS discovery on this machine unless the caller says otherwise.
ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST
export ROS_AUTOMATIC_DISCOVERY_RANGE

.PHONY: setup test test-unit test-venv demo clean

setup:
	@bash "$(ROOT)/scripts/setup.sh"

# Every package's tests as an apt ROS user runs them: colcon build of a workspace over this
# checkout (build/colcon_ws), then colcon test with pytest, one package at a time, and the
# colcon test-result summary (scripts/colcon_check.sh). Fails on any failure, or if a package
# ran no test.
test: setup firmware-test
	cd "$(ROOT)" && bash "$(ROOT)/scripts/colcon_check.sh" $(COLCON_ARGS) -- $(PYTEST_ARGS)

# The reference DAQ board (pam_driver/firmware): the core's unit tests with the host gcc, the
# ATmega2560 ELF with avr-gcc, its tests on simavr (the board alone, then driver_node, the board's
# faults and the closed loop against pam-emulator), then the figures measured there. Needs
# gcc-avr binutils-avr avr-libc simavr libsimavr-dev libsimavrparts1 (.ci/run installs them).
FIRMWARE_TESTS := pam_driver/test/test_firmware_board.py pam_bringup/test/test_firmware_driver.py
firmware-test: setup
	@command -v avr-gcc >/dev/null && test -e /usr/include/simavr/sim_avr.h || { echo \
		"firmware-test: needs the AVR toolchain and simavr: apt-get install -y" \
		"--no-install-recommends gcc-avr binutils-avr avr-libc simavr libsimavr-dev" \
		"libsimavrparts1"; exit 1; }
	@start=$$(date +%s); \
	$(MAKE) -s -C "$(ROOT)/pam_driver/firmware" all unit harness && \
	rm -f "$(ROOT)/pam_driver/firmware/build/figures.json" && \
	cd "$(ROOT)" && PAM_FIRMWARE_TEST=1 AMENT_PREFIX_PATH="$(VENV)" PATH="$(VENV)/bin:$$PATH" \
		"$(VENV)/bin/python" -m pytest -q -p no:cacheprovider $(FIRMWARE_TESTS) && \
	"$(VENV)/bin/python" "$(ROOT)/pam_driver/firmware/tools/figures.py" && \
	echo "firmware-test: $$(( $$(date +%s) - start )) s"

# The same tests in one pytest session against the venv's installed packages (testpaths = */test
# in pytest.ini): no colcon build, for quick runs while developing. pytest's exit code 5 (no test
# collected) fails it like any other failure.
test-venv: setup
	cd "$(ROOT)" && AMENT_PREFIX_PATH="$(VENV)" PATH="$(VENV)/bin:$$PATH" \
		"$(VENV)/bin/python" -m pytest $(PYTEST_ARGS)

# The ROS-free tests only (marker `unit`, given by conftest.py from what a test module uses):
# the cores, the physics, the filters, in one process, no DDS. `process` and `system` select the
# others (`make test-venv PYTEST_ARGS="-m process"`).
test-unit: setup
	cd "$(ROOT)" && AMENT_PREFIX_PATH="$(VENV)" PATH="$(VENV)/bin:$$PATH" \
		"$(VENV)/bin/python" -m pytest -m unit $(PYTEST_ARGS)

# The main job: pam-demo (pam_bringup). `DURATION=30 make demo` records 30 s instead of 64.
demo: setup
	cd "$(ROOT)" && AMENT_PREFIX_PATH="$(VENV)" PATH="$(VENV)/bin:$$PATH" \
		pam-demo $${DURATION:+--duration "$$DURATION"}

clean:
	rm -rf "$(ROOT)/build" "$(VENV)"
