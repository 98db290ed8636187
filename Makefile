# Goal Babbling on growing bodies (Rolf, Steil & Gienger 2010). `make help` lists the targets.
PYTHON  ?= python3.11
VENV    := .venv
PY      := $(VENV)/bin/python
STAMP   := $(VENV)/.installed
FIGURES ?= fig2 fig4 fig5 fig7
PROFILE ?= full
ARGS    ?=

.DEFAULT_GOAL := help
.PHONY: help setup reproduce smoke simulate aggregate choices report pipeline bench test test-slow clean

help: ## list the targets
	@awk 'BEGIN {FS = ":.*## "} /^[a-z-]+:.*## / {printf "  make %-10s %s\n", $$1, $$2}' $(MAKEFILE_LIST)
	@echo "  variables: PROFILE=full|smoke, FIGURES=\"fig2 fig4 fig5 fig7\", ARGS=\"<hydra overrides>\""

# The virtual environment: created when missing, reinstalled when pyproject.toml changes.
$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	@touch $@

setup: $(STAMP) ## create .venv and install the project with its test extras

reproduce: ## the paper's figures and tables at full scale: simulate -> aggregate -> report (outputs/)
	@$(MAKE) --no-print-directory pipeline PROFILE=full

smoke: ## the same at smoke scale (1000 epochs, 2 trials) into outputs/smoke/
	@$(MAKE) --no-print-directory pipeline PROFILE=smoke

pipeline: simulate aggregate choices report

simulate: $(STAMP) ## stage 1: run the trials of FIGURES that are not cached (PROFILE, ARGS)
	@rc=0; for f in $(FIGURES); do \
	  $(PY) -m pipeline.simulate experiment=$$f profile=$(PROFILE) $(ARGS) || rc=1; \
	done; exit $$rc

aggregate: $(STAMP) ## stage 2: the cache into curves.parquet and summaries per figure
	$(PY) -m pipeline.aggregate profile=$(PROFILE) $(ARGS)

report: $(STAMP) ## stage 3: figures, tables and report.md
	$(PY) -m pipeline.report profile=$(PROFILE) $(ARGS)

# the open-choices sweep: 3 seeds x 20,000 epochs per variant at full scale, 1 x 500 for smoke
CHOICES_full  := --out outputs/report --cache outputs/cache/choices
CHOICES_smoke := --epochs 500 --seeds 1 --out outputs/smoke/report --cache outputs/smoke/cache/choices
choices: $(STAMP) ## stage 2b: short sweeps over the choices the paper leaves open (cached)
	$(PY) -m pipeline.choices $(CHOICES_$(PROFILE))

bench: $(STAMP) ## time the fast path against the numpy reference (outputs/bench/bench.json)
	$(PY) -m pipeline.bench

test: $(STAMP) ## run the test suite (slow tests excluded)
	$(PY) -m pytest

test-slow: $(STAMP) ## run the slow tests only
	$(PY) -m pytest -m slow

clean: ## remove generated outputs (asks first; YES=1 to skip the question); keeps the committed report and bench
	@if [ "$(YES)" != 1 ]; then \
	  printf 'Remove outputs/ (cache, aggregate, smoke, logs; not report/ and bench/)? [y/N] '; \
	  read ans; [ "$$ans" = y ] || { echo "nothing removed"; exit 0; }; \
	fi; \
	find outputs -mindepth 1 -maxdepth 1 ! -name report ! -name bench -exec rm -rf {} + 2>/dev/null; \
	echo "removed outputs/ except outputs/report/ and outputs/bench/"
