# elastica-auto: one target per job. `make demo` installs and runs the main job; `make test` tests.
# `install` also byte-compiles the package (only what changed): pip does so for the dependencies
# it installs but not for an editable install, whose modules every process compiles again where
# PYTHONDONTWRITEBYTECODE is set (0.25 s of each start here, and of each Dask worker's).
PYTHON ?= python3
VENV   ?= .venv
BIN     = $(VENV)/bin
OUT    ?= out
FIG    ?= figures

.PHONY: install demo test bench bench-auto clean

$(BIN)/elastica-auto: pyproject.toml setup.py elastica_auto/numerics/_banded.c \
		elastica_auto/numerics/_blocks.c elastica_auto/energy/_frames.c
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test]'
	@touch $@

install: $(BIN)/elastica-auto
	@$(BIN)/python -m compileall -q elastica_auto equations > /dev/null

demo: install
	$(BIN)/elastica-auto run rotating_arm --out $(OUT)
	$(BIN)/elastica-auto plot $(OUT)/rotating_arm.h5 -o $(FIG)/rotating_arm_m1_psi.png

test: install
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -q -n auto --dist loadgroup

bench: install
	$(BIN)/python benchmarks/bench.py
	$(BIN)/python benchmarks/bench.py --memory

# AUTO-07p's boundary value demos against ours (benchmarks/auto/): builds AUTO-07p from a local
# copy of its source into build/auto-07p (ignored by git; not part of `make test` or `make bench`)
# and prints the table of docs/benchmarks.md ("Against AUTO-07p"). ROUNDS=1 for a quick look.
ROUNDS ?= 5
bench-auto: install
	@test -n "$(AUTO_SRC)" -o -f build/auto-07p/.built || \
	  { echo "make bench-auto: give AUTO_SRC=DIR, a copy of AUTO-07p's source"; exit 2; }
	cd benchmarks/auto && ../../$(BIN)/python bench_auto.py --rounds $(ROUNDS) \
	  $(if $(AUTO_SRC),--auto-src $(abspath $(AUTO_SRC))) $(if $(DEMOS),--demos $(DEMOS))

clean:
	rm -rf $(OUT) $(FIG) .pytest_cache

# ---------------------------------------------------------------------------------------------
# The paper's experiments and figures (docs/figures.md). `make figures` computes every run a
# figure needs (out/<run>.h5 from runs/<run>.toml, in restart order) and draws figures/*.png and
# *.pdf. A branch file is recomputed only when its run file, the engine (its Python modules
# and its C files) or a file it restarts from changed; a figure is redrawn only when its branch
# files or the plotting code changed.
RUNS   ?= runs
ENGINE  = $(wildcard elastica_auto/*.py equations/*.py elastica_auto/*/*.c \
            $(filter-out elastica_auto/plots/%,$(wildcard elastica_auto/*/*.py)))
PLOTS   = $(wildcard elastica_auto/plots/*.py)

.PHONY: figures runs gallery fig-rotating-arm

# a run that ends with a failed branch (exit status 1) leaves no file behind for make to trust
$(OUT)/%.h5: $(RUNS)/%.toml $(ENGINE) | $(BIN)/elastica-auto
	$(BIN)/elastica-auto run $< --out $(OUT) -q || { rm -f $@; exit 1; }

# $(call FIGURE,name,runs): target fig-<name> draws $(FIG)/<name with _>.png and .pdf
define FIGURE
FIGURE_TARGETS += fig-$(1)
.PHONY: fig-$(1)
fig-$(1): $(FIG)/$(subst -,_,$(1)).png $(FIG)/$(subst -,_,$(1)).pdf
$(FIG)/$(subst -,_,$(1)).png $(FIG)/$(subst -,_,$(1)).pdf &: $(2:%=$(OUT)/%.h5) $(PLOTS) | $(BIN)/elastica-auto
	$(BIN)/python -m elastica_auto.plots $(1) --data $(OUT) --out $(FIG)
endef

# Which figure reads which runs is written once, in the figure registry
# (elastica_auto/plots/paper.py); which run restarts from which, in the run files. The rules
# (FIGURE calls, restart chains, PAPER_RUNS) are generated from them into $(PAPER_RULES)
# whenever a goal other than those above is made. Make reads them before it makes any goal,
# even with -n: without a venv it creates one first.
PAPER_RULES = $(OUT)/.paper-rules.mk
ifneq ($(filter-out install demo test bench bench-auto clean,$(MAKECMDGOALS)),)
include $(PAPER_RULES)
endif
$(PAPER_RULES): elastica_auto/plots/paper.py elastica_auto/plots/__main__.py \
                $(wildcard $(RUNS)/*.toml) | $(if $(wildcard $(BIN)/python),,$(BIN)/elastica-auto)
	@mkdir -p $(@D)
	@$(BIN)/python -m elastica_auto.plots --make-rules --runs $(RUNS) > $@.tmp && mv $@.tmp $@

runs: $(PAPER_RUNS:%=$(OUT)/%.h5)

fig-rotating-arm: fig-rotating-arm-short fig-rotating-arm-long

figures: $(FIGURE_TARGETS)

# docs/img: reduced copies of the figures for docs/figures.md
gallery: figures
	$(BIN)/python -m elastica_auto.plots --gallery docs/img --out $(FIG)
