# beamid: thin front over the Python/meson build. `make setup` installs what is
# missing (apt-get as root, otherwise it prints the command), creates .venv and
# builds; it is quick when nothing changed.
SHELL := /bin/bash
PY ?= python3
VENV := .venv
VPY := $(VENV)/bin/python
STAMP := $(VENV)/.beamid-installed
APT_PACKAGES := gfortran liblapack-dev pkg-config
BUILD_INPUTS := pyproject.toml Makefile

.PHONY: setup system-deps demo test bench clean

setup: system-deps $(STAMP)

system-deps:
	@missing=""; \
	command -v gfortran >/dev/null 2>&1 || missing="$$missing gfortran"; \
	command -v pkg-config >/dev/null 2>&1 || missing="$$missing pkg-config"; \
	pkg-config --exists lapack 2>/dev/null || missing="$$missing liblapack-dev"; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "installing:$$missing"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(APT_PACKAGES); \
	  else \
	    echo "beamid needs:$$missing. Install them with:"; \
	    echo "  sudo apt-get install -y $(APT_PACKAGES)"; \
	    exit 1; \
	  fi; \
	fi

$(VPY):
	$(PY) -m venv $(VENV)

$(STAMP): $(VPY) $(BUILD_INPUTS)
	$(VPY) -m pip install -q --upgrade pip
	$(VPY) -m pip install -q meson-python meson ninja numpy scipy f90nml matplotlib pytest hypothesis
	$(VPY) -m pip install -q --no-build-isolation -e .
	@touch $(STAMP)

demo: setup
	$(VENV)/bin/beamid demo --out out

test: setup
	$(VPY) -m pytest -q tests

bench: setup
	@for b in benchmarks/bench_*.py; do echo "== $$b"; $(VPY) $$b || exit 1; done

clean:
	rm -rf build out $(VENV)
