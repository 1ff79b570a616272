# chain.mk — the chain of rigid links (Sharp et al. 2023 §5.1, Table 1,
# Figs. 6 and 8; issue 17): LINKS interlocked rings (crom-scene chain: 24 by
# default, 288 DOF; 2 is the paper's mini chain, 24 DOF) held together by
# contact penalties alone and pinned at one end, dropped from the horizontal
# to swing under gravity. Ground truth is crom-fullsim at DT; a second full
# run at DT_STALL shows where the implicit integrator gets stuck (Sharp et
# al.: "even small-timestep implicit integrators get stuck"; the run is kept
# and the table says at which step it stopped). The data-free energy map of
# rank D (crom-fitfield --objective energy, Sharp's lambda = 1 and a
# 5 x 128 MLP as in Table 1; SIGMA is crom's isometry scale in metres of RMS
# displacement) runs with crom-reducedstep --model over every scene element.
#
#   make -f pipelines/chain.mk                        # runs/chain: 24 links, table.md and strips
#   make -f pipelines/chain.mk LINKS=2 D=4 STEPS_DF=20000 OUT=runs/minichain
#
# Pictures: full.png (the full run, 6 times), compare.png (the reduced run
# above the full one).
#
# Measured (24 rings, one core): crom-fullsim at dt 2 ms 36.9 ms a step
# (median; 6.7 Newton iterations, at most 25); at dt 5 ms Newton stalls at
# step 15 (residual 7.8e-7 after 50 iterations). The data-free map (d = 8,
# 3000 steps) does not swing at all: 16 ms a step over every element, 100%
# from the full run. Mini chain (LINKS=2 D=4 STEPS_DF=20000): full 0.65 ms,
# no stall at 5 ms; the map 1.9 ms, 99.6% off (its rings stay linked but
# barely move).
include $(dir $(lastword $(MAKEFILE_LIST)))common.mk

OUT ?= runs/chain
LINKS ?= 24
DT ?= 0.002
STEPS ?= 500
DT_STALL ?= 0.005
D ?= 8
SIGMA ?= 0.03
STEPS_DF ?= 3000
SCENARIO = --dt $(DT) --steps $(STEPS) --every 10 --max-iter 200
$(eval $(call stamp_rule,scene,$(LINKS)))
$(eval $(call stamp_rule,scenario,$(SCENARIO) $(DT_STALL)))
$(eval $(call stamp_rule,datafree,$(D) $(SIGMA) $(STEPS_DF) $(SEED)))

.PHONY: all
all: $(OUT)/table.md $(OUT)/full.png $(OUT)/compare.png
	@cat $(OUT)/table.md

$(OUT)/scene.h5: $(call stamp,scene)
	@mkdir -p $(@D)
	crom-scene chain --links $(LINKS) $(QUIET) -o $@

$(OUT)/full.h5: $(OUT)/scene.h5 $(call stamp,scenario)
	crom-fullsim $(SCENARIO) $(QUIET) --stats $(OUT)/full.csv -o $@ $<

# the stall: crom-fullsim exits 65 when Newton does not converge; the
# message (and the step) is the result
$(OUT)/stall.txt: $(OUT)/scene.h5 $(call stamp,scenario)
	rc=0; crom-fullsim --dt $(DT_STALL) --steps $$(awk 'BEGIN {print int($(STEPS) * $(DT) / $(DT_STALL))}') \
	  --every 10 --max-iter 50 -q -o $(OUT)/stall.h5 $< 2> $@.tmp || rc=$$?; echo "exit $$rc" >> $@.tmp; mv $@.tmp $@

$(OUT)/model.h5: $(OUT)/scene.h5 $(call stamp,datafree)
	crom-fitfield --objective energy --mesh $< --rank $(D) --sigma $(SIGMA) --lambda 1 --width 128 --depth 5 \
	  --steps $(STEPS_DF) --seed $(SEED) $(QUIET) -o $@

$(OUT)/reduced.h5: $(OUT)/model.h5 $(call stamp,scenario)
	crom-reducedstep --model $< $(SCENARIO) $(QUIET) --stats $(OUT)/reduced.csv -o $@

$(OUT)/diff.txt: $(OUT)/reduced.h5 $(OUT)/full.h5
	crom-diff --model $(OUT)/model.h5 $^ > $@.tmp && mv $@.tmp $@

$(OUT)/full.png: $(OUT)/full.h5
	crom-export --format strip --columns 6 --panel 300x300 $(QUIET) -o $@ $<
$(OUT)/compare.png: $(OUT)/reduced.h5 $(OUT)/full.h5 $(OUT)/model.h5
	crom-export --format strip --columns 6 --panel 300x300 --model $(OUT)/model.h5 --compare $(OUT)/full.h5 \
	  $(QUIET) -o $@ $<

$(OUT)/table.md: $(OUT)/diff.txt $(OUT)/stall.txt
	@( med() { awk -F, 'NR == 1 {for (i = 1; i <= NF; i++) if ($$i == "seconds") k = i} NR > 1 {print $$k}' "$$1" \
	     | sort -g | awk '{a[NR] = $$1} END {printf "%.3g", (NR % 2 ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2) * 1e3}'; }; \
	   col() { awk -F, -v c="$$2" 'NR == 1 {for (i = 1; i <= NF; i++) if ($$i == c) k = i} NR > 1 {s += $$k; if ($$k > m) m = $$k; n++} \
	     END {printf "%.2f (max %d)", s / n, m}' "$$1"; }; \
	   echo "### Chain of $(LINKS) rings: $$(crom-info $(OUT)/scene.h5 | sed -n 's/^ *a rigid-body scene: //p')"; echo; \
	   echo "| run | step, median (ms) | iterations per step | error vs full |"; \
	   echo "|---|---:|---:|---:|"; \
	   echo "| crom-fullsim, dt $(DT) | $$(med $(OUT)/full.csv) | $$(col $(OUT)/full.csv newton) | |"; \
	   echo "| energy map d = $(D), sigma $(SIGMA) | $$(med $(OUT)/reduced.csv) | $$(col $(OUT)/reduced.csv iterations) | $$(tail -n 1 $(OUT)/diff.txt | awk '{printf "%.1f%%", 100 * $$4}') |"; \
	   echo; if [ "$$(tail -n 1 $(OUT)/stall.txt)" = "exit 0" ]; then \
	     echo "crom-fullsim at dt $(DT_STALL): Newton converged at every step (--max-iter 50)"; \
	   else echo "crom-fullsim at dt $(DT_STALL): $$(grep -v '^exit' $(OUT)/stall.txt | tail -n 1 | sed 's/^crom-fullsim: //')"; fi \
	 ) > $@.tmp && mv $@.tmp $@
