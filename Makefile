# Every install step lives here: a fresh clone needs nothing but python3.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test bench lint clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/station demo --out demo-out

test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -n 2

# The outside reference of `python -m bench vision` (npm `wallpaper-groups`, evaluation
# only, git-ignored); without npm the benchmark skips that source and says so.
bench/.npm/node_modules/wallpaper-groups:
	@if command -v npm >/dev/null; then \
	  npm install --prefix bench/.npm --no-save --no-package-lock wallpaper-groups@1.0.3; \
	else echo "npm not found: bench vision will skip source npm-wallpaper-groups"; fi

bench: $(STAMP) bench/.npm/node_modules/wallpaper-groups
	$(BIN)/python -m bench

lint: $(STAMP)
	$(BIN)/ruff check .

clean:
	rm -rf $(VENV) demo-out .pytest_cache
