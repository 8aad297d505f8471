# Two commands on a fresh machine (Debian/Ubuntu, Python 3.11 or 3.12, no ROS install):
#   make demo   - set up .venv, then watch the simulated TurtleBot lap the course
#   make test   - set up .venv, then run the whole test suite (what CI runs)
#   make scorecard - score the follower and the book's controller on every built-in course
#   make benchmark - perception time, camera-to-cmd_vel latency and simulator speed, measured
#   make soak      - 30 minutes of laps: both nodes' memory, open files and /dev/shm over time
# Set-up is done once and redone only when a requirements file, setup.py or config/tf2_msgs
# changes.

PYTHON ?= python3
VENV ?= .venv
DEMO_ARGS ?= --duration 240 --pictures-dir pictures
SOAK_ARGS ?= --duration 1800 --soak-period 60 --report-period 300
STAMP := $(VENV)/.followbot-installed
# tf2_msgs is not on PyPI: set-up builds our TFMessage-only stand-in (config/tf2_msgs) into the
# venv with the Jazzy rosidl generators from PyPI, cmake and the system's C/C++ compiler.
TF2_MSGS_DIR := config/tf2_msgs
TF2_MSGS_SOURCES := $(wildcard $(TF2_MSGS_DIR)/*.txt $(TF2_MSGS_DIR)/*.xml \
	$(TF2_MSGS_DIR)/msg/*.msg)
TF2_MSGS_STAMP := $(VENV)/.tf2_msgs-installed
TF2_MSGS_BUILD := $(VENV)/build/tf2_msgs
TF2_MSGS_LOG := $(VENV)/build/tf2_msgs.log
VENV_PREFIX = $(abspath $(VENV))
NPROC := $(shell nproc 2> /dev/null || echo 1)
# Debian's Mesa EGL stack: MuJoCo renders off-screen with it, on the CPU, without a display.
# (The tests also use libxml2-utils' xmllint, the tool ament_xmllint runs.)
MESA_EGL_PACKAGES := libegl1 libegl-mesa0 libgl1-mesa-dri libgles2
# rosidl's Python generator compiles an extension module: it needs Python.h.
HAS_PYTHON_HEADERS := import os, sysconfig; \
	assert os.path.isfile(os.path.join(sysconfig.get_paths()['include'], 'Python.h'))
LDCONFIG := $(shell command -v ldconfig || echo /sbin/ldconfig)

.PHONY: demo test scorecard benchmark soak setup system-deps clean

demo: $(TF2_MSGS_STAMP)
	$(VENV)/bin/followbot $(DEMO_ARGS)

test: $(TF2_MSGS_STAMP)
	$(VENV)/bin/python -m pytest -q test

scorecard: $(TF2_MSGS_STAMP)
	$(VENV)/bin/scorecard

benchmark: $(TF2_MSGS_STAMP)
	$(VENV)/bin/benchmark

soak: $(TF2_MSGS_STAMP)
	$(VENV)/bin/followbot $(SOAK_ARGS)

setup: $(TF2_MSGS_STAMP)

system-deps:
	@missing=""; \
	if ! $(LDCONFIG) -p | grep -q libEGL_mesa.so.0 || ! $(LDCONFIG) -p | grep -q libEGL.so.1; then \
		missing="$(MESA_EGL_PACKAGES)"; \
	fi; \
	if ! $(PYTHON) -c 'import ensurepip, venv' 2> /dev/null; then \
		missing="$$missing python3-venv"; \
	fi; \
	if ! command -v xmllint > /dev/null; then \
		missing="$$missing libxml2-utils"; \
	fi; \
	if ! command -v g++ > /dev/null; then \
		missing="$$missing build-essential"; \
	fi; \
	if ! $(PYTHON) -c "$(HAS_PYTHON_HEADERS)" 2> /dev/null; then \
		missing="$$missing python3-dev"; \
	fi; \
	if [ -n "$$missing" ]; then \
		SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
		echo "Installing Debian packages:$$missing"; \
		$$SUDO apt-get update -qq && \
		DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing; \
	else \
		echo 'Mesa EGL, Python venv and headers, xmllint and g++ present.'; \
	fi

$(STAMP): requirements.txt requirements-test.txt setup.py | system-deps
	$(PYTHON) -m venv $(VENV)
	$(VENV)/bin/python -m pip install -q --upgrade pip
	$(VENV)/bin/python -m pip install -q -r requirements-test.txt
	# Editable, so the models are found in this checkout and edits take effect at once.
	$(VENV)/bin/python -m pip install -q --no-deps -e .
	touch $@

$(TF2_MSGS_STAMP): $(STAMP) requirements-build.txt $(TF2_MSGS_SOURCES)
	$(VENV)/bin/python -m pip install -q -r requirements-build.txt
	@echo 'Building tf2_msgs (TFMessage) into $(VENV); the log goes to $(TF2_MSGS_LOG).'
	@rm -rf $(TF2_MSGS_BUILD) && mkdir -p $(TF2_MSGS_BUILD)
	@( $(VENV)/bin/cmake -S $(TF2_MSGS_DIR) -B $(TF2_MSGS_BUILD) -DBUILD_TESTING=OFF \
		-DCMAKE_INSTALL_PREFIX=$(VENV_PREFIX) -DCMAKE_PREFIX_PATH=$(VENV_PREFIX) \
		-DPython3_EXECUTABLE=$(VENV_PREFIX)/bin/python && \
	  $(VENV)/bin/cmake --build $(TF2_MSGS_BUILD) --parallel $(NPROC) && \
	  $(VENV)/bin/cmake --install $(TF2_MSGS_BUILD) ) > $(TF2_MSGS_LOG) 2>&1 \
		|| { tail -n 40 $(TF2_MSGS_LOG); echo 'tf2_msgs failed to build: see $(TF2_MSGS_LOG)'; exit 1; }
	$(VENV)/bin/python -c 'from tf2_msgs.msg import TFMessage'
	touch $@

clean:
	rm -rf $(VENV) pictures build install log *.egg-info
