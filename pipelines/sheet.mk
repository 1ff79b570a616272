# sheet.mk — the hanging sheet (Sharp et al. 2023 §5.1, Table 1 and Fig. 4:
# a thick cloth in an 8-dimensional subspace): a 1 x 1 m sheet, 5 mm thick,
# clamped along one edge (two rows of vertices pinned) and sagging under its
# own weight, with a damped swing that settles by the end. Ground truth is
# crom-fullsim; the subspaces, each of about 8 dimensions, run with
# crom-reducedstep --model over every triangle and hinge:
#   modes     the 8 lowest linear modes (crom-modes)
#   mderiv    3 modes and the first 5 of their 6 modal derivatives (crom-modes
#             --derivatives --fields 8, d = 8; MDFIELDS= keeps all 9)
#   neural    neural modes on the 8 linear modes (crom-fitfield --objective neuralmodes)
#   nmderiv   the same seeded with the modes' modal derivatives (--derivatives):
#             x = X + Phi z + 1/2 sum Psi_ij z_i z_j + y(z), d = 8
#   quadratic that map untrained (--steps 0, y = 0): Barbic and James's
#             quadratic manifold of the 8 modes
#   nmderiv-ta nmderiv with its correction's tangent anchored (--tangent-anchor:
#             y = N(z) - N(0) - J_N(0) z, zero to first order)
#   energy    the data-free energy map (crom-fitfield --objective energy, d = 8)
#   mderiv-cub mderiv over an optimized cubature of the shell's triangles and
#             hinges (crom-cubature, fitted to the poses of mderiv's own run)
#   skin      the skinning eigenmodes of SKIN_HANDLES affine handles (crom-fitfield
#             --objective skinning --weights eigen): a linear subspace of rank
#             9 per handle, no training
# The table gives each run's error against crom-fullsim at the last frame
# (the static sag) and over the run, and the median step time.
#
#   make -f pipelines/sheet.mk                 # runs/sheet/table.md (YOUNGS=1e9: the tip sags 9% of the span)
#   make -f pipelines/sheet.mk YOUNGS=1e8 OUT=runs/sheet-soft   # 58%: a large rotation at the clamp
#
# Measured (make -j2 on the 2-core machine, about a minute each; 795
# vertices, 1479 triangles, 2164 hinges), static error at YOUNGS=1e9 | 1e8:
# modes 88.8% | 96.6%, mderiv (d = 8) 1.9% | 28.9% (MDFIELDS= , d = 9: 1.8%
# | 28.8%; DMODES=5 MDFIELDS= , 5 modes + 15 derivatives: 0.7% | 13.5%),
# neural 88.7% | 96.3%, nmderiv 30.1% | 73.0%, nmderiv-ta 3.3% | 65.7%,
# quadratic 4.3% | 64%, energy
# 99.8% | 99.6%, mderiv-cub 1.6% | 28.9% at 0.05 | 0.11 ms per step (median)
# against crom-fullsim's 8.4 | 21 ms, where the runs over every element take
# 3-24 ms; skin (8 handles, rank 72) 2.0% | 2.6% at 0.95 | 5.6 ms per step
# (median; measured later beside a CI run, where crom-fullsim took 10.7 | 30
# ms; 16 handles: 0.43% | 0.84%). Bending modes lock: deflected, they stretch the membrane, (L/t)^2
# = 4e4 times stiffer than bending; modal derivatives add the in-plane
# shortening a bent sheet needs. quadratic is nmderiv untrained: the
# training (6000 steps over the box) costs accuracy at this sag (34% after
# 20000 steps). Against constrained equilibria (crom-fullsim --equilibria)
# the trained map is closer over the box (7.3x their energy against 19x)
# but not along its own run (1.20x against 1.01x, --latents): the sag lies
# on the box's edge along the first mode.
include $(dir $(lastword $(MAKEFILE_LIST)))common.mk

OUT ?= runs/sheet
SIZE ?= 0.04
THICKNESS ?= 0.005
YOUNGS ?= 1e9
# the clamp: the first two rows of vertices (rows are SIZE sqrt(3)/2 apart)
CLAMP := y<$(shell awk 'BEGIN {print -0.5 + 1.3 * $(SIZE)}')
MAT = --youngs $(YOUNGS) --poisson 0.3 --density 200
SCENARIO = $(MAT) --pin clamp --gravity 0,0,-9.81 --dt 0.05 --steps 60 --damping 4
D ?= 8
DMODES ?= 3
MDFIELDS ?= $(D)
STEPS_DF ?= 6000
BOX ?= 0.05
CUB_COUNT ?= 200
SKIN_HANDLES ?= 8
RUNS = modes mderiv neural nmderiv nmderiv-ta quadratic energy mderiv-cub skin
$(eval $(call stamp_rule,mesh,$(SIZE) $(THICKNESS) $(CLAMP)))
$(eval $(call stamp_rule,scenario,$(SCENARIO)))
$(eval $(call stamp_rule,modes,$(D)))
$(eval $(call stamp_rule,mderiv,$(DMODES) $(MDFIELDS)))
$(eval $(call stamp_rule,datafree,$(D) $(STEPS_DF) $(SEED) $(BOX)))

.PHONY: all
all: $(OUT)/table.md
	@cat $<

$(OUT)/mesh.h5: $(call stamp,mesh)
	@mkdir -p $(@D)
	crom-mesh sheet --dims 1,1,1 --size $(SIZE) --thickness $(THICKNESS) --region clamp='$(CLAMP)' $(QUIET) -o $@

$(OUT)/full.h5: $(OUT)/mesh.h5 $(call stamp,scenario)
	crom-fullsim $(SCENARIO) $(QUIET) --stats $(OUT)/full.csv -o $@ $<

$(OUT)/model-modes.h5: $(OUT)/mesh.h5 $(call stamp,scenario) $(call stamp,modes)
	crom-modes $(MAT) --pin clamp --count $(D) $(QUIET) -o $@ $<
$(OUT)/model-mderiv.h5: $(OUT)/mesh.h5 $(call stamp,scenario) $(call stamp,mderiv)
	crom-modes $(MAT) --pin clamp --count $(DMODES) --derivatives $(if $(MDFIELDS),--fields $(MDFIELDS)) $(QUIET) \
	  -o $@ $<
$(OUT)/model-neural.h5: $(OUT)/mesh.h5 $(OUT)/model-modes.h5 $(call stamp,datafree)
	crom-fitfield --objective neuralmodes --mesh $< --modes $(OUT)/model-modes.h5 --rank $(D) \
	  --box $(BOX) --steps $(STEPS_DF) --seed $(SEED) $(QUIET) -o $@
$(OUT)/model-nmderiv.h5: $(OUT)/mesh.h5 $(OUT)/model-modes.h5 $(call stamp,datafree)
	crom-fitfield --objective neuralmodes --derivatives --mesh $< --modes $(OUT)/model-modes.h5 --rank $(D) \
	  --box $(BOX) --steps $(STEPS_DF) --seed $(SEED) $(QUIET) -o $@
$(OUT)/model-nmderiv-ta.h5: $(OUT)/mesh.h5 $(OUT)/model-modes.h5 $(call stamp,datafree)
	crom-fitfield --objective neuralmodes --derivatives --tangent-anchor --mesh $< --modes $(OUT)/model-modes.h5 \
	  --rank $(D) --box $(BOX) --steps $(STEPS_DF) --seed $(SEED) $(QUIET) -o $@
$(OUT)/model-quadratic.h5: $(OUT)/mesh.h5 $(OUT)/model-modes.h5 $(call stamp,datafree)
	crom-fitfield --objective neuralmodes --derivatives --mesh $< --modes $(OUT)/model-modes.h5 --rank $(D) \
	  --steps 0 $(QUIET) -o $@
$(OUT)/model-energy.h5: $(OUT)/mesh.h5 $(call stamp,scenario) $(call stamp,datafree)
	crom-fitfield --objective energy --mesh $< --rank $(D) $(MAT) --pin clamp --gravity 0,0,-9.81 \
	  --steps $(STEPS_DF) --seed $(SEED) $(QUIET) -o $@

$(OUT)/model-skin.h5: $(OUT)/mesh.h5 $(call stamp,scenario)
	crom-fitfield --objective skinning --weights eigen --handles $(SKIN_HANDLES) --mesh $< $(MAT) --pin clamp \
	  $(QUIET) -o $@

$(OUT)/cub-mderiv.h5: $(OUT)/model-mderiv.h5 $(OUT)/red-mderiv.h5 $(OUT)/mesh.h5
	crom-cubature --model $< --scheme optimized --count $(CUB_COUNT) --poses $(OUT)/red-mderiv.h5 \
	  --youngs $(YOUNGS) --poisson 0.3 --seed $(SEED) $(QUIET) -o $@ $(OUT)/mesh.h5
$(OUT)/red-mderiv-cub.h5: $(OUT)/model-mderiv.h5 $(OUT)/cub-mderiv.h5 $(OUT)/mesh.h5
	crom-reducedstep --model $< --mesh $(OUT)/mesh.h5 --cubature $(OUT)/cub-mderiv.h5 $(SCENARIO) $(QUIET) \
	  --stats $(OUT)/red-mderiv-cub.csv -o $@
$(OUT)/diff-mderiv-cub.txt: $(OUT)/red-mderiv-cub.h5 $(OUT)/full.h5
	crom-diff --model $(OUT)/model-mderiv.h5 $^ > $@.tmp && mv $@.tmp $@
$(OUT)/red-%.h5: $(OUT)/model-%.h5 $(OUT)/mesh.h5
	crom-reducedstep --model $< --mesh $(OUT)/mesh.h5 $(SCENARIO) $(QUIET) --stats $(OUT)/red-$*.csv -o $@
$(OUT)/diff-%.txt: $(OUT)/red-%.h5 $(OUT)/full.h5
	crom-diff --model $(OUT)/model-$*.h5 $^ > $@.tmp && mv $@.tmp $@

$(OUT)/table.md: $(foreach r,$(RUNS),$(OUT)/diff-$(r).txt)
	@( med() { awk -F, 'NR == 1 {for (i = 1; i <= NF; i++) if ($$i == "seconds") k = i} NR > 1 {print $$k}' "$$1" \
	     | sort -g | awk '{a[NR] = $$1} END {printf "%.3g", (NR % 2 ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2) * 1e3}'; }; \
	   echo "### Hanging sheet, E = $(YOUNGS) Pa: $$(crom-info $(OUT)/mesh.h5 | sed -n 's/^ *\([0-9]* vertices, [0-9]* triangles\).*/\1/p')"; echo; \
	   echo "| subspace | d | static error | error over the run | reduced step (ms) |"; \
	   echo "|---|---:|---:|---:|---:|"; \
	   for r in $(RUNS); do \
	     d=$$(crom-info $(OUT)/model-$${r%-cub}.h5 | awk '$$1 == "rank" {print $$2}'); \
	     last=$$(tail -n 2 $(OUT)/diff-$$r.txt | head -n 1 | awk '{printf "%.1f%%", 100 * $$3}'); \
	     run=$$(tail -n 1 $(OUT)/diff-$$r.txt | awk '{printf "%.1f%%", 100 * $$4}'); \
	     echo "| $$r | $$d | $$last | $$run | $$(med $(OUT)/red-$$r.csv) |"; \
	   done; echo; \
	   echo "crom-fullsim step: $$(med $(OUT)/full.csv) ms (median)" ) > $@.tmp && mv $@.tmp $@
