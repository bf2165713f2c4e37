# Every install step lives here: a fresh clone needs nothing but python3.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test bench lint clean browser

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/station demo --out demo-out

# The web console's browser tests drive Debian's Chromium (Playwright's own download is
# not used): installed here when missing, as root or through passwordless sudo. Without it
# those tests skip on a workstation, saying so, and fail under CI.
CHROMIUM := /usr/bin/chromium
APT_CHROMIUM := DEBIAN_FRONTEND=noninteractive apt-get install -y chromium

browser:
	@if [ -x $(CHROMIUM) ]; then :; \
	elif [ "$$(id -u)" = 0 ]; then $(APT_CHROMIUM) || { apt-get update && $(APT_CHROMIUM); }; \
	elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then \
	  sudo $(APT_CHROMIUM) || { sudo apt-get update && sudo $(APT_CHROMIUM); }; \
	else echo "make: $(CHROMIUM) is missing and neither root nor sudo is at hand:" \
	  "the console's browser tests will skip (and fail under CI)"; fi

test: $(STAMP) browser
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
