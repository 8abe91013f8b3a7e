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

# lerobot's own LeRobotDataset, which loads the LeRobot export back in its test: a venv of its own
# (tests/app/lerobot_env/requirements.txt says why), about 6 GB; `make test` skips that test without it.
LEROBOT_VENV  := .venv-lerobot
LEROBOT_STAMP := $(LEROBOT_VENV)/.installed-stamp
LEROBOT_REQS  := tests/app/lerobot_env/requirements.txt

.PHONY: run test lint bench clean lerobot-venv messages

$(STAMP): pyproject.toml robot_client/pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	# torch first, pinned, CPU build: the `learn` extra below then finds it installed.
	$(BIN)/python -m pip install --quiet torch==2.13.0 $(if $(TORCH_INDEX),--index-url $(TORCH_INDEX))
	# The rover's distribution first: the server depends on it (it owns robot_client/).
	$(BIN)/python -m pip install --quiet -e ./robot_client
	$(BIN)/python -m pip install --quiet -e '.[dev,learn,lerobot,cluster]'
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/robotslang serve --host $(HOST) --port $(PORT)

# Two workers, each test file on one (its module fixtures built once): most tests wait on sockets,
# servers and browsers, so two share the 2-core machine well (19 min serial, 11.5 min so).
TEST_WORKERS ?= 2

test: $(STAMP)
	$(BIN)/python -m pytest -n $(TEST_WORKERS) --dist loadfile

# ruff (lint, format check) and mypy, as pyproject.toml configures them: strict on sim/ and most of app/.
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy

# The participant pages' messages (app/i18n.py, docs/study.md): extracted from the code into the
# template, then merged into each language's catalog for its translator (new ones empty, changed ones
# fuzzy). The server reads the .po files themselves: there is nothing to compile.
messages: $(STAMP)
	$(BIN)/pybabel extract -F app/locale/babel.cfg -k Text -k t --project=RobotSlang --no-wrap -o app/locale/messages.pot .
	$(BIN)/pybabel update -i app/locale/messages.pot -d app/locale --no-wrap

$(LEROBOT_STAMP): $(LEROBOT_REQS)
	$(PYTHON) -m venv $(LEROBOT_VENV)
	$(LEROBOT_VENV)/bin/python -m pip install --quiet --upgrade pip
	# With TORCH_INDEX, its +cpu builds of torch, torchvision and torchcodec rank above PyPI's.
	$(LEROBOT_VENV)/bin/python -m pip install --quiet -r $(LEROBOT_REQS) $(if $(TORCH_INDEX),--extra-index-url $(TORCH_INDEX))
	# lerobot's own pins (torch<2.11, torchvision<0.26, torchcodec<0.11) admit no torchvision that
	# imports here: lerobot alone, its dataset loader's imports being those above.
	$(LEROBOT_VENV)/bin/python -m pip install --quiet --no-deps lerobot==0.4.4
	touch $(LEROBOT_STAMP)

lerobot-venv: $(LEROBOT_STAMP)

bench: $(STAMP)
	$(BIN)/python -m bench.sim

clean:
	rm -rf $(VENV) $(LEROBOT_VENV)
