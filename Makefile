# Thermoviscoelastic double pendulum: EME and midpoint time integration with PETSc SNES.
#   make              build library, drivers and tests (installs missing apt packages first)
#   make run          the paper's Fig. 4 scenes (EME and midpoint, every variable) and Fig. 5
#                     scenes, a summary table, then the figures
#   make test         every test; the last line is "N passed, M failed"
#   make constraints  the constraints with EME_s and EME_u, and without conduction
#   make figures      the figures of `make run`'s files
#   make study        convergence, work-precision and stability studies, and their charts
#   make bench        ensemble throughput and per-step cost (benchmarks, not tests)
#   make clean        remove what the build made
SHELL := /bin/bash
# A failing command inside a pipeline (mpirun ... | tail) fails its recipe.
.SHELLFLAGS := -o pipefail -c
.DEFAULT_GOAL := all

BUILD := build
OBJ := $(BUILD)/obj
MOD := $(BUILD)/mod
BIN := $(BUILD)/bin
TESTBIN := $(BUILD)/tests
VENV := .venv
PYTHON := $(VENV)/bin/python

FC := mpif90
CC := mpicc
# Recursive '=' so that pkg-config runs after `deps` has installed PETSc and HDF5.
PETSC_FLAGS = $(shell pkg-config --cflags PETSc)
PETSC_LIBS = $(shell pkg-config --libs PETSc)
# Modules that use PETSc-typed modules need PETSc's module files, without its other flags.
PETSC_INCLUDES = $(shell pkg-config --cflags-only-I PETSc)
HDF5_FLAGS = $(shell pkg-config --cflags-only-I hdf5-openmpi)
HDF5_LIBS = $(shell pkg-config --libs-only-L hdf5-openmpi) -lhdf5_fortran -lhdf5
WARNINGS := -Wall -Wextra -fimplicit-none
FFLAGS := -O2 -g -fstack-arrays $(WARNINGS) -J$(MOD) -I$(MOD)
# Our own modules are standard Fortran 2018; PETSc's headers need long lines and no -std.
STD_FLAGS := -std=f2018
PETSC_SOURCE_FLAGS = -ffree-line-length-none $(PETSC_FLAGS)
CFLAGS := -O2 -g -Wall -Wextra -std=c11

# ---------------------------------------------------------------- sources
# Every source file is found by its folder: a new module needs no Makefile edit. Module
# dependencies are read from the `use` statements (a module lives in the file of its name).
LIBRARY_SOURCES := $(sort $(wildcard src/*/*.f90 src/*/*.F90 src/*/*.c))
LIBRARY_OBJECTS := $(patsubst %,$(OBJ)/%.o,$(basename $(LIBRARY_SOURCES)))
DRIVERS := $(basename $(notdir $(wildcard drivers/*.F90)))
UNIT_TESTS := $(basename $(notdir $(wildcard tests/unit/test_*.f90 tests/unit/test_*.F90)))
TEST_SUPPORT_SOURCES := $(wildcard tests/unit/support/*.f90 tests/oracles/*.f90)
TEST_SUPPORT := $(patsubst %,$(OBJ)/%.o,$(basename $(TEST_SUPPORT_SOURCES)))
FORTRAN_SOURCES := $(filter %.f90 %.F90,$(LIBRARY_SOURCES)) $(wildcard drivers/*.F90) $(TEST_SUPPORT_SOURCES) \
    $(wildcard tests/unit/test_*.f90 tests/unit/test_*.F90)

# obj: the objects of the modules it uses (only modules of this project have a source file).
$(BUILD)/fortran.deps: $(FORTRAN_SOURCES) Makefile
	@mkdir -p $(BUILD)
	@for f in $(FORTRAN_SOURCES); do \
	  for m in $$(sed -n 's/^ *use  *\([A-Za-z_0-9]*\).*/\1/p' $$f | tr A-Z a-z | sort -u); do \
	    for d in $(FORTRAN_SOURCES); do \
	      case $$d in */$$m.f90|*/$$m.F90) echo "$(OBJ)/$${f%.*}.o: $(OBJ)/$${d%.*}.o";; esac; \
	    done; \
	  done; \
	done > $@
-include $(BUILD)/fortran.deps

$(OBJ)/src/integrator/ts_domain.o: CFLAGS += $(PETSC_FLAGS)
# Callbacks, interface implementations and default implementations have fixed argument lists;
# some arguments are not needed.
$(OBJ)/src/solver/snes_solver.o $(OBJ)/src/solver/lu_preconditioner.o $(filter $(OBJ)/src/integrator/%,$(LIBRARY_OBJECTS)) \
$(OBJ)/src/model/length_constraint.o \
$(OBJ)/src/structure/temperature_constraint.o $(OBJ)/src/model/pendulum_scene.o \
$(OBJ)/src/model/pendulum_model.o $(OBJ)/tests/unit/support/single_spring_model.o $(OBJ)/src/model/invariant_function.o \
$(OBJ)/tests/unit/support/scripted_solver.o: FFLAGS += -Wno-unused-dummy-argument
$(patsubst %,$(OBJ)/tests/unit/%.o,$(UNIT_TESTS)): $(TEST_SUPPORT) $(LIBRARY_OBJECTS)
$(patsubst %,$(OBJ)/drivers/%.o,$(DRIVERS)): $(LIBRARY_OBJECTS)

# ---------------------------------------------------------------- rules
.PHONY: all deps test run constraints figures study bench clean

all: $(patsubst %,$(BIN)/%,$(DRIVERS)) $(patsubst %,$(TESTBIN)/%,$(UNIT_TESTS))

$(OBJ)/%.o: %.f90 | $(BUILD)/.native-deps
	@mkdir -p $(dir $@) $(MOD)
	$(FC) $(FFLAGS) $(STD_FLAGS) $(PETSC_INCLUDES) $(HDF5_FLAGS) -c $< -o $@

$(OBJ)/%.o: %.F90 | $(BUILD)/.native-deps
	@mkdir -p $(dir $@) $(MOD)
	$(FC) $(FFLAGS) $(PETSC_SOURCE_FLAGS) $(HDF5_FLAGS) -c $< -o $@

$(OBJ)/%.o: %.c | $(BUILD)/.native-deps
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) $(HDF5_FLAGS) -c $< -o $@


$(BIN)/%: $(OBJ)/drivers/%.o $(LIBRARY_OBJECTS)
	@mkdir -p $(dir $@)
	$(FC) $(FFLAGS) -o $@ $^ $(LINK_LIBS)

# LAPACK (the one PETSc uses) is called directly by the step solver's LU and the benchmark;
# SUNDIALS CVODE with its dense direct solver serves the CVODE baselines.
SUNDIALS_LIBS := -lsundials_cvode -lsundials_nvecserial -lsundials_sunmatrixdense -lsundials_sunlinsoldense
LINK_LIBS = $(PETSC_LIBS) $(HDF5_LIBS) $(SUNDIALS_LIBS) -llapack

$(TESTBIN)/%: $(OBJ)/tests/unit/%.o $(TEST_SUPPORT) $(LIBRARY_OBJECTS)
	@mkdir -p $(dir $@)
	$(FC) $(FFLAGS) -o $@ $^ $(LINK_LIBS)

# The code version is recompiled in only when `git describe` changes.
VERSION := $(shell git describe --always --dirty 2>/dev/null || echo unknown)
$(BUILD)/version.stamp: FORCE
	@mkdir -p $(BUILD)
	@echo '$(VERSION)' | cmp -s - $@ || echo '$(VERSION)' > $@
$(OBJ)/src/io/build_info.o: $(BUILD)/version.stamp
$(OBJ)/src/io/build_info.o: FFLAGS += -DEME_VERSION='"$(VERSION)"'
.PHONY: FORCE

# ---------------------------------------------------------------- set-up
# Debian packages for the native stack, then a virtual environment for h5py and friends.
NATIVE_PACKAGES := gfortran petsc-dev libhdf5-openmpi-dev libopenmpi-dev openmpi-bin pkg-config libsundials-dev
deps: $(BUILD)/.native-deps $(VENV)/.python-deps

$(BUILD)/.native-deps:
	@if command -v mpif90 >/dev/null && pkg-config --exists PETSc hdf5-openmpi && test -f /usr/include/cvode/cvode.h; then :; else \
	  echo "Installing $(NATIVE_PACKAGES) with apt-get"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(NATIVE_PACKAGES) >/dev/null; fi
	@mkdir -p $(BUILD) && touch $@

$(VENV)/.python-deps: postprocess/requirements.txt
	@python3 -m venv $(VENV) 2>/dev/null || { rm -rf $(VENV); echo "Installing python3-venv with apt-get"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv >/dev/null && \
	  python3 -m venv $(VENV); }
	$(VENV)/bin/pip install --quiet --disable-pip-version-check -r postprocess/requirements.txt
	@touch $@

# ---------------------------------------------------------------- use
PAPER_RUNS := $(foreach s,eme midpoint,$(foreach v,entropy theta internal_energy,paper_fig4_$(s)_$(v))) \
              paper_fig5_fixed_length paper_fig5_fixed_temperature paper_fig5_both
CONSTRAINT_RUNS := $(foreach c,fixed_length fixed_temperature,$(foreach v,entropy internal_energy,fig5_$(c)_eme_$(v))) \
                   $(foreach v,theta entropy internal_energy,fig5_fixed_temperature_no_conduction_eme_$(v))

# Runs every input of a list and prints the summary table of their files.
define run_and_summarize
	@mkdir -p results
	@for run in $(1); do $(BIN)/eme_run inputs/$$run.nml > /dev/null || exit 1; done
	@$(PYTHON) postprocess/summarize_runs.py $(foreach r,$(1),results/$(r).h5)
endef

run: all $(VENV)/.python-deps
	$(call run_and_summarize,$(PAPER_RUNS))
	@$(MAKE) --no-print-directory figures

# The paper's Figs. 3, 4 and 5 and the temperatures from the files `make run` wrote.
FIGURES := results/figures
EME_FILES := $(foreach v,entropy theta internal_energy,results/paper_fig4_eme_$(v).h5)
MIDPOINT_FILES := $(foreach v,entropy theta internal_energy,results/paper_fig4_midpoint_$(v).h5)
FIG5_FILES := $(foreach c,fixed_length fixed_temperature both,results/paper_fig5_$(c).h5)

figures: $(VENV)/.python-deps
	@for f in $(EME_FILES) $(MIDPOINT_FILES) $(FIG5_FILES); do test -f $$f || { echo "$$f is missing: run 'make run' first"; exit 1; }; done
	$(PYTHON) postprocess/plot_snapshots.py results/paper_fig4_eme_theta.h5 --times 0 8 16 -o $(FIGURES)/fig3_snapshots
	$(PYTHON) postprocess/plot_balance.py $(EME_FILES) -o $(FIGURES)/fig4_eme
	$(PYTHON) postprocess/plot_balance.py $(EME_FILES) --compare $(MIDPOINT_FILES) -o $(FIGURES)/fig4_eme_vs_midpoint
	$(PYTHON) postprocess/plot_constrained.py $(FIG5_FILES) -o $(FIGURES)/fig5_constrained
	$(PYTHON) postprocess/plot_temperatures.py $(EME_FILES) $(MIDPOINT_FILES) -o $(FIGURES)/temperatures_jz

# Convergence, work-precision and stability studies on 2 ranks, then their analysis: charts in
# results/figures, numbers in results/study/summary.h5 (README, Speed and accuracy).
STUDIES := convergence convergence_reference stability_paper stability_hard
MPIRUN := mpirun --allow-run-as-root --oversubscribe

# Each study prints its start, a progress line every 2 s and its summary.
study: all $(VENV)/.python-deps
	@for s in $(STUDIES); do rm -rf results/study/$$s; \
	  $(MPIRUN) -n 2 $(BIN)/eme_ensemble inputs/study_$$s.nml || exit 1; done
	$(PYTHON) postprocess/study_analysis.py --study-dir results/study -o results/figures \
	  --summary results/study/summary.h5

# Benchmarks (not tests): the ensemble's throughput on 1 and 2 ranks, then the per-step cost
# of every scheme against a LAPACK Newton floor. The last line is machine-readable.
bench: all $(VENV)/.python-deps
	@echo "machine: $$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $$(nproc) cores, $$(uname -sr)"
	$(PYTHON) postprocess/bench_ensemble.py --repeats 3
	$(BIN)/eme_bench 21

# The constraint scenes for EME_s and EME_u, and g2 without conduction (README, Constraints).
constraints: all $(VENV)/.python-deps
	$(call run_and_summarize,$(CONSTRAINT_RUNS))

test: all $(VENV)/.python-deps
	$(PYTHON) tests/run_tests.py --bin $(TESTBIN)

clean:
	rm -rf $(BUILD)
