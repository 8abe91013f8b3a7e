# The README's two commands: `make run` (the platform on SQLite, simulator, bundled mazes)
# and `make test`. Both build .venv from the two pyproject.toml files on first use.
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
PYTHON ?= python3
HOST   ?= 127.0.0.1
PORT   ?= 8000
# Where torch's CPU wheel comes from: the machine's own pip index by default (this project's
# machines serve the CPU build); elsewhere `make TORCH_INDEX=https://download.pytorch.org/whl/cpu`,
# since a plain PyPI gives Linux the multi-GB CUDA build.
TORCH_INDEX ?=

.PHONY: run test lint bench clean

$(STAMP): pyproject.toml robot_client/pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	# torch first, pinned, CPU build: the `learn` extra below then finds it installed.
	$(BIN)/python -m pip install --quiet torch==2.13.0 $(if $(TORCH_INDEX),--index-url $(TORCH_INDEX))
	# The rover's distribution first: the server depends on it (it owns robot_client/).
	$(BIN)/python -m pip install --quiet -e ./robot_client
	$(BIN)/python -m pip install --quiet -e '.[dev,learn,lerobot]'
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/robotslang serve --host $(HOST) --port $(PORT)

test: $(STAMP)
	$(BIN)/python -m pytest

# ruff (lint, format check) and mypy, as pyproject.toml configures them: strict on sim/ and app/trial/.
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy

bench: $(STAMP)
	$(BIN)/python -m bench.sim

clean:
	rm -rf $(VENV)
