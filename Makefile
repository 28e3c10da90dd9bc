# hairinv: `make demo` sets everything up and runs the pipeline on a sample
# groom; `make test` runs the test suite in the same environment.

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
HAIRINV := $(VENV)/bin/hairinv
STAMP  := $(VENV)/.installed
OUT    ?= out/demo

.PHONY: demo test bench samples clean help

help:
	@echo "make demo    set up .venv, fit and invert the sample wavy groom, print where the outputs are"
	@echo "make test    set up .venv and run the tests"
	@echo "make bench   run the benchmarks and rewrite docs/benchmarks.md"
	@echo "make samples regenerate samples/ (body mesh and grooms)"

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	@mkdir -p $(OUT)
	$(HAIRINV) fit samples/wavy.h5 -o $(OUT)/wavy.fit.h5
	$(HAIRINV) invert $(OUT)/wavy.fit.h5 samples/body.obj -o $(OUT)/wavy.model.h5
	$(HAIRINV) info $(OUT)/wavy.model.h5
	@echo
	@echo "Outputs:"
	@echo "  $(OUT)/wavy.fit.h5     /curves and /helices of the sample wavy groom"
	@echo "  $(OUT)/wavy.model.h5   the same plus /contacts and /model: rest shape and contact forces"

test: $(STAMP)
	$(PY) -m pytest -q

bench: $(STAMP)
	$(PY) bench/run.py

samples: $(STAMP)
	$(PY) samples/make_samples.py

clean:
	rm -rf out .pytest_cache
