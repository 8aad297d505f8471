# Two commands on a fresh machine (Debian/Ubuntu, Python 3.11 or 3.12, no ROS install):
#   make demo   - set up .venv, then watch the simulated TurtleBot lap the course
#   make test   - set up .venv, then run the whole test suite (what CI runs)
#   make scorecard - score the follower and the book's controller on every built-in course
#   make benchmark - perception time, camera-to-cmd_vel latency and simulator speed, measured
# Set-up is done once and redone only when a requirements file or setup.py changes.

PYTHON ?= python3
VENV ?= .venv
DEMO_ARGS ?= --duration 240 --pictures-dir pictures
STAMP := $(VENV)/.followbot-installed
# Debian's Mesa EGL stack: MuJoCo renders off-screen with it, on the CPU, without a display.
# (The tests also use libxml2-utils' xmllint, the tool ament_xmllint runs.)
MESA_EGL_PACKAGES := libegl1 libegl-mesa0 libgl1-mesa-dri libgles2
LDCONFIG := $(shell command -v ldconfig || echo /sbin/ldconfig)

.PHONY: demo test scorecard benchmark setup system-deps clean

demo: $(STAMP)
	$(VENV)/bin/followbot $(DEMO_ARGS)

test: $(STAMP)
	$(VENV)/bin/python -m pytest -q test

scorecard: $(STAMP)
	$(VENV)/bin/scorecard

benchmark: $(STAMP)
	$(VENV)/bin/benchmark

setup: $(STAMP)

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
	if [ -n "$$missing" ]; then \
		SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
		echo "Installing Debian packages:$$missing"; \
		$$SUDO apt-get update -qq && \
		DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing; \
	else \
		echo 'Mesa EGL, Python venv and xmllint present.'; \
	fi

$(STAMP): requirements.txt requirements-test.txt setup.py | system-deps
	$(PYTHON) -m venv $(VENV)
	$(VENV)/bin/python -m pip install -q --upgrade pip
	$(VENV)/bin/python -m pip install -q -r requirements-test.txt
	# Editable, so the models are found in this checkout and edits take effect at once.
	$(VENV)/bin/python -m pip install -q --no-deps -e .
	touch $@

clean:
	rm -rf $(VENV) pictures build install log *.egg-info
