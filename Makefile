# Thermoviscoelastic double pendulum: EME and midpoint time integration with PETSc SNES.
#   make              build library, drivers and tests (installs missing apt packages first)
#   make run          the paper's Fig. 4 scenes (EME and midpoint, every variable) and Fig. 5
#                     scenes, a summary table, then the figures
#   make test         every test; the last line is "N passed, M failed"
#   make constraints  the constraints with EME_s and EME_u, and without conduction
#   make figures      the figures of the paper scenes (runs what is missing or outdated first)
#   make study        convergence, work-precision and stability studies, and their charts
#   make study-chain  the spring chain's stability map, work-precision chart and temperature picture
#   make bench        ensemble throughput, per-step cost and instructions (benchmarks, not tests)
#   make python-lock  pin every Python package anew after postprocess/requirements.txt changed
#   make generate     regenerate the Fortran of every model description (src/model/*/description.py)
#   make new-model NAME=x  start src/model/x/description.py from the template
#   make clean        remove what the build made
SHELL := /bin/bash
# A failing command inside a pipeline (mpirun ... | tail) fails its recipe.
.SHELLFLAGS := -o pipefail -c
.DEFAULT_GOAL := all

BUILD := build
OBJ := $(BUILD)/obj
MOD := $(BUILD)/mod
BIN := $(BUILD)/bin
VENV := .venv
PYTHON := $(VENV)/bin/python

FC := mpif90
CC := mpicc
# PETSC_FLAGS, PETSC_LIBS, PETSC_INCLUDES (PETSc's include flags alone, for modules that use
# PETSc-typed modules), HDF5_FLAGS, HDF5_LIBS, SUNDIALS_FLAGS and SUNDIALS_LDFLAGS come from
# build/config.mk (section set-up).
WARNINGS := -Wall -Wextra -fimplicit-none
# Optimization of the step kernel (src/scheme, src/model, the LU) and the instruction set
# (docs/performance.md). Never -ffast-math: the structure-preserving residual needs IEEE
# semantics and its NaN checks. ARCH_FLAGS is empty, so the binaries run on any x86-64 CPU;
# `make clean && make ARCH_FLAGS=-march=native` builds for this machine's CPU only.
# The kernel's objects carry link-time-optimization code as well (fat objects): the programs in
# build/bin are linked with LTO, which inlines the spring potentials and discrete-gradient parts
# across modules (12 % off the floor's step, 7 % off SNES's, docs/performance.md); the unit
# tests link the plain code (PROGRAM_LINK_FLAGS, TEST_LINK_FLAGS), which keeps their build short.
# -fno-tree-loop-distribute-patterns keeps the zeroing and copying of the kernel's arrays of 2 to
# 18 numbers inline instead of calls to memset and memcpy (about 150 a step; 5 % off the floor's
# and SNES's step, docs/performance.md).
KERNEL_FLAGS ?= -O3 -flto=auto -ffat-lto-objects -fno-tree-loop-distribute-patterns
PROGRAM_LINK_FLAGS ?= -flto=auto
TEST_LINK_FLAGS ?= -fno-lto
ARCH_FLAGS ?=
FFLAGS := -O2 -g -fstack-arrays $(WARNINGS) -J$(MOD) -I$(MOD) $(ARCH_FLAGS)
# Our own modules are standard Fortran 2018; PETSc's headers need long lines and no -std.
STD_FLAGS := -std=f2018
PETSC_SOURCE_FLAGS = -ffree-line-length-none $(PETSC_FLAGS)
CFLAGS := -O2 -g -Wall -Wextra -std=c11 $(ARCH_FLAGS)

# ---------------------------------------------------------------- sources
# Every source file is found by its folder: a new module needs no Makefile edit. Module
# dependencies are read from the `use` statements (a module lives in the file of its name).
LIBRARY_SOURCES := $(sort $(wildcard src/*/*.f90 src/*/*.F90 src/*/*.c src/*/*/*.f90 src/*/*/*.F90 src/*/*/*.c))
LIBRARY_OBJECTS := $(patsubst %,$(OBJ)/%.o,$(basename $(LIBRARY_SOURCES)))
DRIVERS := $(basename $(notdir $(wildcard drivers/*.F90)))
# Programs in C on SUNDIALS CVODE alone, compiled and linked without MPI, PETSc or HDF5
# (drivers/cvode_baseline.c: the whole-run baseline of make bench).
CVODE_C_DRIVERS := cvode_baseline
# Programs in C that need PETSc alone (drivers/snes_overhead.c: PETSc SNES timed by itself).
C_DRIVERS := $(filter-out $(CVODE_C_DRIVERS),$(basename $(notdir $(wildcard drivers/*.c))))
FORTRAN_SOURCES := $(filter %.f90 %.F90,$(LIBRARY_SOURCES)) $(wildcard drivers/*.F90)

# obj: the objects of the modules it uses, and a submodule's of its parent (only modules of this
# project have a source file).
$(BUILD)/fortran.deps: $(FORTRAN_SOURCES) Makefile
	@mkdir -p $(BUILD)
	@for f in $(FORTRAN_SOURCES); do \
	  for m in $$(sed -n 's/^ *use  *\([A-Za-z_0-9]*\).*/\1/p; s/^ *submodule *( *\([A-Za-z_0-9]*\) *).*/\1/p' $$f | \
	              tr A-Z a-z | sort -u); do \
	    for d in $(FORTRAN_SOURCES); do \
	      case $$d in */$$m.f90|*/$$m.F90) echo "$(OBJ)/$${f%.*}.o: $(OBJ)/$${d%.*}.o";; esac; \
	    done; \
	  done; \
	done > $@
-include $(BUILD)/fortran.deps

$(OBJ)/src/integrator/ts_domain.o $(OBJ)/src/io/version_queries.o $(OBJ)/src/io/petsc_option_checks.o $(OBJ)/src/io/petsc_errors.o \
$(OBJ)/src/io/petsc_option_files.o \
$(OBJ)/src/solver/petsc_options.o $(OBJ)/src/solver/dense_read.o $(OBJ)/src/solver/vector_access.o $(OBJ)/src/solver/converged_reasons.o \
$(patsubst %,$(OBJ)/drivers/%.o,$(C_DRIVERS)): private CFLAGS += $(PETSC_FLAGS)
# Callbacks, interface implementations and default implementations have fixed argument lists;
# some arguments are not needed. By folder (a model's folder included), so a new module needs no
# edit here.
$(filter $(OBJ)/src/solver/% $(OBJ)/src/structure/% $(OBJ)/src/integrator/% $(OBJ)/src/model/%,$(LIBRARY_OBJECTS)): \
  private FFLAGS += -Wno-unused-dummy-argument
# The solver's modules that run in every Newton iteration (the SNES callbacks, norms, vector
# accessors, the modified Newton's record and tests) and EME's stepper too: LTO inlines the norms
# and the record's tests into the callbacks (docs/performance.md, Issue 42: EME's step through
# SNESSolve, 76,297 to 73,605 instructions; the stepper 84 more).
KERNEL_SOLVER_OBJECTS := $(patsubst %,$(OBJ)/src/solver/%.o,dense_lu snes_shell euclidean_norm vector_arrays \
  modified_newton retry_strategies hand_newton snes_solver) $(OBJ)/src/integrator/discrete_gradient_stepper.o
$(filter $(OBJ)/src/scheme/% $(OBJ)/src/model/% $(KERNEL_SOLVER_OBJECTS),$(LIBRARY_OBJECTS)): private FFLAGS += $(KERNEL_FLAGS)
# Every library object depends on the flags it is compiled with: $(OBJ)/flags holds them (the
# compilers, the common flags, the kernel's and which objects take them) and is rewritten only
# when they change, so that a flag edited here recompiles the objects instead of leaving them
# built with the old flags (a working tree's bench read 66,402 instructions an EME step, a fresh
# build 64,288, after the solver's objects joined the kernel's flags).
COMPILE_FLAGS_TEXT := $(FC) $(CC) $(FFLAGS) $(STD_FLAGS) $(CFLAGS) $(KERNEL_FLAGS) $(KERNEL_SOLVER_OBJECTS)
$(shell mkdir -p $(OBJ) && { printf '%s\n' '$(COMPILE_FLAGS_TEXT)' | cmp -s - $(OBJ)/flags || \
  printf '%s\n' '$(COMPILE_FLAGS_TEXT)' > $(OBJ)/flags; })
$(OBJ)/flags: ;
$(LIBRARY_OBJECTS): $(OBJ)/flags
# A driver is recompiled when a module it uses changes (fortran.deps); the others only come first.
$(patsubst %,$(OBJ)/drivers/%.o,$(DRIVERS)): | $(LIBRARY_OBJECTS)

# ---------------------------------------------------------------- rules
.PHONY: all programs deps test check run constraints figures study study-chain bench bench-deps clean python-lock version docs \
        generate new-model

# The programs alone (make run, figures, study, bench and constraints need no unit tests).
PROGRAMS := $(patsubst %,$(BIN)/%,$(DRIVERS) $(C_DRIVERS) $(CVODE_C_DRIVERS))
programs: $(PROGRAMS)
all: $(PROGRAMS)

$(OBJ)/%.o: %.f90 | $(BUILD)/.native-deps
	@mkdir -p $(dir $@) $(MOD)
	$(FC) $(FFLAGS) $(STD_FLAGS) $(PETSC_INCLUDES) $(HDF5_FLAGS) -c $< -o $@

$(OBJ)/%.o: %.F90 | $(BUILD)/.native-deps
	@mkdir -p $(dir $@) $(MOD)
	$(FC) $(FFLAGS) $(PETSC_SOURCE_FLAGS) $(HDF5_FLAGS) -c $< -o $@

# -MMD: the compiler lists the headers a C file includes (src/io/hdf5_snapshot_storage.h) in a .d
# file beside its object, so that an edited header recompiles the files that include it.
$(OBJ)/%.o: %.c | $(BUILD)/.native-deps
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -MMD -MP $(HDF5_FLAGS) $(SUNDIALS_FLAGS) -c $< -o $@
-include $(patsubst %,$(OBJ)/%.d,$(basename $(filter %.c,$(LIBRARY_SOURCES))))


$(BIN)/%: $(OBJ)/drivers/%.o $(LIBRARY_OBJECTS)
	@mkdir -p $(dir $@)
	$(FC) $(FFLAGS) $(PROGRAM_LINK_FLAGS) -o $@ $^ $(LINK_LIBS)

$(patsubst %,$(BIN)/%,$(C_DRIVERS)): $(BIN)/%: $(OBJ)/drivers/%.o
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -o $@ $< $(PETSC_LIBS) -lm

# The C compiler itself, not MPI's wrapper, for the programs on SUNDIALS alone.
SERIAL_CC ?= cc
$(patsubst %,$(OBJ)/drivers/%.o,$(CVODE_C_DRIVERS)): $(OBJ)/drivers/%.o: drivers/%.c | $(BUILD)/.native-deps
	@mkdir -p $(dir $@)
	$(SERIAL_CC) $(CFLAGS) $(SUNDIALS_FLAGS) -c $< -o $@
$(patsubst %,$(BIN)/%,$(CVODE_C_DRIVERS)): $(BIN)/%: $(OBJ)/drivers/%.o
	@mkdir -p $(dir $@)
	$(SERIAL_CC) $(CFLAGS) -o $@ $< $(SUNDIALS_LDFLAGS) $(CVODE_LIBS) -lsundials_arkode -lm

# Test helpers built with the programs, in build/tests (build/bin holds the programs alone):
# snapshot_probe writes snapshots of known values from every MPI rank through hdf5_snapshots
# (tests/e2e/test_snapshots.py); chain_field_probe writes the split chain's field and Jacobian
# for PETSc TS beside the dense model's (tests/e2e/test_chain_ts.py).
TEST_HELPERS := $(BUILD)/tests/snapshot_probe $(BUILD)/tests/chain_field_probe
all: $(TEST_HELPERS)
$(OBJ)/tests/e2e/snapshot_probe.o: $(OBJ)/src/io/hdf5_snapshots.o $(OBJ)/src/util/failures.o
$(OBJ)/tests/e2e/chain_field_probe.o: $(OBJ)/src/io/run_config.o $(OBJ)/src/model/spring_chain/spring_chain_sparse_run.o
$(TEST_HELPERS): $(BUILD)/tests/%: $(OBJ)/tests/e2e/%.o $(LIBRARY_OBJECTS)
	@mkdir -p $(dir $@)
	$(FC) $(FFLAGS) $(TEST_LINK_FLAGS) -o $@ $^ $(LINK_LIBS)

# LAPACK and BLAS (the ones PETSc uses): --version reports LAPACK's, and the LU's unit test compares with it;
# SUNDIALS CVODE with its dense direct solver serves the CVODE baselines (BDF with Newton), and
# its fixed-point solver CVODE-Adams (cvode_baseline also takes ARKODE's explicit steps); zlib (HDF5's own dependency) gives the CRC-32 of a file's
# texts (src/io/hdf5_text_checksum.c).
CVODE_LIBS := -lsundials_cvode -lsundials_nvecserial -lsundials_sunmatrixdense -lsundials_sunlinsoldense
SUNDIALS_LIBS := $(CVODE_LIBS) -lsundials_sunnonlinsolfixedpoint
LINK_LIBS = $(PETSC_LIBS) $(HDF5_LIBS) $(SUNDIALS_LDFLAGS) $(SUNDIALS_LIBS) -llapack -lblas -lz

# ---------------------------------------------------------------- unit tests
# The suites tests/unit/test_*.pf are pFUnit tests (tests/README.md). They run under pFUnit when
# PFUNIT_DIR names an installation (make test PFUNIT_DIR=...; with its include/PFUNIT.mk) or one
# is found where .ci/run builds it, ~/.cache/pfunit-4.14/PFUNIT-4.14; else (PFUNIT_DIR=none, or
# none found) under the fallback runner of tests/unit/fallback, which reads the same files. Each
# runner builds in a folder of its own, build/unit-<runner>, one program per suite in its bin/.
PFUNIT_DIR ?= $(firstword $(wildcard $(HOME)/.cache/pfunit-4.14/PFUNIT-4.14))
UNIT_RUNNER := $(if $(wildcard $(PFUNIT_DIR)/include/PFUNIT.mk),pfunit,fallback)
UNIT := $(BUILD)/unit-$(UNIT_RUNNER)
TESTBIN := $(UNIT)/bin
UNIT_SUITES := $(basename $(notdir $(wildcard tests/unit/test_*.pf)))
UNIT_PROGRAMS := $(patsubst %,$(TESTBIN)/%,$(UNIT_SUITES))
UNIT_OBJECTS := $(patsubst %,$(UNIT)/%.o,$(UNIT_SUITES))
UNIT_DRIVERS := $(patsubst %,$(UNIT)/%_driver.o,$(UNIT_SUITES))
all: $(UNIT_PROGRAMS)
# The hand-derived double pendulum (pendulum_model and its field and elastic springs: the reference
# the generated rungs are tested against) is test support since eme_run runs the generated rungs, and
# so are the hand-derived springs (free_energy, thermo_variable) since the fused kernel runs the
# generated element of the paper's spring (src/model/paper_spring).
TEST_SUPPORT := $(patsubst %,$(UNIT)/%.o,close_values free_energy thermo_variable fixtures scripted_solver \
                single_spring_model paper_free_energy model_conformance pendulum_model pendulum_vector_field \
                elastic_potential spring_chain_blocks_reference)
UNIT_INCLUDES = -I$(UNIT)/mod $(filter-out -J$(MOD),$(FFLAGS)) -Wno-unused-dummy-argument
UNIT_FFLAGS = -J$(UNIT)/mod $(UNIT_INCLUDES)
ifeq ($(UNIT_RUNNER),pfunit)
include $(PFUNIT_DIR)/include/PFUNIT.mk
# pFUnit's generated suite builders declare what they may not use: their warnings are not ours
# (the fallback build compiles the same test code with every warning).
UNIT_FLAGS = $(PFUNIT_EXTRA_FFLAGS) -Wno-unused-variable -Wno-uninitialized
UNIT_LIBS = $(PFUNIT_LIBRARIES)
FUNIT :=
$(UNIT)/%.F90: tests/unit/%.pf | $(UNIT)/mod
	$(PFUNIT_BIN_DIR)/funitproc $< $@ > /dev/null
$(UNIT)/%_suites.inc: | $(UNIT)/mod
	echo 'ADD_TEST_SUITE($*_suite)' > $@
# pFUnit's driver.F90 holds a module of its own (loader): each suite's copy writes it apart.
$(UNIT_DRIVERS): $(UNIT)/%_driver.o: $(UNIT)/%_suites.inc $(UNIT)/%.o
	@mkdir -p $(UNIT)/$*_driver
	$(FC) -J$(UNIT)/$*_driver $(UNIT_INCLUDES) -ffree-line-length-none $(UNIT_FLAGS) -D_TEST_SUITES='"$<"' \
	  -c $(PFUNIT_INCLUDE_DIR)/driver.F90 -o $@
else
UNIT_FLAGS :=
UNIT_LIBS :=
# The fallback's module funit, in place of pFUnit's.
FUNIT := $(UNIT)/funit.o
$(UNIT)/%.F90 $(UNIT)/%_driver.F90: tests/unit/%.pf tests/unit/fallback/pf_lite.py tests/unit/fallback/driver_template.F90 | $(UNIT)/mod
	python3 tests/unit/fallback/pf_lite.py $< $(UNIT)
$(UNIT_DRIVERS): $(UNIT)/%_driver.o: $(UNIT)/%_driver.F90 $(UNIT)/%.o
	$(FC) $(UNIT_FFLAGS) -ffree-line-length-none -c $< -o $@
$(UNIT)/funit.o: tests/unit/fallback/funit.f90 | $(UNIT)/mod
	$(FC) $(UNIT_FFLAGS) $(STD_FLAGS) -c $< -o $@
endif
$(UNIT)/mod:
	@mkdir -p $@
# Test support (tests/unit/support, tests/oracles), then each suite, then its driver.
$(UNIT)/%.o: tests/unit/support/%.f90 $(FUNIT) $(LIBRARY_OBJECTS) | $(UNIT)/mod
	$(FC) $(UNIT_FFLAGS) $(STD_FLAGS) $(UNIT_FLAGS) $(PETSC_INCLUDES) -c $< -o $@
$(UNIT)/%.o: tests/oracles/%.f90 $(LIBRARY_OBJECTS) | $(UNIT)/mod
	$(FC) $(UNIT_FFLAGS) $(STD_FLAGS) -c $< -o $@
$(UNIT)/fixtures.o: $(UNIT)/close_values.o $(UNIT)/paper_free_energy.o $(UNIT)/pendulum_model.o
$(UNIT)/pendulum_model.o: $(UNIT)/pendulum_vector_field.o $(UNIT)/elastic_potential.o $(UNIT)/thermo_variable.o
$(UNIT)/thermo_variable.o $(UNIT)/pendulum_vector_field.o $(UNIT)/elastic_potential.o: $(UNIT)/free_energy.o
$(UNIT)/single_spring_model.o: $(UNIT)/free_energy.o $(UNIT)/thermo_variable.o
$(UNIT)/model_conformance.o: $(UNIT)/close_values.o
$(UNIT_OBJECTS): $(UNIT)/%.o: $(UNIT)/%.F90 $(TEST_SUPPORT) $(FUNIT) $(LIBRARY_OBJECTS)
	$(FC) $(UNIT_FFLAGS) $(PETSC_SOURCE_FLAGS) $(HDF5_FLAGS) $(UNIT_FLAGS) -c $< -o $@
$(TESTBIN)/%: $(UNIT)/%_driver.o $(UNIT)/%.o $(TEST_SUPPORT) $(FUNIT) $(LIBRARY_OBJECTS)
	@mkdir -p $(dir $@)
	$(FC) $(FFLAGS) $(TEST_LINK_FLAGS) -o $@ $^ $(UNIT_LIBS) $(LINK_LIBS)
# The generated sources are kept for reading the failures' lines.
.PRECIOUS: $(UNIT)/%.F90 $(UNIT)/%_driver.F90 $(UNIT)/%_suites.inc

# The code's version: the release number of the file VERSION and, in a git checkout, `git describe`
# ("0.9.0 (git cb77f99-dirty)"); a source tarball without .git has the release number alone. It
# is recompiled in only when it changes. `make version` prints it.
RELEASE := $(shell cat VERSION 2>/dev/null || echo unknown)
GIT_DESCRIPTION := $(shell [ "$$(git rev-parse --show-toplevel 2>/dev/null)" = "$(CURDIR)" ] && \
                     git describe --always --dirty 2>/dev/null)
VERSION := $(RELEASE)$(if $(GIT_DESCRIPTION), (git $(GIT_DESCRIPTION)))
$(BUILD)/version.stamp: FORCE
	@mkdir -p $(BUILD)
	@echo '$(VERSION)' | cmp -s - $@ || echo '$(VERSION)' > $@
$(OBJ)/src/io/build_info.o: $(BUILD)/version.stamp VERSION
$(OBJ)/src/io/build_info.o: private FFLAGS += -DEME_VERSION='"$(VERSION)"'
# The programs in C (snes_overhead, cvode_baseline) print the same version.
$(patsubst %,$(OBJ)/drivers/%.o,$(C_DRIVERS) $(CVODE_C_DRIVERS)): $(BUILD)/version.stamp VERSION
$(patsubst %,$(OBJ)/drivers/%.o,$(C_DRIVERS) $(CVODE_C_DRIVERS)): private CFLAGS += -DEME_VERSION='"$(VERSION)"'
.PHONY: FORCE

# ---------------------------------------------------------------- set-up
# The native libraries: setup/configure.sh finds them (PETSC_DIR and PETSC_ARCH, HDF5_DIR or
# pkg-config or h5pfc/h5fc, SUNDIALS_DIR), installs what is missing with apt-get on Debian as
# root, or else says what to install (Debian, Spack, conda-forge) and stops. Their flags go to
# build/config.mk, which make includes and so remakes first. Then a virtual environment with the
# Python packages of postprocess/requirements.txt, every package pinned by requirements.lock.
NATIVE_PACKAGES := gfortran petsc-dev libhdf5-openmpi-dev libopenmpi-dev openmpi-bin pkg-config libsundials-dev
SETUP_SETTINGS := PETSC_DIR=$(PETSC_DIR) PETSC_ARCH=$(PETSC_ARCH) HDF5_DIR=$(HDF5_DIR) SUNDIALS_DIR=$(SUNDIALS_DIR) \
                  FC=$(FC) CC=$(CC)
PYTHON_REQUIREMENTS := postprocess/requirements.txt
PYTHON_LOCK := postprocess/requirements.lock
deps: $(BUILD)/.native-deps $(VENV)/.python-deps

# Every goal but these needs the libraries (no goal means `all`).
ifneq ($(filter-out clean python-lock version docs,$(or $(MAKECMDGOALS),all)),)
include $(BUILD)/config.mk
endif

# Reconfigures when the settings change.
$(BUILD)/setup.stamp: FORCE
	@mkdir -p $(BUILD)
	@echo '$(SETUP_SETTINGS)' | cmp -s - $@ || echo '$(SETUP_SETTINGS)' > $@

$(BUILD)/config.mk: setup/configure.sh $(BUILD)/setup.stamp
	@NATIVE_PACKAGES='$(NATIVE_PACKAGES)' $(SETUP_SETTINGS) sh setup/configure.sh $@

$(BUILD)/.native-deps: $(BUILD)/config.mk
	@touch $@

$(VENV)/.python-deps: $(PYTHON_REQUIREMENTS) $(PYTHON_LOCK) setup/check_python_lock.py
	@python3 setup/check_python_lock.py $(PYTHON_REQUIREMENTS) $(PYTHON_LOCK)
	@python3 -m venv $(VENV) 2>/dev/null || { rm -rf $(VENV); \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then echo "Installing python3-venv with apt-get"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv >/dev/null && \
	    python3 -m venv $(VENV); \
	  else echo "python3 -m venv does not work: install python3-venv (Debian: apt-get install python3-venv)," \
	    "or put a Python with venv first on PATH (conda: conda install python)" >&2; exit 1; fi; }
	$(VENV)/bin/pip install --quiet --disable-pip-version-check -r $(PYTHON_REQUIREMENTS) -c $(PYTHON_LOCK)
	@$(VENV)/bin/python setup/check_python_lock.py --installed $(PYTHON_LOCK)
	@touch $@

# Regenerates the lock after requirements.txt changed: a fresh environment, what pip installs
# for requirements.txt today, frozen. Commit both files.
python-lock:
	rm -rf $(BUILD)/lock-venv
	python3 -m venv $(BUILD)/lock-venv
	$(BUILD)/lock-venv/bin/pip install --quiet --disable-pip-version-check -r $(PYTHON_REQUIREMENTS)
	{ echo "# Every Python package of .venv, pinned. Generated by 'make python-lock' from $(PYTHON_REQUIREMENTS)"; \
	  echo "# ($$($(BUILD)/lock-venv/bin/python --version), $$(date -u +%Y-%m-%d)); do not edit by hand."; \
	  $(BUILD)/lock-venv/bin/pip freeze; } > $(PYTHON_LOCK)
	rm -rf $(BUILD)/lock-venv

# ---------------------------------------------------------------- use
PAPER_RUNS := $(foreach s,eme midpoint,$(foreach v,entropy theta internal_energy,paper_fig4_$(s)_$(v))) \
              $(foreach s,rk4 rk8 dp853 gauss6,paper_fig4_relaxed_$(s)) \
              paper_fig5_fixed_length paper_fig5_fixed_temperature paper_fig5_both
CONSTRAINT_RUNS := $(foreach c,fixed_length fixed_temperature,$(foreach v,entropy internal_energy,fig5_$(c)_eme_$(v))) \
                   $(foreach c,fixed_length fixed_temperature both,$(foreach s,relaxed_rk8 relaxed_gauss6,fig5_$(c)_$(s))) \
                   $(foreach v,theta entropy internal_energy,fig5_fixed_temperature_no_conduction_eme_$(v))

# A run file from its input: inputs/NAME.nml writes results/NAME.h5 (its &output file). An
# earlier file is removed first; a run that stops early keeps its file as results/NAME.h5.failed
# (marked incomplete inside), so that the next make runs it again.
results/%.h5: inputs/%.nml $(BIN)/eme_run
	@mkdir -p results
	@rm -f $@ $@.failed
	@$(BIN)/eme_run $< > /dev/null || { status=$$?; test -f $@ && mv $@ $@.failed && \
	  echo "$<: eme_run stopped (exit status $$status); its file is kept as $@.failed"; exit $$status; }
	@test -f $@ || { echo "$< did not write $@: its &output file must be $@"; exit 1; }

# Runs every input of a list (again, even when its file is newer than the input) and prints
# the summary table of their files.
define run_and_summarize
	@rm -f $(foreach r,$(1),results/$(r).h5)
	@$(MAKE) --no-print-directory $(foreach r,$(1),results/$(r).h5)
	@$(PYTHON) postprocess/summarize_runs.py $(foreach r,$(1),results/$(r).h5)
endef

run: programs $(VENV)/.python-deps
	$(call run_and_summarize,$(PAPER_RUNS))
	@$(MAKE) --no-print-directory figures

# The paper's Figs. 3, 4 and 5 and the temperatures, each drawn from the run files it shows;
# a missing or outdated run file is run first (rule above), so this works from a clean clone.
FIGURES := results/figures
EME_FILES := $(foreach v,entropy theta internal_energy,results/paper_fig4_eme_$(v).h5)
MIDPOINT_FILES := $(foreach v,entropy theta internal_energy,results/paper_fig4_midpoint_$(v).h5)
FIG5_FILES := $(foreach c,fixed_length fixed_temperature both,results/paper_fig5_$(c).h5)
PLOT_DEPS := postprocess/plotting.py postprocess/trajectory.py postprocess/integrators.py $(VENV)/.python-deps
FIGURE_FILES := $(foreach f,fig2_structure fig3_snapshots fig4_eme fig4_eme_vs_midpoint fig5_constrained \
                temperatures_jz,$(FIGURES)/$(f).png)

figures: $(FIGURE_FILES)

# Fig. 2: L and K of eq. (8) at the paper scene's initial state, for each thermodynamic variable.
results/structure.h5: inputs/paper_fig3.nml $(BIN)/eme_structure
	@mkdir -p results
	$(BIN)/eme_structure $< $@
$(FIGURES)/fig2_structure.png: results/structure.h5 postprocess/plot_structure.py $(PLOT_DEPS)
	$(PYTHON) postprocess/plot_structure.py $< -o $(basename $@)
# Fig. 3 at the paper's times 0, 8, 16 and 24 s, from the EME_theta run on [0, 24] s.
$(FIGURES)/fig3_snapshots.png: results/paper_fig3.h5 postprocess/plot_snapshots.py $(PLOT_DEPS)
	$(PYTHON) postprocess/plot_snapshots.py $< --times 0 8 16 24 -o $(basename $@)
$(FIGURES)/fig4_eme.png: $(EME_FILES) postprocess/plot_balance.py $(PLOT_DEPS)
	$(PYTHON) postprocess/plot_balance.py $(EME_FILES) -o $(basename $@)
$(FIGURES)/fig4_eme_vs_midpoint.png: $(EME_FILES) $(MIDPOINT_FILES) postprocess/plot_balance.py $(PLOT_DEPS)
	$(PYTHON) postprocess/plot_balance.py $(EME_FILES) --compare $(MIDPOINT_FILES) -o $(basename $@)
$(FIGURES)/fig5_constrained.png: $(FIG5_FILES) postprocess/plot_constrained.py $(PLOT_DEPS)
	$(PYTHON) postprocess/plot_constrained.py $(FIG5_FILES) -o $(basename $@)
$(FIGURES)/temperatures_jz.png: $(EME_FILES) $(MIDPOINT_FILES) postprocess/plot_temperatures.py $(PLOT_DEPS)
	$(PYTHON) postprocess/plot_temperatures.py $(EME_FILES) --compare $(MIDPOINT_FILES) -o $(basename $@)

# Convergence, work-precision and stability studies on 2 ranks, then their analysis: charts in
# results/figures, numbers in results/study/summary.h5 (docs/performance.md). The gas containers'
# work-precision and stability studies (GAS_STUDIES) go beside the pendulum's in the same charts.
HARD_SCENES := low_viscosity stiff_spring high_conductivity temperature_gap
GAS_STUDIES := gas_work_precision gas_work_precision_adaptive gas_work_precision_step_control \
               gas_work_precision_reference gas_stability
# The spring ladder's published scenes (issue 32): their stability maps beside the paper scene's.
LADDER_STUDIES := stability_gonzalez_elastic stability_romero_thermoelastic
STUDIES := convergence convergence_reference work_precision work_precision_adaptive work_precision_step_control \
           work_precision_reference stability_paper stability_hard \
           $(foreach s,$(HARD_SCENES),stability_$(s) stability_$(s)_tolerance) $(GAS_STUDIES) $(LADDER_STUDIES)
MPIRUN := mpirun --allow-run-as-root --oversubscribe

# Each study prints its start, a progress line every 2 s and its summary; the machine's load around
# it goes to results/study/NAME.load.json (postprocess/machine_load.py), for the charts' captions.
study: programs $(VENV)/.python-deps
	@for s in $(STUDIES); do rm -rf results/study/$$s results/study/$$s.load.json; \
	  $(PYTHON) postprocess/machine_load.py --record results/study/$$s.load.json --own 2 -- \
	    $(MPIRUN) -n 2 $(BIN)/eme_ensemble inputs/study_$$s.nml || exit 1; done
	$(PYTHON) postprocess/study_analysis.py --study-dir results/study -o results/figures \
	  --summary results/study/summary.h5
	$(PYTHON) postprocess/estimate_tracking.py --bin $(BIN) -o results/figures/estimate_tracking \
	  --data results/study/estimate_tracking.h5
	@$(MAKE) --no-print-directory study-chain

# The spring chain's rod family (issue 39 item 7, docs/performance.md): the stability map over
# (N, dt) and the work-precision chart, each from eme_ensemble studies that chain_study.py writes
# into results/study (its numbers in results/study/chain_*.csv), and the temperatures along the
# chain over time from the run of inputs/chain_rod_heat.nml. The map's dense runs at 1000 unknowns
# need more than the usual 8 MB of stack: chain_study.py raises its children's limit.
study-chain: programs $(VENV)/.python-deps
	rm -rf results/study/chain_stability results/study/chain_work_precision
	$(PYTHON) postprocess/chain_study.py stability --bin $(BIN) --study-dir results/study -o results/figures
	$(PYTHON) postprocess/chain_study.py work-precision --bin $(BIN) --study-dir results/study -o results/figures
	$(BIN)/eme_run inputs/chain_rod_heat.nml -eme_overwrite
	$(PYTHON) postprocess/plot_chain_temperatures.py results/chain_rod_heat.h5 -o results/figures/chain_temperatures

# Benchmarks (not tests): the ensemble's throughput on 1 and 2 ranks, the CPU time to 1e-4 and
# 1e-6 at t = 5 s of every scheme, the per-step cost of every scheme against a hand-written
# Newton floor, then issue 22's four speed ratios, each on its own line with its target
# (bench_eme_run.py: eme_run and eme_bench alternating), and PETSc SNES timed by itself
# (snes_overhead) beside what the ratios leave it; then issue 34's ratios against CVODE-BDF on
# the same model (bench_cvode_baseline.py): instructions per step by callgrind, and a whole
# eme_run against the C program with CVODE alone (cvode_baseline); then issue 42's instructions
# per evaluation of the paper scene's field, eme's (field_bench) against the C one's
# (bench_field.py), and relaxed_dp853's instructions against ARKODE's Dormand-Prince 5(4) at
# every error decade (bench_arkode.py); then issue 32's cost per
# step of each rung of the pendulum (bench_rungs.py: spatial and planar, thermoviscoelastic and
# thermoelastic, and the full model on the generic path, in instructions and alternating in
# time, against the full model; target 0.7 for the planar thermoelastic step); then the spring
# chain on the sparse path against its size, 1e3 to 1e5 springs, and on two ranks (bench_chain.py,
# docs/performance.md). Each part ends with
# machine-readable lines and the machine's load around it (postprocess/machine_load.py; a
# warning when it was busy).
bench: programs $(VENV)/.python-deps bench-deps
	@echo "machine: $$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $$(nproc) cores, $$(uname -sr)"
	$(PYTHON) postprocess/bench_ensemble.py --repeats 3
	$(PYTHON) postprocess/machine_load.py --record results/bench/eme_accuracy_bench.load.json -- $(BIN)/eme_accuracy_bench 5
	$(PYTHON) postprocess/machine_load.py --record results/bench/eme_bench.load.json -- $(BIN)/eme_bench 21
	$(PYTHON) postprocess/bench_eme_run.py --bin $(BIN) --repeats 7
	$(PYTHON) postprocess/bench_cvode_baseline.py --bin $(BIN) --repeats 15
	$(PYTHON) postprocess/bench_field.py --bin $(BIN)
	$(PYTHON) postprocess/bench_arkode.py --bin $(BIN)
	$(PYTHON) postprocess/bench_rungs.py --bin $(BIN) --repeats 7
	$(PYTHON) postprocess/bench_chain.py --bin $(BIN) --repeats 3

# make bench counts instructions with valgrind's callgrind (perf stat says "not supported" on
# these machines): installed with apt-get on Debian as root (not with EME_SETUP_APT=no), else
# the rule says what to install.
bench-deps:
	@command -v valgrind >/dev/null && command -v callgrind_annotate >/dev/null || \
	if [ "$$(id -u)" = 0 ] && [ "$${EME_SETUP_APT:-yes}" != no ] && command -v apt-get >/dev/null; then \
	  echo "Installing valgrind with apt-get (make bench's instruction counts)"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq valgrind >/dev/null; \
	else echo "make bench counts instructions with valgrind's callgrind: install valgrind (Debian: apt-get" \
	  "install valgrind; Spack: spack install valgrind; conda-forge: conda install valgrind)" >&2; exit 1; fi

# The constraint scenes for EME_s and EME_u, and g2 without conduction (docs/constraints.md).
constraints: programs $(VENV)/.python-deps
	$(call run_and_summarize,$(CONSTRAINT_RUNS))

# Every test (CI runs this), pytest on TEST_WORKERS processes; `make check` is the quick loop:
# the unit tests and a fast subset of the end-to-end tests (tests/run_tests.py, QUICK_TESTS).
TEST_WORKERS ?= $(shell nproc 2>/dev/null || echo 1)
RUN_TESTS = $(PYTHON) tests/run_tests.py --bin $(TESTBIN) --runner '$(UNIT_RUNNER)' --pfunit-dir '$(PFUNIT_DIR)' \
            --workers $(TEST_WORKERS)
# Both build on TEST_WORKERS processes too.
test: $(VENV)/.python-deps
	@$(MAKE) --no-print-directory -j$(TEST_WORKERS) all
	$(RUN_TESTS)

check: $(VENV)/.python-deps
	@$(MAKE) --no-print-directory -j$(TEST_WORKERS) all
	$(RUN_TESTS) --quick

version:
	@echo '$(VERSION)'

# ---------------------------------------------------------------- model descriptions
# A model described in src/model/NAME/description.py (docs/development.md, Adding a model) has its
# Fortran generated by src/model/generator/generate_model.py (SymPy) and committed beside it, so
# `make` never needs SymPy: `make generate` regenerates them after a description changed (the
# build then recompiles that folder's modules and what uses them);
# tests/e2e/test_generated_models.py fails when they differ from what it generates.
MODEL_GENERATOR := src/model/generator/generate_model.py
generate: $(VENV)/.python-deps
	@for description in $(wildcard src/model/*/description.py); do \
	  $(PYTHON) $(MODEL_GENERATOR) $$description || exit 2; echo "generated from $$description"; done

# `make new-model NAME=x`: src/model/x/description.py from the template, and its first Fortran.
new-model: $(VENV)/.python-deps
	@[[ "$(NAME)" =~ ^[a-z][a-z0-9_]{0,15}$$ ]] || { echo "make new-model: NAME='$(NAME)' is not allowed;" \
	  "allowed: a lowercase Fortran name of at most 16 characters, e.g. NAME=heat_bath"; exit 2; }
	@[ ! -e src/model/$(NAME) ] || { echo "make new-model: src/model/$(NAME) exists; nothing written"; exit 2; }
	@mkdir -p src/model/$(NAME)
	@sed 's/MODEL_NAME/$(NAME)/g' src/model/generator/description_template.py > src/model/$(NAME)/description.py
	@$(PYTHON) $(MODEL_GENERATOR) src/model/$(NAME)/description.py || { rm -rf src/model/$(NAME); exit 2; }
	@echo "src/model/$(NAME)/description.py and its Fortran written; edit the description, 'make generate', and"
	@echo "register it in src/model/model_registry_lines.f90 (docs/development.md, Adding a model):"
	@echo "  use $(NAME)_scene, only: $(NAME)_name, new_$(NAME)_scene"
	@echo "  model_entry($(NAME)_name, new_$(NAME)_scene)"

# The module graph of docs/architecture.md, drawn from the sources.
docs: $(VENV)/.python-deps
	$(PYTHON) tests/architecture/module_graph.py -o docs/architecture

clean:
	rm -rf $(BUILD)
