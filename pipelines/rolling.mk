# rolling.mk — LiCROM §6.1, Fig. 11 and 12: soft bodies fall onto an
# inclined plane (normal (0, √2/2, √2/2) as in the paper: a 45° slope going
# down towards +z) and roll down it with friction. One basis is trained on a
# few superquadrics (sphere to rounded cube); reduced runs follow on them and
# on shapes interpolated between them (exponents in between, Fig. 12's
# interpolation). Both simulators handle the contact the same way: a penalty
# half-space and lagged Coulomb friction at the boundary vertices.
#
# A rolling body's displacement is mostly rigid motion, so the learned basis
# must contain it: recon.md lists crom-encode's reconstruction error of every
# full run and of pure rigid spins (a free body spinning about the rolling
# axis x, and about y, which rolling never shows) projected on the basis.
#
#   make -f pipelines/rolling.mk -j2        # runs/rolling/table.md, recon.md, strip-*.png, red-*.pvd, red-*.xdmf, *.plot.png
#   make -f pipelines/rolling.mk -j2 SIZE=0.028   # the paper's size: ~20K vertices (a sphere has 17.3K at 0.03)
#   make -f pipelines/rolling.mk TRAIN='2 3 6' TEST='2.5 4' MU=0.8 PLANE=0,1,0.5,-0.8
#
# Measured: 5 min 58 s for the defaults with make -j2 on the 2-core machine
# (shared with other jobs): SIZE=0.06 gives 2.6K-3.8K vertices, 2 training and
# 2 interpolated shapes x 100 steps (1 s: each falls onto the slope and rolls ~2.4 m down it);
# training (EPOCHS=3000 from common.mk) takes 199 s of it.
#
# experiment defaults come before common.mk's (the sphere at SIZE has ~2.5K vertices)
POINTS ?= 1000
include $(dir $(lastword $(MAKEFILE_LIST)))common.mk

OUT ?= runs/rolling
SIZE ?= 0.06
STEPS ?= 100
DT ?= 0.01
YOUNGS ?= 5e5
# the slope: keep n.x >= D (n normalized by the simulators), Coulomb friction MU;
# D below every shape in the cube [-0.5, 0.5]^3 (its corner is at -0.707), so
# each starts a little above the plane and falls onto it
PLANE ?= 0,0.7071067811865476,0.7071067811865476,-0.72
MU ?= 0.5
SCENARIO = --youngs $(YOUNGS) --plane $(PLANE),$(MU) --gravity 0,-9.81,0 --dt $(DT) --steps $(STEPS)
# superquadric exponents: training shapes, and shapes in between them
TRAIN ?= 2 5
TEST ?= 2.7 3.5
# rigid-motion probes: a free body (no gravity, no plane) spinning at SPIN rad/s
SPIN ?= 6
PROBES = spinx spiny
ALL := $(TRAIN) $(TEST)

CUB_FLAGS = --scheme $(CUBATURE) --count $(COUNT) --seed $(SEED)
RED_FLAGS = --solver $(SOLVER) $(SCENARIO) $(IND_FLAGS)
$(eval $(call stamp_rule,mesh,$(SIZE)))
$(eval $(call stamp_rule,scenario,$(SCENARIO)))
$(eval $(call stamp_rule,sample,$(POINTS) $(SEED) $(TRAIN)))
$(eval $(call stamp_rule,fit,$(FIT_FLAGS)))
$(eval $(call stamp_rule,cubature,$(CUB_FLAGS)))
$(eval $(call stamp_rule,reduced,$(RED_FLAGS)))
$(eval $(call stamp_rule,probe,$(SPIN) $(DT) $(STEPS) $(YOUNGS)))

PICTURES = $(foreach s,$(ALL),$(OUT)/strip-$(s).png $(OUT)/red-$(s).pvd $(OUT)/red-$(s).xdmf)
PLOTS = $(OUT)/loss.plot.png $(OUT)/error.plot.png $(OUT)/cost.plot.png
.PHONY: all pictures plots
all: $(OUT)/summary.txt
# the closing report, remade (and shown) only when what it reports changes,
# so a finished run has nothing left to do, not even under make -n
$(OUT)/summary.txt: $(OUT)/table.md $(OUT)/recon.md $(PICTURES) $(PLOTS)
	@( cat $(OUT)/table.md; echo; cat $(OUT)/recon.md; echo; \
	   echo "pictures: $(OUT)/strip-*.png (reduced over full, each shape); plots: $(OUT)/*.plot.png"; \
	   echo "ParaView: $(OUT)/red-*.pvd, $(OUT)/red-*.xdmf (reduced runs)" ) > $@.tmp && mv $@.tmp $@ && cat $@
pictures: $(PICTURES)
plots: $(PLOTS)

$(OUT)/mesh-%.h5: $(call stamp,mesh)
	@mkdir -p $(@D)
	crom-mesh superquadric --exponent $* --size $(SIZE) $(QUIET) -o $@

# ground truth (and training data for TRAIN)
$(OUT)/full-%.h5 $(OUT)/full-%.csv &: $(OUT)/mesh-%.h5 $(call stamp,scenario)
	crom-fullsim $(SCENARIO) $(QUIET) --stats $(OUT)/full-$*.csv -o $(OUT)/full-$*.h5 $<

$(OUT)/samples.h5: $(foreach s,$(TRAIN),$(OUT)/full-$(s).h5) $(call stamp,sample)
	crom-sample --points $(POINTS) --seed $(SEED) -o $@ $(filter %.h5,$^)

$(OUT)/model.h5: $(OUT)/samples.h5 $(call stamp,fit)
	crom-fitfield $(FIT_FLAGS) $(QUIET) -o $@ < $<

# latent poses of every full run; crom-encode's one-line summary (the
# reconstruction error of the run in the basis) is kept next to them
$(OUT)/poses-%.h5 $(OUT)/recon-%.txt &: $(OUT)/model.h5 $(OUT)/full-%.h5
	crom-encode --model $< -o $(OUT)/poses-$*.h5 < $(OUT)/full-$*.h5 2> $(OUT)/recon-$*.txt

POSES = $(foreach s,$(TRAIN),$(OUT)/poses-$(s).h5)
$(OUT)/cub-%.h5: $(OUT)/model.h5 $(OUT)/mesh-%.h5 $(POSES) $(call stamp,cubature)
	crom-cubature --model $< $(CUB_FLAGS) $(addprefix --poses ,$(POSES)) $(QUIET) -o $@ $(OUT)/mesh-$*.h5

$(OUT)/red-%.h5 $(OUT)/red-%.csv &: $(OUT)/cub-%.h5 $(call stamp,reduced)
	crom-reducedstep --cubature $< $(RED_FLAGS) $(QUIET) --stats $(OUT)/red-$*.csv -o $(OUT)/red-$*.h5

$(OUT)/diff-%.txt $(OUT)/diff-%.csv &: $(OUT)/red-%.h5 $(OUT)/full-%.h5 $(OUT)/model.h5
	crom-diff $< $(OUT)/full-$*.h5 --model $(OUT)/model.h5 --csv $(OUT)/diff-$*.csv > $(OUT)/diff-$*.txt

$(OUT)/rows.txt: $(foreach s,$(ALL),$(OUT)/diff-$(s).txt $(OUT)/red-$(s).csv $(OUT)/full-$(s).csv)
	( for s in $(TRAIN); do echo "trained-p$$s $(OUT)/full-$$s.csv $(OUT)/red-$$s.csv $(OUT)/diff-$$s.txt $(OUT)/cub-$$s.h5 $(OUT)/model.h5"; done; \
	  for s in $(TEST); do echo "interpolated-p$$s $(OUT)/full-$$s.csv $(OUT)/red-$$s.csv $(OUT)/diff-$$s.txt $(OUT)/cub-$$s.h5 $(OUT)/model.h5"; done ) $(ATOMIC)
$(OUT)/table.md: $(OUT)/rows.txt
	$(TOP)/pipelines/table.sh "rolling: superquadrics rolling down a 45° frictional slope, trained on p = $(TRAIN), interpolated p = $(TEST) (LiCROM Fig. 11, 12)" $< $(ATOMIC)

# rigid-motion probes on the first training shape: spinning freely about x
# (the axis a body rolls about on this slope) and about y (never in training)
$(OUT)/probe-spinx.h5: $(OUT)/mesh-$(firstword $(TRAIN)).h5 $(call stamp,probe)
	crom-fullsim --youngs $(YOUNGS) --gravity 0,0,0 --spin $(SPIN),0,0 --dt $(DT) --steps $(STEPS) $(QUIET) -o $@ $<
$(OUT)/probe-spiny.h5: $(OUT)/mesh-$(firstword $(TRAIN)).h5 $(call stamp,probe)
	crom-fullsim --youngs $(YOUNGS) --gravity 0,0,0 --spin 0,$(SPIN),0 --dt $(DT) --steps $(STEPS) $(QUIET) -o $@ $<
$(OUT)/recon-probe-%.txt: $(OUT)/model.h5 $(OUT)/probe-%.h5
	crom-encode --model $< -o /dev/null < $(OUT)/probe-$*.h5 2> $@

# "reconstruction error 0.0123 over 101 frames" -> a table
$(OUT)/recon.md: $(foreach s,$(ALL),$(OUT)/recon-$(s).txt) $(foreach p,$(PROBES),$(OUT)/recon-probe-$(p).txt)
	( echo "### rolling: is rigid motion in the learned subspace? (crom-encode: ‖Wq − u‖_M / ‖u‖_M over the run)"; echo; \
	  echo "| run | what | reconstruction error |"; echo "|---|---|---:|"; \
	  for s in $(TRAIN); do echo "| p$$s | training run (rolling) | $$(grep -o 'error [0-9.e+-]*' $(OUT)/recon-$$s.txt | head -1 | cut -d' ' -f2) |"; done; \
	  for s in $(TEST); do echo "| p$$s | interpolated shape, its full run | $$(grep -o 'error [0-9.e+-]*' $(OUT)/recon-$$s.txt | head -1 | cut -d' ' -f2) |"; done; \
	  echo "| spin-x | p$(firstword $(TRAIN)) spinning freely about x, $(SPIN) rad/s (the rolling axis) | $$(grep -o 'error [0-9.e+-]*' $(OUT)/recon-probe-spinx.txt | head -1 | cut -d' ' -f2) |"; \
	  echo "| spin-y | p$(firstword $(TRAIN)) spinning freely about y, $(SPIN) rad/s (not in training) | $$(grep -o 'error [0-9.e+-]*' $(OUT)/recon-probe-spiny.txt | head -1 | cut -d' ' -f2) |"; \
	  echo; echo "A small spin-x error means the basis spans finite rotations about the rolling axis (a rotation about a"; \
	  echo "fixed axis is linear in X, so a linear subspace can hold it at any angle); spin-y is the control." ) $(ATOMIC)

# pictures: each reduced run over its full run
$(OUT)/strip-%.png: $(OUT)/red-%.h5 $(OUT)/full-%.h5 $(OUT)/model.h5
	crom-export --format strip --model $(OUT)/model.h5 --mesh $(OUT)/mesh-$*.h5 --compare $(OUT)/full-$*.h5 \
	  --columns 6 $(QUIET) -o $@ $<
$(OUT)/red-%.pvd: $(OUT)/red-%.h5 $(OUT)/model.h5
	crom-export --format pvd --model $(OUT)/model.h5 --mesh $(OUT)/mesh-$*.h5 $(QUIET) -o $@ $<
$(OUT)/red-%.xdmf: $(OUT)/red-%.h5 $(OUT)/model.h5
	crom-export --format xdmf --model $(OUT)/model.h5 --mesh $(OUT)/mesh-$*.h5 $(QUIET) -o $@ $<

$(OUT)/loss.plot.png: $(OUT)/model.h5
	$(TOP)/pipelines/plot.sh loss $@ $< "rolling: training loss"
$(OUT)/error.plot.png: $(foreach s,$(ALL),$(OUT)/diff-$(s).csv)
	$(TOP)/pipelines/plot.sh error $@ "rolling: reduced vs full, relative error" $(foreach s,$(ALL),$(OUT)/diff-$(s).csv=p$(s))
$(OUT)/cost.plot.png: $(OUT)/table.md
	$(TOP)/pipelines/plot.sh cost $@ $(OUT)/rows.txt.csv "rolling: step cost"
