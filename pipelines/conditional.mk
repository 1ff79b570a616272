# conditional.mk — Sharp et al.'s conditional bar (§3.5, Fig. 5; issue 19
# item 2) in 3-D: ONE data-free energy map of a clamped bar conditioned on
# two scenario parameters, the modulus ratio of its clamped half (RATIO
# range) and gravity along y (GRAVITY range), trained STEPS steps (about
# 2 min each, the two at once; a fixed count, so a rerun gives the same
# numbers, where a time budget did not); then the
# static sag at conditions drawn as such by no batch (CASES: RATIO_G pairs,
# g in m/s² downward) against crom-fullsim with the same region modulus
# and gravity. Then Sharp's own pair of conditions: a second map of the bar
# pinned at both ends, over the modulus ratio and where its far end is
# pinned (pin:tip:y, PIN range, m), against crom-fullsim moving that end
# there (--velocity over the first 0.5 s, then held) at PCASES (RATIO_PIN).
# Output: OUT/table.md (static error and sag per case, both maps).
#
#   make -f pipelines/conditional.mk -j2
#   make -f pipelines/conditional.mk SIZE=0.1 STEPS=5000       # a quick look
include $(dir $(lastword $(MAKEFILE_LIST)))common.mk

OUT ?= runs/conditional
SIZE ?= 0.05
R ?= 6
STEPS ?= 50000
E ?= 2e5
RATIO ?= 1:10
GRAVITY ?= -15:-5
CASES ?= 1.5_6 3_12 6_8 9_14
PIN ?= -0.2:0.2
PCASES ?= 1.5_0.05 3_-0.12 6_0.15 9_-0.03
MAT = --youngs $(E) --poisson 0.45 --density 1000
STATIC = --pin clamp --dt 0.02 --steps 150 --damping 20 --max-iter 200
ratio = $(word 1,$(subst _, ,$1))
grav = $(word 2,$(subst _, ,$1))
pin = $(word 2,$(subst _, ,$1))
PSTATIC = --gravity 0,-9.81,0 --dt 0.02 --steps 150 --damping 20 --max-iter 200

.PHONY: all
all: $(OUT)/table.md
	@cat $<

$(OUT)/mesh.h5:
	@mkdir -p $(@D)
	crom-mesh box --dims 1,0.2,0.2 --size $(SIZE) --region clamp='x<-0.499' --region tip='x>0.499' $(QUIET) -o $@
$(OUT)/model.h5: $(OUT)/mesh.h5
	crom-fitfield --objective energy --mesh $< $(MAT) --pin clamp --rank $(R) --condition 'ratio:x<0=$(RATIO)' \
	  --condition 'gravity:y=$(GRAVITY)' --steps $(STEPS) --seed $(SEED) --threads 1 \
	  $(QUIET) -o $@
$(OUT)/full-%.h5: $(OUT)/mesh.h5
	crom-fullsim $(MAT) --youngs 'x<0=$(shell awk 'BEGIN {print $(E) * $(call ratio,$*)}')' \
	  --gravity 0,-$(call grav,$*),0 $(STATIC) --threads 1 $(QUIET) -o $@ $<
$(OUT)/red-%.h5: $(OUT)/model.h5
	crom-reducedstep --model $< $(MAT) $(STATIC) --condition 'ratio:x<0=$(call ratio,$*)' \
	  --condition 'gravity:y=-$(call grav,$*)' --threads 1 $(QUIET) --stats $(OUT)/red-$*.csv -o $@
$(OUT)/diff-%.txt: $(OUT)/red-%.h5 $(OUT)/full-%.h5 $(OUT)/model.h5
	crom-diff $< $(OUT)/full-$*.h5 --model $(OUT)/model.h5 $(ATOMIC)
$(OUT)/red-%.vtu: $(OUT)/red-%.h5 $(OUT)/model.h5
	crom-export --format vtu --model $(OUT)/model.h5 $(QUIET) -o $@ $<
# the pinned end's place as a condition
$(OUT)/model-pin.h5: $(OUT)/mesh.h5
	crom-fitfield --objective energy --mesh $< $(MAT) --pin clamp --pin tip --gravity 0,-9.81,0 --rank $(R) \
	  --condition 'ratio:x<0=$(RATIO)' --condition 'pin:tip:y=$(PIN)' --steps $(STEPS) \
	  --seed $(SEED) --threads 1 $(QUIET) -o $@
$(OUT)/pfull-%.h5: $(OUT)/mesh.h5
	crom-fullsim $(MAT) --youngs 'x<0=$(shell awk 'BEGIN {print $(E) * $(call ratio,$*)}')' $(PSTATIC) --pin clamp \
	  --velocity tip=0,$(shell awk 'BEGIN {print $(call pin,$*) / 0.5}'),0@0:0.5 --threads 1 $(QUIET) -o $@ $<
$(OUT)/pred-%.h5: $(OUT)/model-pin.h5
	crom-reducedstep --model $< $(MAT) $(PSTATIC) --pin clamp --pin tip --condition 'ratio:x<0=$(call ratio,$*)' \
	  --condition 'pin:tip:y=$(call pin,$*)' --threads 1 $(QUIET) --stats $(OUT)/pred-$*.csv -o $@
$(OUT)/pdiff-%.txt: $(OUT)/pred-%.h5 $(OUT)/pfull-%.h5 $(OUT)/model-pin.h5
	crom-diff $< $(OUT)/pfull-$*.h5 --model $(OUT)/model-pin.h5 $(ATOMIC)
$(OUT)/pred-%.vtu: $(OUT)/pred-%.h5 $(OUT)/model-pin.h5
	crom-export --format vtu --model $(OUT)/model-pin.h5 $(QUIET) -o $@ $<
$(OUT)/table.md: $(foreach c,$(CASES),$(OUT)/diff-$(c).txt $(OUT)/red-$(c).vtu $(OUT)/full-$(c).h5) \
                 $(foreach c,$(PCASES),$(OUT)/pdiff-$(c).txt $(OUT)/pred-$(c).vtu $(OUT)/pfull-$(c).h5)
	/usr/bin/python3 $(TOP)/pipelines/benchtab.py conditional $(OUT) "$(CASES)" "$(PCASES)" $(ATOMIC)
