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

# The CPU-bound tests spread over every core (pytest-xdist, one worker per test file); the tests that start whole
# systems (routers, nodes, the API: tests/live, tests/security) then run one at a time on an otherwise idle machine,
# as their timeouts and latency checks assume.
SYSTEM_TESTS := tests/live tests/security
PARALLEL := -n auto --dist loadfile $(foreach d,$(SYSTEM_TESTS),--ignore=$(d))

test: setup
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -q $(PARALLEL)
	$(BIN)/python -m pytest -q $(SYSTEM_TESTS)

test-slow: setup
	$(BIN)/python -m pytest -q -m slow $(PARALLEL)
	$(BIN)/python -m pytest -q -m slow $(SYSTEM_TESTS)

lint: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

clean:
	rm -rf $(VENV) runs out .pytest_cache .ruff_cache
