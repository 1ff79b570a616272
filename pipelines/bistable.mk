# bistable.mk — Sharp et al.'s bistable bar (Figs. 3 and 10; issue 19 item
# 3): a 2-D bar in plane strain (1 m x 6 cm, 5 cm deep; 411 vertices, the
# paper's 830 DOF is 415), E = 10 MPa, under gravity, its clamped ends
# pushed together by COMP m each (crom-fullsim --velocity over the first
# second) so that it buckles: down under gravity (the first equilibrium),
# or up when pushed at its middle by PUSH N over 1.2-2 s (the second); a
# push of PUSH/4 does not snap it. The down state is the seed of an
# R-dimensional data-free energy map (crom-fitfield --seed-state, Sharp
# §4.1; STEPS training steps at SIGMA, about 20 s per 20000), and the same
# pushes run in that subspace from it (crom-reducedstep --model, the same timeline: the
# reduced run sits at the seed while the full one compresses). Does the
# subspace contain both equilibria? The paper asks for each one's energy
# within 5 % of the full minimum. Then REFINE rounds of refinement along
# the subspace's own push run (crom-fitfield --init-model --latents, LR,
# RSTEPS steps each: every other sample near a latent the run visited;
# still data-free). Output: OUT/table.md and OUT/strip-up.png (the push
# in the subspace over the full run).
#
#   make -f pipelines/bistable.mk -j2
include $(dir $(lastword $(MAKEFILE_LIST)))common.mk

OUT ?= runs/bistable
R ?= 8
STEPS ?= 20000
PUSH ?= 800
COMP ?= 0.025
SIGMA ?= 0.03
REFINE ?= 2
RSTEPS ?= 10000
LR ?= 1e-3
MAT = --youngs 1e7 --poisson 0.3 --density 1000
BASE = $(MAT) --gravity 0,-9.8,0 --dt 0.01 --damping 10 --max-iter 200 --threads 1
COMPRESS = --velocity left=$(COMP),0,0@0:1 --velocity right=-$(COMP),0,0@0:1
# the pushes at the middle over 1.2-2 s (N): none, a quarter, the full one
F_down = 0
F_nudge = $(shell awk 'BEGIN {print $(PUSH) / 4}')
F_up = $(PUSH)
CASES = down nudge up

.PHONY: all
all: $(OUT)/table.md $(OUT)/strip-up.png
	@cat $<

$(OUT)/mesh.h5:
	@mkdir -p $(@D)
	crom-mesh sheet --dims 1,0.06,1 --size 0.015 --thickness 0.05 --plane-strain --region left='x<-0.49' \
	  --region right='x>0.49' --region mid='x>-0.03&x<0.03' $(QUIET) -o $@
# full space: compress, then push (or not)
$(OUT)/full-%.h5: $(OUT)/mesh.h5
	crom-fullsim $(BASE) $(COMPRESS) --force mid=0,$(F_$*),0@1.2:2 --steps 400 $(QUIET) -o $@ $<
TRAIN = --objective energy --mesh $(OUT)/mesh.h5 $(MAT) --pin left --pin right --gravity 0,-9.8,0 --rank $(R) \
  --sigma $(SIGMA) --threads 1 $(QUIET)
RED = --mesh $(OUT)/mesh.h5 $(BASE) --pin left --pin right --steps 400
# the seed: the down state, the last frame of the run with no push
$(OUT)/model-0.h5: $(OUT)/full-down.h5 $(OUT)/mesh.h5
	crom-fitfield $(TRAIN) --seed-state $< --steps $(STEPS) --seed $(SEED) -o $@
# each round: the last model's push run, then the model refined along it
$(OUT)/probe-%.h5: $(OUT)/model-%.h5 $(OUT)/mesh.h5
	crom-reducedstep --model $< $(RED) --force mid=0,$(F_up),0@1.2:2 $(QUIET) -o $@
define round
$(OUT)/model-$(1).h5: $(OUT)/model-$(2).h5 $(OUT)/probe-$(2).h5
	crom-fitfield $$(TRAIN) --init-model $$< --latents $$(word 2,$$^) --lr $$(LR) --steps $$(RSTEPS) \
	  --seed $$$$(($$(SEED) + $(1))) -o $$@
endef
$(foreach k,$(shell seq 1 $(REFINE)),$(eval $(call round,$(k),$(shell echo $$(($(k) - 1))))))
$(OUT)/energy.h5: $(OUT)/model-$(REFINE).h5
	cp $< $@
# the subspace, from the seed, on the same timeline
$(OUT)/red-%.h5: $(OUT)/energy.h5 $(OUT)/mesh.h5
	crom-reducedstep --model $< $(RED) --force mid=0,$(F_$*),0@1.2:2 $(QUIET) -o $@
$(OUT)/red-%.vtu: $(OUT)/red-%.h5 $(OUT)/energy.h5
	crom-export --format vtu --model $(OUT)/energy.h5 $(QUIET) -o $@ $<
$(OUT)/diff-%.txt: $(OUT)/red-%.h5 $(OUT)/full-%.h5 $(OUT)/energy.h5
	crom-diff --model $(OUT)/energy.h5 $(OUT)/red-$*.h5 $(OUT)/full-$*.h5 $(ATOMIC)
# the push in the subspace (top) over the full run (bottom)
$(OUT)/strip-up.png: $(OUT)/red-up.h5 $(OUT)/full-up.h5 $(OUT)/energy.h5
	crom-export --format strip --columns 6 --panel 300x200 --model $(OUT)/energy.h5 --mesh $(OUT)/mesh.h5 \
	  --compare $(OUT)/full-up.h5 $(QUIET) -o $@ $<
ROUNDS = $(shell seq 0 $(REFINE))
$(OUT)/table.md: $(foreach c,$(CASES),$(OUT)/diff-$(c).txt $(OUT)/red-$(c).vtu) \
                 $(foreach k,$(ROUNDS),$(OUT)/probe-$(k).h5)
	/usr/bin/python3 $(TOP)/pipelines/benchtab.py bistable $(OUT) "$(foreach c,$(CASES),$(c):$(F_$(c)))" \
	  "$(ROUNDS)" $(ATOMIC)
