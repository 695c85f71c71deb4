# Two commands do all the set-up: `make demo` and `make test`. Both create .venv on first use.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup demo test test-slow lint eval-full bench clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	$(BIN)/rerun analytics disable >/dev/null  # Rerun collects usage data unless told not to
	touch $(STAMP)

demo: setup
	$(BIN)/windwarden demo

# The tests that start no system spread over every core (pytest-xdist, one worker per test file); the tests that
# start whole systems (routers, nodes, the API, child processes: marked `system`, which every test of tests/live and
# tests/security is unless marked `in_process`; tests/conftest.py fails a test that starts one unmarked) then run one
# at a time on an otherwise idle machine, as their timeouts and latency checks assume.
SYSTEM_TESTS := tests/live tests/security
PARALLEL := -n auto --dist loadfile

test: setup
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -q $(PARALLEL) -m 'not slow and not system'
	$(BIN)/python -m pytest -q -m 'not slow and system' $(SYSTEM_TESTS)

test-slow: setup
	$(BIN)/python -m pytest -q $(PARALLEL) -m 'slow and not system'
	$(BIN)/python -m pytest -q -m 'slow and system' $(SYSTEM_TESTS)

lint: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

clean:
	rm -rf $(VENV) runs out .pytest_cache .ruff_cache
