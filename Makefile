# Two commands do everything on a fresh machine:
#   make demo   grow the default tree and write tree.glb
#   make test   lint and run the whole test suite, with the real validators
# Pictures, rendered by Blender from .venv-bpy:
#   make preview   a picture of the default tree, tree.png
#   make gallery   regenerate docs/gallery.md and docs/gallery/
# For developers:
#   make lint      ruff check and ruff format --check (make format fixes what it can)
#   make bench     every benchmark in benchmarks/ (prints ratios against baselines measured in the same run)
# The Blender add-on as an extension zip (docs/blender.md):
#   make blender-extension   build/lsys3d-blender-<version>.zip, for BLENDER_PLATFORMS (default: all four)
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# Blender's importer (the bpy wheel) needs its own Python 3.11 environment.
BPY_PYTHON ?= python3.11
BPY_VENV := .venv-bpy
BPY_STAMP := $(BPY_VENV)/.installed
BPY_VERSION := 5.0.1
# usd-core's ARKit profile (UsdUtils.ComplianceChecker, last shipped in usd-core 25.x) in its own environment.
USDCHECK_VENV := .venv-usdchecker
USDCHECK_STAMP := $(USDCHECK_VENV)/.installed
USDCHECK_VERSION := 25.5

.PHONY: demo preview gallery test lint format bench validators browser blender-extension clean

# pip's and the build backend's chatter (setuptools notes on editable installs) goes to a log,
# shown only when the install fails, so a new user's first screen is the tree, not warnings.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip > $(VENV)/install.log 2>&1 || { cat $(VENV)/install.log; exit 1; }
	$(BIN)/pip install --quiet -e '.[test]' >> $(VENV)/install.log 2>&1 || { cat $(VENV)/install.log; exit 1; }
	touch $(STAMP)

# The Khronos glTF-Validator, pinned in package.json / package-lock.json.
node_modules/.package-lock.json: package.json package-lock.json
	npm ci --no-audit --no-fund --loglevel=error

$(BPY_STAMP):
	$(BPY_PYTHON) -m venv $(BPY_VENV)
	$(BPY_VENV)/bin/pip install --quiet bpy==$(BPY_VERSION) > $(BPY_VENV)/install.log 2>&1 || { cat $(BPY_VENV)/install.log; exit 1; }
	$(BPY_VENV)/bin/python -c "import bpy" || { echo "bpy does not import: install the X11/GL libraries it links (see README)"; exit 1; }
	touch $(BPY_STAMP)

# lsys3d's own dependencies in Blender's Python (the add-on's tests run lsys3d there, from the checkout): the
# list read from pyproject.toml, with the numpy bpy was built against kept (bpy needs numpy < 2).
BPY_DEPS := $(BPY_VENV)/.lsys3d-deps
$(BPY_DEPS): pyproject.toml $(BPY_STAMP)
	$(BPY_VENV)/bin/python -c "import tomllib; print('\n'.join(tomllib.load(open('pyproject.toml', 'rb'))['project']['dependencies']))" > $(BPY_VENV)/lsys3d-requirements.txt
	$(BPY_VENV)/bin/pip install --quiet -r $(BPY_VENV)/lsys3d-requirements.txt "numpy==$$($(BPY_VENV)/bin/python -c 'import numpy; print(numpy.__version__)')" >> $(BPY_VENV)/install.log 2>&1 || { cat $(BPY_VENV)/install.log; exit 1; }
	touch $(BPY_DEPS)

# The Blender 4.2+ extension: build/lsys3d-blender-<version>.zip with blender_manifest.toml, the add-on and the
# wheels of lsys3d and its dependencies for each platform (BLENDER_PLATFORMS; Blender's own numpy is used).
BLENDER_PLATFORMS ?= linux-x64 windows-x64 macos-arm64 macos-x64
blender-extension: $(STAMP)
	$(BIN)/python tools/blender_extension.py --platforms $(BLENDER_PLATFORMS)

$(USDCHECK_STAMP):
	$(BPY_PYTHON) -m venv $(USDCHECK_VENV)
	$(USDCHECK_VENV)/bin/pip install --quiet usd-core==$(USDCHECK_VERSION) > $(USDCHECK_VENV)/install.log 2>&1 || { cat $(USDCHECK_VENV)/install.log; exit 1; }
	touch $(USDCHECK_STAMP)

# Debian's Chromium, driven headless by playwright-core (package.json) in the browser tests (three.js pages).
# Installed with apt-get when missing and make runs as root; otherwise the command to run is printed.
CHROMIUM ?= /usr/bin/chromium
browser: node_modules/.package-lock.json
	@test -x $(CHROMIUM) || { if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	  { apt-get install -y -q chromium || { apt-get update -q && apt-get install -y -q chromium; }; } \
	    > .chromium-install.log 2>&1 || { cat .chromium-install.log; exit 1; }; \
	  else echo "Chromium is missing: run 'sudo apt-get install chromium' (the browser tests skip locally, fail under CI)"; fi; }

validators: node_modules/.package-lock.json $(BPY_STAMP) $(BPY_DEPS) $(USDCHECK_STAMP) browser

demo: $(STAMP)
	$(BIN)/lsys3d generate

preview: $(STAMP) $(BPY_STAMP)
	LSYS3D_BLENDER=$(BPY_VENV)/bin/python $(BIN)/lsys3d preview

gallery: $(STAMP) $(BPY_STAMP)
	LSYS3D_BLENDER=$(BPY_VENV)/bin/python $(BIN)/python docs/make_gallery.py

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

test: lint validators
	$(BIN)/pytest -n auto --dist worksteal

bench: $(STAMP)
	for b in benchmarks/bench_*.py; do echo "== $$b"; $(BIN)/python $$b || exit 1; done

format: $(STAMP)
	$(BIN)/ruff check --fix .
	$(BIN)/ruff format .

clean:
	rm -rf $(VENV) $(BPY_VENV) $(USDCHECK_VENV) node_modules build *.egg-info .pytest_cache
