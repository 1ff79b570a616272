# squareshell.mk — the square-shell benchmark of Neural Modes (Wang et al.
# 2024, §4 "Performance Comparisons", Table 2 and A1): a flat square sheet,
# a 3-dimensional modal subspace, and the subspaces measured against the
# ground truth they approximate, the constrained equilibria
#   x*(z) = argmin E(x)  subject to  W^T M (x - X) / m = z
# (crom-fullsim --equilibria), at held-out modal coordinates z drawn
# uniformly in the box [-BOX, BOX]^3:
#   modes       the 3 linear modes, x = X + W z (crom-modes)
#   quadratic   the modes and their modal derivatives, untrained
#               (crom-fitfield --objective neuralmodes --derivatives --steps 0)
#   neural      neural modes trained on the energy over the box (no data)
#   nmderiv     the same seeded with the modal derivatives
#   supervised  the same network fitted to a training grid of equilibria
#               (TRAIN_GRID^3) by the geometric loss: Wang et al.'s
#               "L2 supervised" baseline (crom-fitfield --supervised)
# The table: mean elastic energy over the equilibria's (1 is the floor), the
# mean and largest element stress (membrane von Mises) against the
# equilibria's, the relative stress error, the RMS nodal force error and the
# displacement error (crom-metrics --equilibria), and the build time.
#
# The paper does not give the sheet's support or its coordinate scale
# ([-0.625, 0.625]^3 in its own units); here the sheet is 1 x 1 m, 1 cm thick,
# clamped along one edge (two rows of vertices), E = 1 GPa, and z is in
# metres of RMS displacement (W^T M W / m = I). A free sheet's equilibria
# converge slowly (nearly isometric bendings leave flat directions).
#
#   make -f pipelines/squareshell.mk          # runs/squareshell/table.md, about 4 minutes on 2 cores
#
# Measured (make -j2, 2 minutes; 516 vertices, 943 triangles; 200 test
# equilibria, mean 31.7 J; 20000 training steps, 37-44 s each):
# | subspace   | energy / equilibria's | stress error | nodal force error | displacement error |
# | modes      | 328   | 106  | 8465 N | 0.21  |
# | quadratic  | 29.3  | 32.2 | 2050 N | 0.12  |
# | neural     | 1.36  | 3.51 |  619 N | 0.070 |
# | nmderiv    | 1.27  | 3.00 |  184 N | 0.073 |
# | supervised | 3.27  | 10.2 |  803 N | 0.044 |
# The supervised fit comes closest in shape, neural modes in energy, stress
# and nodal force, as the paper reports (its Table 2 and A1).
include $(dir $(lastword $(MAKEFILE_LIST)))common.mk

OUT ?= runs/squareshell
SIZE ?= 0.05
THICKNESS ?= 0.01
YOUNGS ?= 1e9
MAT = --youngs $(YOUNGS) --poisson 0.3 --density 200
# the clamp: the first two rows of vertices (rows are SIZE sqrt(3)/2 apart)
CLAMP := y<$(shell awk 'BEGIN {print -0.5 + 1.3 * $(SIZE)}')
D ?= 3
BOX ?= 0.05
TRAIN_GRID ?= 7
TEST ?= 200
STEPS_NM ?= 20000
RUNS = modes quadratic neural nmderiv supervised
NMFLAGS = --mesh $(OUT)/mesh.h5 --modes $(OUT)/model-modes.h5 --rank $(D) --box $(BOX) --box-scaling uniform \
  --seed $(SEED) $(QUIET)
$(eval $(call stamp_rule,mesh,$(SIZE) $(THICKNESS) $(CLAMP)))
$(eval $(call stamp_rule,material,$(MAT) $(D)))
$(eval $(call stamp_rule,box,$(BOX) $(TRAIN_GRID) $(TEST) $(SEED)))
$(eval $(call stamp_rule,train,$(STEPS_NM)))

.PHONY: all
all: $(OUT)/table.md
	@cat $<

$(OUT)/mesh.h5: $(call stamp,mesh)
	@mkdir -p $(@D)
	crom-mesh sheet --dims 1,1,1 --size $(SIZE) --thickness $(THICKNESS) --region clamp='$(CLAMP)' $(QUIET) -o $@

$(OUT)/model-modes.h5: $(OUT)/mesh.h5 $(call stamp,material)
	crom-modes $(MAT) --pin clamp --count $(D) $(QUIET) -o $@ $<
$(OUT)/eq-train.h5: $(OUT)/model-modes.h5 $(OUT)/mesh.h5 $(call stamp,box)
	crom-fullsim --equilibria $< --pin clamp $(MAT) --grid $(TRAIN_GRID) --box $(BOX) $(QUIET) -o $@ $(OUT)/mesh.h5
$(OUT)/eq-test.h5: $(OUT)/model-modes.h5 $(OUT)/mesh.h5 $(call stamp,box)
	crom-fullsim --equilibria $< --pin clamp $(MAT) --random $(TEST) --box $(BOX) --seed $$(( $(SEED) + 100 )) $(QUIET) \
	  -o $@ $(OUT)/mesh.h5

$(OUT)/model-quadratic.h5: $(OUT)/model-modes.h5 $(OUT)/mesh.h5
	crom-fitfield --objective neuralmodes --derivatives $(NMFLAGS) $(MAT) --pin clamp --steps 0 -o $@
$(OUT)/model-neural.h5: $(OUT)/model-modes.h5 $(OUT)/mesh.h5 $(call stamp,box) $(call stamp,train)
	crom-fitfield --objective neuralmodes $(NMFLAGS) --steps $(STEPS_NM) -o $@
$(OUT)/model-nmderiv.h5: $(OUT)/model-modes.h5 $(OUT)/mesh.h5 $(call stamp,box) $(call stamp,train)
	crom-fitfield --objective neuralmodes --derivatives $(NMFLAGS) $(MAT) --pin clamp --steps $(STEPS_NM) -o $@
$(OUT)/model-supervised.h5: $(OUT)/model-modes.h5 $(OUT)/eq-train.h5 $(OUT)/mesh.h5 $(call stamp,train)
	crom-fitfield --objective neuralmodes --supervised $(OUT)/eq-train.h5 $(NMFLAGS) --steps $(STEPS_NM) -o $@

$(OUT)/metrics-%.txt: $(OUT)/model-%.h5 $(OUT)/eq-test.h5
	crom-metrics --equilibria $(OUT)/eq-test.h5 $< > $@.tmp && mv $@.tmp $@

$(OUT)/table.md: $(foreach r,$(RUNS),$(OUT)/metrics-$(r).txt)
	@( v() { awk -v key="$$2" -v k="$$3" '$$1 == key {print $$k}' "$$1"; }; \
	   echo "### Square shell, E = $(YOUNGS) Pa, $(D) modes, z in [-$(BOX), $(BOX)]^$(D) m: \
	$$(crom-info $(OUT)/mesh.h5 | sed -n 's/^ *\([0-9]* vertices, [0-9]* triangles\).*/\1/p')"; echo; \
	   echo "$(TEST) held-out equilibria (crom-fullsim --equilibria), mean elastic energy \
	$$(v $(OUT)/metrics-modes.txt elastic_energy: 10) J, mean stress $$(v $(OUT)/metrics-modes.txt von_mises_stress: 10) Pa; \
	supervised on $$(( $(TRAIN_GRID) * $(TRAIN_GRID) * $(TRAIN_GRID) )) training equilibria."; echo; \
	   echo "| subspace | energy / equilibria's | mean stress (Pa) | max stress (Pa) | stress error | nodal force error (N) | displacement error | build (s) |"; \
	   echo "|---|---:|---:|---:|---:|---:|---:|---:|"; \
	   for r in $(RUNS); do \
	     f=$(OUT)/metrics-$$r.txt; \
	     secs=$$(crom-info $(OUT)/model-$$r.h5 | awk '$$1 == "training_seconds" {printf "%.1f", $$2}'); \
	     echo "| $$r | $$(v $$f elastic_energy: 16) | $$(v $$f von_mises_stress: 3) | $$(v $$f von_mises_stress: 6) \
	| $$(v $$f von_mises_stress: 17) | $$(v $$f nodal_force_error: 2) | $$(v $$f displacement_error: 2) | $${secs:--} |"; \
	   done ) > $@.tmp && mv $@.tmp $@
