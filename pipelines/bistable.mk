# bistable.mk — a bistable 2-D body (issue 19 item 3; after Sharp et al.'s
# bistable bar, Figs. 3 and 10): a shallow clamped arch in plane strain
# (pipelines/arch.py through crom-mesh import --plane-strain; span 1 m,
# rise 0.1 m, 1 cm thick) has two stable equilibria: its rest shape and a
# snapped one. crom-fullsim finds both: pushed at the crown by PUSH N for
# 0.8 s it snaps and stays; nudged by a tenth of that it comes back. The
# same push in R-dimensional subspaces (linear modes; modes with modal
# derivatives; neural modes over them, TMINUTES; a data-free energy map,
# TMINUTES, sigma SIGMA), and for the modal ones also a relaxation from the
# snapped state's own modal coordinates (crom-encode): does the subspace
# hold the snapped equilibrium? Output: OUT/table.md.
#
#   make -f pipelines/bistable.mk -j2
include $(dir $(lastword $(MAKEFILE_LIST)))common.mk

OUT ?= runs/bistable
R ?= 8
TMINUTES ?= 1
PUSH ?= 5
SIGMA ?= 0.03
NX ?= 80
MAT = --youngs 1e6 --poisson 0.3 --density 1000
BASE = $(MAT) --gravity 0,0,0 --pin left --pin right --dt 0.01 --damping 30 --max-iter 200
RUN = $(BASE) --steps 400
ROWS = modes mderiv neuralmodes energy

.PHONY: all
all: $(OUT)/table.md
	@cat $<

$(OUT)/arch.obj: $(TOP)/pipelines/arch.py
	@mkdir -p $(@D)
	/usr/bin/python3 $< 1 0.1 0.01 $(NX) 3 $(ATOMIC)
$(OUT)/mesh.h5: $(OUT)/arch.obj
	crom-mesh import $< --thickness 0.05 --plane-strain --size 1 --region left='x<-0.49' --region right='x>0.49' \
	  --region crown='x>-0.03&x<0.03&y>0.09' $(QUIET) -o $@
$(OUT)/full-push.h5: $(OUT)/mesh.h5
	crom-fullsim $(RUN) --force crown=0,-$(PUSH),0@0:0.8 --threads 1 $(QUIET) -o $@ $<
$(OUT)/full-nudge.h5: $(OUT)/mesh.h5
	crom-fullsim $(RUN) --force crown=0,-$(shell awk 'BEGIN {print $(PUSH) / 10}'),0@0:0.8 --threads 1 $(QUIET) -o $@ $<
$(OUT)/modes.h5: $(OUT)/mesh.h5
	crom-modes $(MAT) --pin left --pin right --count $(R) --threads 1 $(QUIET) -o $@ $<
$(OUT)/mderiv.h5: $(OUT)/modes.h5
	crom-fitfield --objective neuralmodes --mesh $(OUT)/mesh.h5 --modes $< --derivatives --tangent-anchor --steps 0 \
	  $(QUIET) -o $@
$(OUT)/neuralmodes.h5: $(OUT)/modes.h5
	crom-fitfield --objective neuralmodes --mesh $(OUT)/mesh.h5 --modes $< --derivatives --tangent-anchor \
	  --steps 100000000 --minutes $(TMINUTES) --seed $(SEED) --threads 1 $(QUIET) -o $@
$(OUT)/energy.h5: $(OUT)/mesh.h5
	crom-fitfield --objective energy --mesh $< $(MAT) --pin left --pin right --gravity 0,0,0 --rank $(R) \
	  --sigma $(SIGMA) --steps 100000000 --minutes $(TMINUTES) --seed $(SEED) --threads 1 $(QUIET) -o $@
# the push in each subspace
$(OUT)/push-%.h5: $(OUT)/%.h5 $(OUT)/mesh.h5
	crom-reducedstep --model $< --mesh $(OUT)/mesh.h5 $(RUN) --force crown=0,-$(PUSH),0@0:0.8 --threads 1 $(QUIET) -o $@
# from the snapped state's modal coordinates, no load
$(OUT)/snapq-%.h5: $(OUT)/%.h5 $(OUT)/full-push.h5
	crom-encode --model $< $(QUIET) $(OUT)/full-push.h5 | crom-reducedstep --model $< --mesh $(OUT)/mesh.h5 $(BASE) --steps 300 \
	  --init - --threads 1 $(QUIET) -o $@
$(OUT)/table.md: $(foreach r,$(ROWS),$(OUT)/push-$(r).h5) $(foreach r,modes mderiv neuralmodes,$(OUT)/snapq-$(r).h5) \
                 $(OUT)/full-push.h5 $(OUT)/full-nudge.h5
	/usr/bin/python3 $(TOP)/pipelines/benchtab.py bistable $(OUT) "$(ROWS)" $(ATOMIC)
