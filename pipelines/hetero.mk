# hetero.mk — Sharp et al. Fig. 8 (../shared/seeds/001_*.txt; issue 19 item 1):
# a clamped bar whose far half is STIFF times stiffer than its near half
# (--youngs 'x>0=...'), loaded by gravity and a tip force, comes to rest
# (heavy damping); the same static response is sought in each subspace of
# dimension about R and compared with crom-fullsim's:
#   - linear modes (crom-modes, R of them),
#   - modes and their modal derivatives (Barbič and James 2005; crom-modes
#     --derivatives, DMODES modes: DMODES + DMODES(DMODES+1)/2 fields),
#   - a data-free energy map of R latents (Sharp et al.; crom-fitfield
#     --objective energy, TMINUTES of training),
#   - neural modes over the R linear modes with their derivatives (Wang et
#     al.; crom-fitfield --objective neuralmodes --derivatives, TMINUTES).
# Every subspace is built on the heterogeneous body (the regions reach the
# modes, the derivatives and the data-free training), and every reduced run
# integrates every tet. Output: OUT/table.md, the relative displacement
# error of each subspace's rest state against the full one.
#
#   make -f pipelines/hetero.mk -j2
#   make -f pipelines/hetero.mk STIFF=1      # the same bar of one material
include $(dir $(lastword $(MAKEFILE_LIST)))common.mk

OUT ?= runs/hetero
SIZE ?= 0.05
R ?= 8
DMODES ?= 3
TMINUTES ?= 1
E ?= 4e5
STIFF ?= 10
MAT = --youngs $(E) --poisson 0.45 --density 1000 --youngs 'x>0=$(shell awk 'BEGIN {print $(E) * $(STIFF)}')'
LOAD = --pin clamp --gravity 0,-9.81,0 --force 'tip=0,-20,10@0:'
STATIC = $(MAT) $(LOAD) --dt 0.02 --steps 150 --damping 20 --max-iter 200
TRAIN = --steps 1000000 --minutes $(TMINUTES) --seed $(SEED) --threads 1
ROWS = modes mderiv energy neuralmodes

.PHONY: all
all: $(OUT)/table.md
	@cat $<

$(OUT)/mesh.h5:
	@mkdir -p $(@D)
	crom-mesh box --dims 1,0.2,0.2 --size $(SIZE) --region clamp='x<-0.499' --region tip='x>0.499' $(QUIET) -o $@
$(OUT)/full.h5: $(OUT)/mesh.h5
	crom-fullsim $(STATIC) --threads 1 $(QUIET) -o $@ $<
$(OUT)/modes.h5: $(OUT)/mesh.h5
	crom-modes $(MAT) --pin clamp --count $(R) --threads 1 $(QUIET) -o $@ $<
$(OUT)/mderiv.h5: $(OUT)/mesh.h5
	crom-modes $(MAT) --pin clamp --count $(DMODES) --derivatives --threads 1 $(QUIET) -o $@ $<
$(OUT)/energy.h5: $(OUT)/mesh.h5
	crom-fitfield --objective energy --rank $(R) --mesh $< $(MAT) --pin clamp --gravity 0,-9.81,0 $(TRAIN) $(QUIET) -o $@
$(OUT)/neuralmodes.h5: $(OUT)/mesh.h5 $(OUT)/modes.h5
	crom-fitfield --objective neuralmodes --mesh $< --modes $(OUT)/modes.h5 --derivatives $(MAT) --pin clamp \
	  $(TRAIN) $(QUIET) -o $@
# linear subspaces over a cubature of every tet; the maps over every tet of the mesh
$(OUT)/cub-%.h5: $(OUT)/%.h5 $(OUT)/mesh.h5
	crom-cubature --model $< --scheme all $(QUIET) -o $@ $(OUT)/mesh.h5
$(OUT)/red-modes.h5 $(OUT)/red-mderiv.h5: $(OUT)/red-%.h5: $(OUT)/cub-%.h5
	crom-reducedstep --cubature $< $(STATIC) --threads 1 $(QUIET) -o $@
$(OUT)/red-energy.h5 $(OUT)/red-neuralmodes.h5: $(OUT)/red-%.h5: $(OUT)/%.h5 $(OUT)/mesh.h5
	crom-reducedstep --model $< --mesh $(OUT)/mesh.h5 $(STATIC) --threads 1 $(QUIET) -o $@
$(OUT)/diff-%.txt: $(OUT)/red-%.h5 $(OUT)/full.h5 $(OUT)/%.h5
	crom-diff $< $(OUT)/full.h5 --model $(OUT)/$*.h5 --mesh $(OUT)/mesh.h5 $(ATOMIC)
$(OUT)/table.md: $(foreach r,$(ROWS),$(OUT)/diff-$(r).txt $(OUT)/red-$(r).h5) $(OUT)/full.h5
	/usr/bin/python3 $(TOP)/pipelines/benchtab.py hetero $(OUT) "$(ROWS)" "$(STIFF)" $(ATOMIC)
