# elastica-auto: one target per job. `make demo` installs and runs the main job; `make test` tests.
PYTHON ?= python3
VENV   ?= .venv
BIN     = $(VENV)/bin
OUT    ?= out
FIG    ?= figures

.PHONY: install demo test bench clean

$(BIN)/elastica-auto: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test]'
	@touch $@

install: $(BIN)/elastica-auto

demo: install
	$(BIN)/elastica-auto run rotating_arm --out $(OUT)
	$(BIN)/elastica-auto plot $(OUT)/rotating_arm.h5 -o $(FIG)/rotating_arm_m1_psi.png

test: install
	$(BIN)/python -m pytest -q

bench: install
	$(BIN)/python benchmarks/bench_rotating_arm.py
	$(BIN)/python benchmarks/bench_rotating_arm.py --memory

clean:
	rm -rf $(OUT) $(FIG) .pytest_cache
