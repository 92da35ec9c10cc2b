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
# The editable install builds into build/cpXY and never installs beamid-batch into
# the environment; a symlink in .venv/bin puts it on the PATH and follows rebuilds.
PYTAG = $(shell $(VPY) -c 'import sys; print("cp%d%d" % sys.version_info[:2])')
BATCH_LINK := $(VENV)/bin/beamid-batch
# The checking build (CI): bounds, pointer and loop checks everywhere, floating-point
# traps in the batch program (gfortran arms them only in a Fortran main program).
CHECK_DIR := build/check
CHECK_SITE := build/check-site

.PHONY: setup system-deps demo test bench clean check-build test-check

setup: system-deps $(STAMP)
	@# importing beamid rebuilds what changed (also beamid-batch); then link it
	@$(VPY) -c 'import beamid' && ln -sfn "$(CURDIR)/build/$(PYTAG)/beamid-batch" $(BATCH_LINK)

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
	$(VPY) -m pip install -q meson-python meson ninja numpy scipy f90nml matplotlib tqdm pytest hypothesis dask distributed pyuff
	$(VPY) -m pip install -q --no-build-isolation -e .
	@touch $(STAMP)

demo: setup
	$(VENV)/bin/beamid demo --out out

# The Fortran kernel tests (tests/fortran, `meson test`) in the build dir of the
# editable install, then pytest.
test: setup
	PATH="$(CURDIR)/$(VENV)/bin:$$PATH" $(VENV)/bin/meson test -C build/$(PYTAG) -q --print-errorlogs
	$(VPY) -m pytest -q tests

bench: setup
	@for b in benchmarks/bench_*.py; do echo "== $$b"; $(VPY) $$b || exit 1; done

# The checking build: a second meson build dir of the same sources with -Dcheck=true,
# and a package overlay (the Python sources plus that build's extension) that the
# test run puts first on the path; `python -S` keeps the editable install's import
# hook (a .pth file) from loading the normal build instead.
check-build: setup
	@if [ ! -f $(CHECK_DIR)/build.ninja ]; then \
	  mkdir -p build && printf "[binaries]\npython = '%s'\n" "$(CURDIR)/$(VPY)" > build/check-native.ini && \
	  PATH="$(CURDIR)/$(VENV)/bin:$$PATH" $(VENV)/bin/meson setup $(CHECK_DIR) -Dcheck=true \
	    --native-file build/check-native.ini; fi
	PATH="$(CURDIR)/$(VENV)/bin:$$PATH" $(VENV)/bin/ninja -C $(CHECK_DIR)
	rm -rf $(CHECK_SITE) && mkdir -p $(CHECK_SITE)/beamid
	ln -s "$(CURDIR)"/pyfront/beamid/*.py $(CHECK_SITE)/beamid/
	ln -s "$(CURDIR)"/$(CHECK_DIR)/_ext.*.so $(CHECK_SITE)/beamid/

# The Fortran kernel tests and the tests that go through Fortran, against the
# checking build (floating-point traps armed in the Fortran test programs too);
# the API fuzz (tests/test_fuzz_api.py) with its long profile.
test-check: check-build
	PATH="$(CURDIR)/$(VENV)/bin:$$PATH" $(VENV)/bin/meson test -C $(CHECK_DIR) -q --print-errorlogs
	PATH="$(CURDIR)/$(CHECK_DIR):$$PATH" BEAMID_BATCH="$(CURDIR)/$(CHECK_DIR)/beamid-batch" \
	  BEAMID_FUZZ_PROFILE=long \
	  PYTHONPATH="$(CURDIR)/$(CHECK_SITE):$$($(VPY) -c 'import sysconfig; print(sysconfig.get_path("purelib"))')" \
	  $(VPY) -S -m pytest -q -p no:cacheprovider tests

clean:
	rm -rf build out $(VENV)
