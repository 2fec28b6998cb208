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
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -q

bench: install
	$(BIN)/python benchmarks/bench.py
	$(BIN)/python benchmarks/bench.py --memory

clean:
	rm -rf $(OUT) $(FIG) .pytest_cache

# ---------------------------------------------------------------------------------------------
# The paper's experiments and figures (docs/figures.md). `make figures` computes every run a
# figure needs (out/<run>.h5 from runs/<run>.toml, in restart order) and draws figures/*.png and
# *.pdf. A branch file is recomputed only when its run file, the engine or a file it restarts
# from changed; a figure is redrawn only when its branch files or the plotting code changed.
RUNS   ?= runs
ENGINE  = $(wildcard elastica_auto/*.py equations/*.py)
PLOTS   = $(wildcard elastica_auto/plots/*.py)

.PHONY: figures runs gallery fig-rotating-arm

# restart chains: a run's file depends on the files its starts come from
$(OUT)/arm_length.h5 $(OUT)/rotating_load.h5 $(OUT)/rotating_base.h5: $(OUT)/rotating_arm.h5
$(OUT)/buckled_load.h5: $(OUT)/rotating_arm.h5
$(OUT)/rotating_arm_stable.h5: $(OUT)/buckled_load.h5
$(OUT)/load_magnitude.h5: $(OUT)/rotating_load.h5

# a run that ends with a failed branch (exit status 1) leaves no file behind for make to trust
$(OUT)/%.h5: $(RUNS)/%.toml $(ENGINE) | $(BIN)/elastica-auto
	$(BIN)/elastica-auto run $< --out $(OUT) -q || { rm -f $@; exit 1; }

PAPER_RUNS = rotating_arm trivial_buckling arm_length rotating_load load_magnitude \
             rotating_base buckled_load rotating_arm_stable
runs: $(PAPER_RUNS:%=$(OUT)/%.h5)

# $(call FIGURE,name,runs): target fig-<name> draws $(FIG)/<name with _>.png and .pdf
define FIGURE
FIGURE_TARGETS += fig-$(1)
.PHONY: fig-$(1)
fig-$(1): $(FIG)/$(subst -,_,$(1)).png $(FIG)/$(subst -,_,$(1)).pdf
$(FIG)/$(subst -,_,$(1)).png $(FIG)/$(subst -,_,$(1)).pdf &: $(2:%=$(OUT)/%.h5) $(PLOTS) | $(BIN)/elastica-auto
	$(BIN)/python -m elastica_auto.plots $(1) --data $(OUT) --out $(FIG)
endef

$(eval $(call FIGURE,critical-loads,trivial_buckling))                      # paper fig. 3
$(eval $(call FIGURE,rotating-arm-short,rotating_arm rotating_arm_stable))  # fig. 4
$(eval $(call FIGURE,rotating-arm-long,rotating_arm))                       # fig. 5
$(eval $(call FIGURE,arm-length-straight,rotating_arm arm_length))          # fig. 6
$(eval $(call FIGURE,arm-length-tilted,arm_length))                         # fig. 7
$(eval $(call FIGURE,rotating-load,rotating_load))                          # fig. 8
$(eval $(call FIGURE,load-magnitude-vertical,rotating_load load_magnitude)) # fig. 9
$(eval $(call FIGURE,load-magnitude-tilted,load_magnitude))                 # fig. 10
$(eval $(call FIGURE,rotating-base,rotating_base))                          # fig. 11
$(eval $(call FIGURE,rotating-base-snaps,rotating_base))                    # fig. 12

fig-rotating-arm: fig-rotating-arm-short fig-rotating-arm-long

figures: $(FIGURE_TARGETS)

# docs/img: reduced copies of the figures for docs/figures.md
gallery: figures
	$(BIN)/python -m elastica_auto.plots --gallery docs/img --out $(FIG)
