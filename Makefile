# imupipe: two everyday commands (make run, make test); everything else is optional.
VENV   ?= .venv
PYTHON ?= python3
CORES  ?= 2
CONFIG ?= config/config.yaml
# With --max-checksum-file-size 0 Snakemake does not hash every input under 1 MB once per output of each
# finished job (measured before the per-axis split: ~0.25 s after a merge job of 45 inputs); an input newer than its
# outputs then re-runs the job even when its content did not change (the plain mtime rule).
SNAKEMAKE_FLAGS = --max-checksum-file-size 0
SNAKEMAKE = OPENBLAS_NUM_THREADS=1 $(VENV)/bin/snakemake --cores $(CORES) --configfile $(CONFIG) $(SNAKEMAKE_FLAGS)

.PHONY: env run test test-all bench report rulegraph lint clean

$(VENV)/.installed: pyproject.toml setup.py
	$(PYTHON) -m venv $(VENV)
	$(VENV)/bin/pip install -q --upgrade pip
	$(VENV)/bin/pip install -q -e ".[test]"
	touch $@

env: $(VENV)/.installed

# Every job imports imupipe in a new interpreter: compiled bytecode saves ~50 ms per job. Python writes it
# itself on first import unless PYTHONDONTWRITEBYTECODE is set; compileall writes it either way (a no-op
# when it is up to date).
BYTECODE = $(VENV)/bin/python -m compileall -q src/imupipe

# Snakemake's job listing is kept quiet by default (progress and errors only; every job's own log is under
# logs/<name>/, the run summary is printed at the end): `make run VERBOSE=1` shows every job.
QUIET = $(if $(VERBOSE),,--quiet rules host reason)

run: env  ## the default paper-scale workflow (simulated STIM-300-like data); ends with the run summary
	$(BYTECODE)
	$(SNAKEMAKE) $(QUIET)

# The suite runs on TEST_WORKERS processes (pytest-xdist; "auto": one per core), each taking whole test files
# (--dist loadfile), so a module's shared workflow run is built once; the session's tiny run (tests/conftest.py)
# is built once for all workers. TEST_WORKERS=0 runs the suite in one process.
TEST_WORKERS ?= auto
PYTEST = OPENBLAS_NUM_THREADS=1 $(VENV)/bin/pytest -n $(TEST_WORKERS) --dist loadfile

test: env  ## the test suite (slow paper-scale checks excluded)
	$(PYTEST) -q -m "not slow"

test-all: env  ## every test, paper-scale ones included
	$(PYTEST) -q

bench: env  ## speed against error, with allantools in the same run
	OPENBLAS_NUM_THREADS=1 $(VENV)/bin/python benchmarks/run.py

report: env  ## the HTML report of a finished run (results/<name>/report.html; the summary on its first page)
	$(BYTECODE)
	$(SNAKEMAKE) $(QUIET) --report results/$$($(VENV)/bin/python -c "import functools, sys, yaml; print(functools.reduce(lambda n, f: (yaml.safe_load(open(f)) or {}).get('name', n), sys.argv[1:], 'paper'))" $(CONFIG))/report.html

rulegraph: env  ## docs/figures/rulegraph.svg (needs graphviz's dot)
	$(SNAKEMAKE) --rulegraph | dot -Tsvg > docs/figures/rulegraph.svg

lint: env  ## Snakemake's linter: reports nothing on a clean workflow
	$(SNAKEMAKE) --lint

clean:
	rm -rf results logs .snakemake

# The workflow on a one-node SLURM cluster on localhost (tests/test_slurm.py, a few minutes): installs Debian's
# slurm-wlm and munge first when their commands are missing (needs root; the test skips with the reason when
# they are still missing or the daemons do not start). The test starts and stops its own daemons.
.PHONY: test-slurm
test-slurm: env
	@missing=""; for c in munged slurmctld slurmd sbatch squeue srun; do \
	    command -v $$c >/dev/null 2>&1 || [ -x /usr/sbin/$$c ] || missing="$$missing $$c"; done; \
	if [ -n "$$missing" ]; then \
	    echo "missing:$$missing; installing slurm-wlm and munge"; \
	    { apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y slurm-wlm munge; } \
	        || echo "could not install slurm-wlm and munge (not root?): the SLURM test will skip"; \
	fi
	OPENBLAS_NUM_THREADS=1 $(VENV)/bin/pytest -q -m slurm -s tests/test_slurm.py
