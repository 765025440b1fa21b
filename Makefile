# pano2cad: `make demo` and `make test` do all set-up on a fresh machine by themselves.
SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
PIP := $(VENV)/bin/pip
STAMP := $(VENV)/.pano2cad-installed
export PYOPENGL_PLATFORM ?= egl
export OMP_NUM_THREADS ?= 2

.PHONY: demo test setup sysdeps bench clean models browser

demo: setup
	$(VENV)/bin/pano2cad demo --out out/demo

test: setup browser
	$(PY) -m pytest -q panogeom detect posecrf layout apps tests

# Chromium for the report's browser test (skipped with a reason when it is absent and we are not root).
browser:
	@if ! command -v chromium >/dev/null 2>&1; then \
	  if [ "$$(id -u)" = "0" ]; then \
	    echo "installing Debian package chromium (browser test of report.html)"; \
	    (apt-get update -qq >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null) || \
	      echo "could not install chromium: the browser test will be skipped"; \
	  else \
	    echo "chromium not installed (sudo apt-get install -y chromium): the browser test will be skipped"; \
	  fi; \
	fi

setup: $(STAMP)

sysdeps:
	@if ! ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so'; then \
	  if [ "$$(id -u)" = "0" ]; then \
	    echo "installing Debian package libusb-1.0-0 (needed by open3d-cpu)"; \
	    (apt-get install -y -qq libusb-1.0-0 >/dev/null 2>&1 || \
	     (apt-get update -qq >/dev/null && apt-get install -y -qq libusb-1.0-0 >/dev/null)) || \
	     { echo "could not install libusb-1.0-0"; exit 1; }; \
	  else \
	    echo "open3d-cpu needs the Debian package libusb-1.0-0. Run: sudo apt-get install -y libusb-1.0-0"; exit 1; \
	  fi; \
	fi

$(STAMP): pyproject.toml | sysdeps
	@test -x $(PY) || python3 -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	$(PIP) install -q torch==2.13.0
	$(PIP) install -q -e '.[test]'
	@touch $(STAMP)

# The MediaPipe Objectron SSD (tflite backend), from the npm registry, checked by SHA-256.
models: setup
	$(PY) -m detect.fetch_models

bench: setup
	for b in benchmarks/bench_*.py; do $(PY) $$b || exit 1; done

clean:
	rm -rf out .pytest_cache
