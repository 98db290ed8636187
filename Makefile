# Goal Babbling on growing bodies (Rolf, Steil & Gienger 2010). `make help` lists the targets.
# The Python that creates .venv: python3.11 if there is one, else python3 (>= 3.11 is checked).
PYTHON  ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV    := .venv
PY      := $(VENV)/bin/python
STAMP   := $(VENV)/.installed
# make reproduce: the paper's figures (Fig. 7 also at 20 trials: the scorecard judges it there),
# the choices it leaves open and the experiments behind the report's explanations; make studies
# adds the studies beyond the paper (readings x figures, baselines) and publishes the report of
# everything (the committed one). Each experiment file says which list it is in and where
# (conf/experiment/*.yaml: declares.group, declares.order); the lists are read from them once,
# when first used (pipeline.tools.experiments: after make setup, which installs what it needs).
LISTED   = $(eval LISTED := $(shell test -x $(PY) && $(PY) -m pipeline.tools.experiments --make))$(LISTED)
PAPER    = $(patsubst paper:%,%,$(filter paper:%,$(LISTED)))
CHOICES  = $(patsubst choices:%,%,$(filter choices:%,$(LISTED)))
EXPLAIN  = $(patsubst explain:%,%,$(filter explain:%,$(LISTED)))
STUDIES  = $(patsubst studies:%,%,$(filter studies:%,$(LISTED)))
FIGURES ?= $(PAPER) $(CHOICES) $(EXPLAIN) $(STUDIES)
PROFILE ?= full
ARGS    ?=
# make test's processes (pytest-xdist): one per core of the 2-core machine it is sized for; a test
# file stays on one process, so a file's shared fixtures are built once
TESTJOBS ?= 2

.DEFAULT_GOAL := help
.PHONY: help experiments setup reproduce studies stamp docs smoke simulate aggregate choices report pipeline bench scale first-hour test test-slow test-cluster test-browser html gym-figure notebooks publish clean

help: ## list the targets
	@awk 'BEGIN {FS = ":.*## "} /^[a-z-]+:.*## / {printf "  make %-10s %s\n", $$1, $$2}' $(MAKEFILE_LIST)
	@echo "  variables: PROFILE=full|smoke, FIGURES=\"$(PAPER) $(CHOICES) $(EXPLAIN) $(STUDIES)\", ARGS=\"<hydra overrides>\""

# The virtual environment: created when missing, reinstalled when pyproject.toml or the lock
# changes; the packages are the locked versions the committed report was made with. Then numba
# compiles the kernels once (cached beside the sources), so no later stage is cut off mid-compile.
$(STAMP): pyproject.toml requirements.lock
	@test -n "$(PYTHON)" || { echo "error: no python3 found; install Python >= 3.11"; exit 2; }
	@$(PYTHON) -c 'import sys; sys.exit(sys.version_info < (3, 11))' || \
	  { echo "error: $(PYTHON) is Python $$($(PYTHON) -c 'import platform; print(platform.python_version())'); need >= 3.11 (make PYTHON=python3.x)"; exit 2; }
	@echo "creating $(VENV) with $(PYTHON) ($$($(PYTHON) --version))"
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -c requirements.lock -e '.[test]'
	# the Poppy Ergo Jr body reads only the URDF file of this package: without its dependencies
	# (pypot would pull in a robot driver stack the body never uses)
	$(PY) -m pip install --quiet --no-deps poppy-ergo-jr==4.0.2
	$(PY) -m pipeline.warm
	@touch $@

experiments: ## the experiments of each list (PAPER, CHOICES, EXPLAIN, STUDIES), as declared
	@echo "PAPER   = $(PAPER)"; echo "CHOICES = $(CHOICES)"; echo "EXPLAIN = $(EXPLAIN)"; echo "STUDIES = $(STUDIES)"

setup: $(STAMP) ## create .venv, install the locked packages, compile the kernels

reproduce: $(STAMP) ## the paper's figures, its open choices and the explanations, published to outputs/report/
	@$(MAKE) --no-print-directory pipeline PROFILE=full FIGURES="$(PAPER) $(CHOICES) $(EXPLAIN)" \
	  PUBLISH="report.publish=true 'report.paper_experiments=[$(shell echo $(PAPER) $(CHOICES) $(EXPLAIN) | tr ' ' ',')]'"

studies: ## the studies beyond the paper (readings x figures, baselines), then the whole committed report
	@$(MAKE) --no-print-directory pipeline PROFILE=full PUBLISH=report.publish=true

stamp: ## after make studies and a rewrite of findings.md: record the numbers it discusses
	@$(MAKE) --no-print-directory report PROFILE=full PUBLISH="report.publish=true report.stamp_findings=true"

docs: $(STAMP) ## render README.md and docs/ from docs/templates/ and the committed report's values.csv (CHECK=1: only compare)
	$(PY) -m pipeline.tools.render $(if $(CHECK),--check)

smoke: ## the same at smoke scale (1000 epochs, 2 trials) into outputs/smoke/latest/
	@$(MAKE) --no-print-directory pipeline PROFILE=smoke

pipeline: simulate aggregate report

# no experiment listed (the experiments tool failed: its error is printed above) stops here, rather
# than running the default config under experiments=[]
EXPS     = $(if $(strip $(FIGURES)),'experiments=[$(shell echo $(FIGURES) | tr ' ' ',')]',$(error no experiments \
           listed: '$(PY) -m pipeline.tools.experiments --make' failed (FIGURES=... names them by hand)))

simulate: $(STAMP) ## stage 1: run the trials of FIGURES that are not cached, in one process (PROFILE, ARGS)
	$(PY) -m pipeline.simulate $(EXPS) profile=$(PROFILE) $(ARGS)

aggregate: $(STAMP) ## stage 2: the cache into curves.parquet and summaries per figure (changed figures only)
	$(PY) -m pipeline.aggregate $(EXPS) profile=$(PROFILE) $(ARGS)

report: $(STAMP) ## stage 3: figures, tables and report.md (outputs/latest/; make reproduce: outputs/report/)
	$(PY) -m pipeline.report $(EXPS) profile=$(PROFILE) $(PUBLISH) $(ARGS)

choices: $(STAMP) ## the open-choices experiments only (choices_*), then aggregate and report
	@$(MAKE) --no-print-directory pipeline FIGURES="$(CHOICES)"

bench: $(STAMP) ## time the fast path against the numpy reference (outputs/bench/bench.json)
	$(PY) -m pipeline.tools.bench $(ARGS)

scale: $(STAMP) ## time sweeps of 1,000 and 10,000 short trials stage by stage and a cached make smoke (outputs/bench/scale.json; ARGS="--baseline DIR")
	$(PY) -m pipeline.tools.scale --smoke-experiments '$(shell echo $(FIGURES) | tr ' ' ',')' $(ARGS)

first-hour: $(STAMP) ## time make setup, make smoke and make test in a fresh clone (outputs/bench/first_hour.json; ARGS="--no-test")
	$(PY) -m pipeline.tools.firsthour $(ARGS)

test: $(STAMP) ## run the test suite (slow tests excluded) on TESTJOBS processes
	$(PY) -m pytest -n $(TESTJOBS) --dist loadfile

test-slow: $(STAMP) ## install the extras (Ray, submitit, MuJoCo), run the slow tests and the MuJoCo cross-checks
	$(PY) -m pip install --quiet -c requirements.lock -e '.[test,ray,slurm,mujoco]'
	$(PY) -m pytest -m slow
	# the MJCF bodies against MuJoCo itself (make test skips them: mujoco is an extra)
	$(PY) -m pytest tests/core/test_bodies_mjcf.py tests/core/test_body_loop.py

test-cluster: $(STAMP) ## start a one-host SLURM (as root: apt-get installs it) and a two-node Ray, run the cluster tests
	@if [ "$$(id -u)" = 0 ] && ! command -v slurmctld >/dev/null; then apt-get update -q; \
	  apt-get install -y -q --no-install-recommends slurmctld slurmd slurm-client slurmdbd mariadb-server \
	  || echo "SLURM not installed: its tests will skip"; fi
	$(PY) -m pip install --quiet -c requirements.lock -e '.[test,ray,slurm]'
	$(PY) -m pytest -m cluster

html: $(STAMP) ## render report.html beside every report.md under outputs/ and write outputs/index.html
	$(PY) -m pipeline.html_report outputs

test-browser: $(STAMP) ## install Debian's chromium (as root), open the HTML reports in it headless (screenshots: outputs/browser/)
	@if ! command -v chromium >/dev/null; then \
	  if [ "$$(id -u)" = 0 ]; then apt-get update -q && apt-get install -y -q --no-install-recommends chromium; \
	  else echo "no chromium: install it (apt-get install chromium) or run as root"; exit 2; fi; fi
	$(PY) -m pytest -m browser tests/pipeline/test_html_report.py

gym-figure: $(STAMP) ## install the extra [rl] (torch CPU, stable-baselines3), redraw docs/img/sac_vs_goal_babbling.png
	$(PY) -m pip install --quiet -c requirements.lock -e '.[test,rl]'
	$(PY) examples/06_sac_against_goal_babbling.py $(ARGS)

notebooks: $(STAMP) ## install the extra [notebooks], run every notebook (notebooks/*.py) in a kernel
	$(PY) -m pip install --quiet -c requirements.lock -e '.[test,notebooks]'
	$(PY) -m pytest tests/e2e/test_notebooks.py

publish: $(STAMP) ## build the sdist and wheel into dist/, check them with twine, validate CITATION.cff
	$(PY) -m pip install --quiet -c requirements.lock -e '.[test,publish]'
	rm -rf dist && $(PY) -m build --outdir dist . && $(PY) -m twine check --strict dist/*
	rm -rf build/cff && $(PYTHON) -m venv build/cff && build/cff/bin/pip install --quiet 'cffconvert>=2.0,<3'
	build/cff/bin/cffconvert --validate -i CITATION.cff

clean: ## remove generated outputs (asks first; YES=1 to skip the question); keeps the committed report and bench
	@if [ "$(YES)" != 1 ]; then \
	  printf 'Remove outputs/ (cache, aggregate, smoke, logs; not report/ and bench/)? [y/N] '; \
	  read ans; [ "$$ans" = y ] || { echo "nothing removed"; exit 0; }; \
	fi; \
	find outputs -mindepth 1 -maxdepth 1 ! -name report ! -name bench -exec rm -rf {} + 2>/dev/null; \
	echo "removed outputs/ except outputs/report/ and outputs/bench/"
