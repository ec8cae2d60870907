# kincal: `make demo` and `make test` set up .venv themselves on a fresh clone.
PYTHON ?= python3
VENV   ?= .venv
PY      = $(VENV)/bin/python
STAMP   = $(VENV)/.installed

.PHONY: setup demo test test-fast docs bench clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check --no-compile -e '.[dev]'  # bytecode on first import: 15 s less
	touch $(STAMP)

# the real datasets are used where they are, never copied here: ../shared/datasets beside this checkout (or beside
# a folder above it), or the folder KINCAL_SHARED_DATASETS names
DATASETS ?= $(or $(KINCAL_SHARED_DATASETS),$(shell d="$(CURDIR)"; while [ "$$d" != / ]; do d=$$(dirname "$$d"); \
              [ -d "$$d/shared/datasets" ] && { echo "$$d/shared/datasets"; break; }; done))
DATA = $(DATASETS)/ur5_wam_gts3800
UR5  = --length-unit mm --angle-unit deg --joint-cols joint_1,joint_2,joint_3,joint_4,joint_5,joint_6

demo: setup
	@test -f "$(DATA)/ur5_grid.csv" || { echo "make demo: the UR5 laser-tracker data ($(DATA)/ur5_grid.csv) \
	is not here: put the shared datasets beside this checkout (../shared/datasets) or set KINCAL_SHARED_DATASETS"; exit 1; }
	$(VENV)/bin/kincal demo
	@echo
	@echo "Guo et al. 2024's 62 % claim as a Monte-Carlo study (200 trials; resumes from .venv/guo2024_study_v2.jsonl)"
	$(VENV)/bin/kincal study guo2024 --workers 2 -o .venv/guo2024_study_v2.jsonl
	@echo
	@echo "Real laser-tracker data: calibrate the UR5 on 1000 grid poses, evaluate on 20 unseen poses"
	@echo "(one tracker set-up, data in the robot base frame: --same-frame)"
	$(VENV)/bin/kincal evaluate ur5 $(DATA)/ur5_random.csv $(UR5) --same-frame
	$(VENV)/bin/kincal calibrate ur5 $(DATA)/ur5_grid.csv $(UR5) -o .venv/ur5_calibrated.yaml > /dev/null
	$(VENV)/bin/kincal evaluate .venv/ur5_calibrated.yaml $(DATA)/ur5_random.csv $(UR5) --same-frame
	@echo
	@echo "The calibration report (open it in a browser): verdict, errors before/after, plots, parameters"
	$(VENV)/bin/kincal report .venv/ur5_calibrated.yaml --test $(DATA)/ur5_random.csv --same-frame -o .venv/ur5_report.html
	@echo
	@echo "The calibrated UR5 back out, for ROS: a URDF (with the reflector as link 'smr') and UR's kinematics file"
	$(VENV)/bin/kincal export .venv/ur5_calibrated.yaml .venv/ur5_calibrated.urdf --tool-link smr
	$(VENV)/bin/kincal export .venv/ur5_calibrated.yaml .venv/ur5_calibration.yaml --format ur
	@echo "written: .venv/ur5_calibrated.yaml (kincal), .venv/ur5_calibrated.urdf (URDF), .venv/ur5_calibration.yaml (UR driver)"
	@echo "report:  .venv/ur5_report.html (numbers in .venv/ur5_report.json)"
	@echo
	@echo "To use kincal on your own robot, put it on your PATH (this shell):  source $(VENV)/bin/activate"
	@echo "or for good:  ln -s $(CURDIR)/$(VENV)/bin/kincal ~/.local/bin/kincal   (then: kincal --help)"

# two workers (pytest-xdist), the tests that share a computation in one xdist_group
test: setup
	$(PY) -m mypy
	$(PY) -m pytest -q -n 2 --dist loadgroup

# the inner loop: everything but the tests marked slow (each over about a second), on two workers: under a minute
test-fast: setup
	$(PY) -m pytest -q -m "not slow" -n 2 --dist loadgroup

# the documentation site: warnings are errors, the gallery's scripts run, every internal link is checked
DOCS_STAMP = $(VENV)/.docs-installed
$(DOCS_STAMP): $(STAMP)
	$(PY) -m pip install --quiet --disable-pip-version-check -e '.[dev,docs]'
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	$(VENV)/bin/sphinx-build -W --keep-going -q -b html docs docs/_build/html
	$(PY) docs/check_links.py docs/_build/html
	@echo "the site: docs/_build/html/index.html"

bench: setup
	$(PY) benchmarks/startup.py
	$(PY) benchmarks/core.py
	$(PY) benchmarks/design.py
	$(PY) benchmarks/design_real.py
	$(PY) benchmarks/parallel.py
	$(PY) benchmarks/report.py
	$(PY) benchmarks/models.py

clean:
	rm -rf $(VENV) build src/*.egg-info .pytest_cache docs/_build docs/tutorials docs/reference/api
