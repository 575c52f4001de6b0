# Set-up and the two Quick-start commands (README): `make demo` runs the whole pipeline on the
# bundled closed room, `make test` runs the tests. Both create the virtual environment and install an OpenCL
# runtime that can build kernels when the machine has none (Debian's pocl-opencl-icd).

SHELL  := /bin/bash
.SHELLFLAGS := -o pipefail -c
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
SCENE  ?= scenes/room.json
OUT    ?= out

.PHONY: demo test lint staged opencl bytecode setup clean

setup: opencl bytecode

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[all,test]'
	touch $(STAMP)

# Install PoCL from Debian when no OpenCL device can build kernels (PyPI's PoCL cannot here).
opencl: $(STAMP)
	@$(BIN)/clsonar devices >/dev/null 2>&1 || { \
	  echo "No OpenCL device can build kernels: installing Debian's pocl-opencl-icd"; \
	  if [ "$$(id -u)" -eq 0 ]; then SUDO=; else SUDO=sudo; fi; \
	  $$SUDO apt-get update -qq && $$SUDO apt-get install -y -qq pocl-opencl-icd >/dev/null; }
	@$(BIN)/clsonar devices

# Python's bytecode cache of the package, written once (incremental): where the environment
# sets PYTHONDONTWRITEBYTECODE, every process would otherwise compile clsonar's modules from
# source (0.15-0.3 s of a run); Python reads the cache whatever that variable says.
bytecode: $(STAMP)
	@$(BIN)/python -m compileall -q clsonar gui kernels >/dev/null

demo: opencl bytecode
	$(BIN)/clsonar run $(SCENE) --out $(OUT)/$(notdir $(basename $(SCENE)))
	@echo "Pictures of every stage: $(OUT)/$(notdir $(basename $(SCENE)))/*.png"

test: opencl bytecode
	$(BIN)/python -m pytest

# The GUI lives in gui/ and is installed as clsonar.gui: the import contracts (import-linter)
# and the type checker (mypy) read the package laid out as installed, from a copy in build/.
STAGED := build/staged

staged:
	rm -rf $(STAGED) && mkdir -p $(STAGED)
	cp -r clsonar $(STAGED)/clsonar && cp -r gui $(STAGED)/clsonar/gui
	find $(STAGED) -name __pycache__ -prune -exec rm -rf {} +

lint: $(STAMP) staged
	$(BIN)/ruff check clsonar gui kernels tests
	cd $(STAGED) && PYTHONPATH=. $(abspath $(BIN))/lint-imports $(CURDIR)/pyproject.toml
	cd $(STAGED) && $(abspath $(BIN))/mypy --config-file $(CURDIR)/pyproject.toml -p clsonar \
	  | sed 's|^clsonar/gui/|gui/|'

clean:
	rm -rf $(VENV) $(OUT) build dist *.egg-info
