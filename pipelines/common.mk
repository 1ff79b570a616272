# common.mk — what every experiment Makefile shares: strict shell, deletion
# of half-made targets, the programs on PATH, and the stage variables that
# swap one stage for an experiment (ENCODER=pointnet, CUBATURE=metis, ...).
SHELL := /bin/bash
.DEFAULT_GOAL := all
.SHELLFLAGS := -euo pipefail -c
.DELETE_ON_ERROR:
.SECONDARY:
TOP := $(abspath $(dir $(lastword $(MAKEFILE_LIST)))/..)
BINDIR ?= $(TOP)/bin
export PATH := $(BINDIR):$(PATH)

# SUBMIT: run every stage as a job of a cluster's scheduler, e.g.
#   make -f pipelines/shapes.mk -j64 SUBMIT='srun -N1 -n1 -c1' SUBMIT_FULLSIM='--mem=8G' SUBMIT_FITFIELD='-c4'
# Each recipe line that runs a crom program is run by $(SUBMIT) (on a node
# that shares this directory), with the options SUBMIT_<PROGRAM> of each
# program it names appended; other lines run here (pipelines/submit.sh). A
# failed job fails its target, and make deletes what it had written.
SUBMIT ?=
# a recipe's standard output to its target, atomically: `cmd $(ATOMIC)` writes
# $@.tmp and renames it when cmd succeeds, and removes it when cmd fails, so a
# target on a shared directory is either complete or absent
ATOMIC = > $@.tmp && mv -f $@.tmp $@ || { rm -f $@.tmp; false; }
ifneq ($(strip $(SUBMIT)),)
CROM_STAGES := MESH FULLSIM SAMPLE ENCODE FITFIELD CUBATURE REDUCEDSTEP REMESH EXPORT INFO DIFF METRICS MODES SCENE
export CROM_SUBMIT := $(SUBMIT)
$(foreach s,$(CROM_STAGES),$(eval export CROM_SUBMIT_$(s) := $$(SUBMIT_$(s))))
%: SHELL = $(TOP)/pipelines/submit.sh
endif

# stage variables (one variable swaps one stage)
RANK ?= 20
BASIS ?= mlp
ENCODER ?= lsq
EPOCHS ?= 3000
MINUTES ?=
POINTS ?= 2048
CUBATURE ?= optimized
COUNT ?= 200
SOLVER ?= newton
SEED ?= 1
QUIET ?= -q
# the a-posteriori error indicator of every reduced run over cubatures
# (crom-reducedstep --indicator: needs no full run; the tables show it
# beside crom-diff's error)
IND_FLAGS = --indicator --indicator-model $(OUT)/model.h5
FIT_FLAGS = --basis $(BASIS) --rank $(RANK) --seed $(SEED) $(if $(filter mlp,$(BASIS)),--encoder $(ENCODER) --epochs $(EPOCHS) $(if $(MINUTES),--minutes $(MINUTES)))

# Stage flag stamps: $(OUT)/flags/NAME holds the flags of a stage and is
# rewritten only when they change, so a target that depends on it is rebuilt
# exactly when its stage's variables change (make -j then reruns that stage and
# what follows, and reuses the rest). Use: $(eval $(call stamp_rule,NAME,FLAGS))
# once, then $(call stamp,NAME) as a prerequisite. The stamp is brought up to
# date while make reads the Makefile, not by a recipe, so `make -n` after a
# finished run lists nothing and after a variable change lists just the
# stages it affects. Single quotes are dropped from the stamped text (they
# only matter to the shell, and inside printf's quoted argument they would
# end it).
stamp = $(OUT)/flags/$(1)
define stamp_rule
$(shell mkdir -p $(OUT)/flags && { printf '%s\n' '$(subst ',,$(2))' | cmp -s - $(OUT)/flags/$(1) || printf '%s\n' '$(subst ',,$(2))' > $(OUT)/flags/$(1); })
$(OUT)/flags/$(1): ;
endef
