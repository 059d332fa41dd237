# Quick start: `make run` then `make test`. Both create .venv on first use.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
OUT    ?= out
# strictly typed (mypy.ini): the whole package
TYPED  := folder_line

.PHONY: run report test docs bench accuracy clean

$(STAMP): requirements.txt setup.py setup.cfg package.xml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -r requirements.txt
	$(BIN)/python -m pip install --quiet --no-deps --no-build-isolation -e .
	@touch $(STAMP)

run: $(STAMP)
	$(BIN)/folder-line run --scene folder --duration 20 --out $(OUT)

# the kinematics/efficiency/cyclogram report of the defaults, with plots
report: $(STAMP)
	$(BIN)/folder-line report --out $(OUT)

test: $(STAMP)
	$(BIN)/ruff format --check --quiet .
	$(BIN)/ruff check --quiet .
	$(BIN)/mypy $(TYPED)
	$(BIN)/python -m pytest -n 2 --dist loadfile

# the manual (Sphinx, MyST Markdown, autodoc) into build/docs; warnings are errors
docs: $(STAMP)
	$(BIN)/sphinx-build -W --keep-going -q -b html docs build/docs

bench: $(STAMP)
	$(BIN)/python bench/bench_layup.py
	$(BIN)/python bench/bench_line.py
	$(BIN)/python bench/bench_nodes.py
	$(BIN)/python bench/bench_studies.py

# what accuracy costs in CPU time (about 3 min); docs/accuracy.md quotes this run
accuracy: $(STAMP)
	$(BIN)/folder-line bench accuracy --out docs/accuracy

clean:
	rm -rf $(VENV) $(OUT) build *.egg-info .pytest_cache .hypothesis .mypy_cache
