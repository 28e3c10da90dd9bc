# hairinv: `make demo` sets everything up and runs the pipeline on a sample
# groom; `make test` runs the test suite in the same environment.

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
HAIRINV := $(VENV)/bin/hairinv
STAMP  := $(VENV)/.installed
OUT    ?= out/demo
# Blender as a Python module, in its own venv: tests/test_blender.py and bench/blender_bench.py
# import the USD files hairinv exports with it. bpy 5.0 wheels are for CPython 3.11 only.
BPY_VERSION   ?= 5.0.1
BLENDER_VENV  ?= .venv-blender
BLENDER_PY    := $(BLENDER_VENV)/bin/python
BLENDER_STAMP := $(BLENDER_VENV)/.installed-bpy-$(BPY_VERSION)

.PHONY: demo test bench samples rigs blender clean help

help:
	@echo "make demo    set up .venv, fit and invert the sample wavy groom, print where the outputs are"
	@echo "make test    set up .venv and .venv-blender and run the tests"
	@echo "make bench   run the benchmarks and rewrite docs/benchmarks.md"
	@echo "make samples regenerate samples/ (body mesh, grooms and turn.glb, the bust turning its head)"
	@echo "make rigs    write the rigged mannequin's shots to out/rigs (GLB, USD, OBJ sequence and groom each)"
	@echo "make blender set up .venv-blender: Blender $(BPY_VERSION) as the bpy module, to read the USD export"

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

$(BLENDER_STAMP):
	$(PYTHON) -m venv $(BLENDER_VENV)
	$(BLENDER_PY) -m pip install --quiet bpy==$(BPY_VERSION)
	touch $(BLENDER_STAMP)

blender: $(BLENDER_STAMP)

demo: $(STAMP)
	@mkdir -p $(OUT)
	$(HAIRINV) fit samples/wavy.h5 -o $(OUT)/wavy.fit.h5
	$(HAIRINV) invert $(OUT)/wavy.fit.h5 samples/body.obj -o $(OUT)/wavy.model.h5
	$(HAIRINV) info $(OUT)/wavy.model.h5
	@echo
	@echo "Outputs:"
	@echo "  $(OUT)/wavy.fit.h5     /curves and /helices of the sample wavy groom"
	@echo "  $(OUT)/wavy.model.h5   the same plus /contacts and /model: rest shape and contact forces"

# The Blender tests run in make test: .venv-blender installs in about 20 s (a 374 MB wheel, 0.97 GB on disk).
test: $(STAMP) $(BLENDER_STAMP)
	$(PY) -m pytest -q

bench: $(STAMP) $(BLENDER_STAMP)
	$(PY) bench/run.py

samples: $(STAMP)
	$(PY) samples/make_samples.py
	$(PY) samples/make_rigs.py --sample

# every variant of samples/make_rigs.py (about a minute, 120 MB of OBJ frames), each read back and checked
rigs: $(STAMP)
	$(PY) samples/make_rigs.py -o out/rigs

clean:
	rm -rf out .pytest_cache
