# punching.mk — LiCROM §6.1, Fig. 10: a block fixed at its base sways and
# sags under gravity after a short sideways push at the top. One basis is
# trained on full runs of the intact block and of the block with 1..N square
# tunnels punched through it (crom-remesh punch); the reduced run then punches
# the tunnels one after another while the block moves: a --schedule switches
# to the mesh with one more hole, the state carries over in q (the rest of the
# block stays where it was; only the punched part is gone).
#
#   make -f pipelines/punching.mk -j2         # runs/punching/table.md, strip.png, punch.pvd, punch.xdmf, *.plot.png
#   make -f pipelines/punching.mk -j2 SIZE=0.036   # the paper's size: ~20K vertices (18.6K at 0.037)
#   make -f pipelines/punching.mk CUBATURE=metis ENCODER=pointnet RANK=12  # swap a stage
#
# Measured: 5 min 06 s for the defaults with make -j2 on the 2-core machine
# (shared with other jobs): SIZE=0.06 gives a 4.7K-vertex block, 5 training
# meshes x 80 steps; training (EPOCHS=3000 from common.mk) takes 183 s of it.
include $(dir $(lastword $(MAKEFILE_LIST)))common.mk

OUT ?= runs/punching
SIZE ?= 0.06
STEPS ?= 80
DT ?= 0.01
YOUNGS ?= 1e5
# the push: a total sideways force on the top layer for a short while
PUSH ?= 3000,0,0@0:0.15
SCENARIO = --youngs $(YOUNGS) --pin bottom --force 'top=$(PUSH)' --gravity 0,-9.81,0 --dt $(DT) --steps $(STEPS)
# square tunnels through the block along z (boxes X0,Y0,Z0,X1,Y1,Z1), punched
# in this order: mesh-K has the first K of them
HOLES ?= -0.32,0.08,-1,-0.08,0.32,1  0.08,0.08,-1,0.32,0.32,1  -0.32,-0.32,-1,-0.08,-0.08,1  0.08,-0.32,-1,0.32,-0.08,1
NHOLES := $(words $(HOLES))
MESHES := $(shell seq 0 $(NHOLES))
# the meshes whose full runs train the basis (all by default, as in the paper)
TRAIN ?= $(MESHES)
# the reduced run punches hole K at step FIRST + (K-1) * GAP
FIRST ?= $(shell echo $$(( $(STEPS) / 5 )))
GAP ?= $(shell echo $$(( ($(STEPS) * 3 / 5) / ($(NHOLES) > 1 ? $(NHOLES) - 1 : 1) )))

CUB_FLAGS = --scheme $(CUBATURE) --count $(COUNT) --seed $(SEED)
RED_FLAGS = --solver $(SOLVER) $(SCENARIO) $(IND_FLAGS)
$(eval $(call stamp_rule,mesh,$(SIZE)))
$(eval $(call stamp_rule,holes,$(HOLES)))
$(eval $(call stamp_rule,scenario,$(SCENARIO)))
$(eval $(call stamp_rule,sample,$(POINTS) $(SEED) $(TRAIN)))
$(eval $(call stamp_rule,fit,$(FIT_FLAGS)))
$(eval $(call stamp_rule,cubature,$(CUB_FLAGS)))
$(eval $(call stamp_rule,reduced,$(RED_FLAGS) $(FIRST) $(GAP)))

PLOTS = $(OUT)/loss.plot.png $(OUT)/error.plot.png $(OUT)/cost.plot.png
.PHONY: all plots
all: $(OUT)/summary.txt
# the closing report, remade (and shown) only when what it reports changes,
# so a finished run has nothing left to do, not even under make -n
$(OUT)/summary.txt: $(OUT)/table.md $(OUT)/strip.png $(OUT)/punch.pvd $(OUT)/punch.xdmf $(PLOTS)
	@( cat $(OUT)/table.md; echo; \
	   echo "pictures: $(OUT)/strip.png (reduced punching run over the intact and the $(NHOLES)-hole full runs); plots: $(OUT)/*.plot.png"; \
	   echo "ParaView: $(OUT)/punch.pvd or $(OUT)/punch.xdmf (the punching run, each frame on the mesh it had)" ) > $@.tmp && mv $@.tmp $@ && cat $@
plots: $(PLOTS)

# the block in the bounding cube [-0.5, 0.5]^3; top and bottom layers are regions
$(OUT)/mesh-0.h5: $(call stamp,mesh)
	@mkdir -p $(@D)
	crom-mesh box --size $(SIZE) --region top='y>0.45' --region bottom='y<-0.45' $(QUIET) -o $@
$(OUT)/mesh-%.h5: $(OUT)/mesh-0.h5 $(call stamp,holes)
	crom-remesh punch $(addprefix --box ,$(wordlist 1,$*,$(HOLES))) $(QUIET) -o $@ $<

# ground truth and training data: every mesh under the same scenario
$(OUT)/full-%.h5 $(OUT)/full-%.csv &: $(OUT)/mesh-%.h5 $(call stamp,scenario)
	crom-fullsim $(SCENARIO) $(QUIET) --stats $(OUT)/full-$*.csv -o $(OUT)/full-$*.h5 $<

$(OUT)/samples.h5: $(foreach k,$(TRAIN),$(OUT)/full-$(k).h5) $(call stamp,sample)
	crom-sample --points $(POINTS) --seed $(SEED) -o $@ $(filter %.h5,$^)

$(OUT)/model.h5: $(OUT)/samples.h5 $(call stamp,fit)
	crom-fitfield $(FIT_FLAGS) $(QUIET) -o $@ < $<

$(OUT)/poses-%.h5: $(OUT)/model.h5 $(OUT)/full-%.h5
	crom-encode --model $< $(QUIET) -o $@ < $(OUT)/full-$*.h5

POSES = $(foreach k,$(TRAIN),$(OUT)/poses-$(k).h5)
$(OUT)/cub-%.h5: $(OUT)/model.h5 $(OUT)/mesh-%.h5 $(POSES) $(call stamp,cubature)
	crom-cubature --model $< $(CUB_FLAGS) $(addprefix --poses ,$(POSES)) $(QUIET) -o $@ $(OUT)/mesh-$*.h5

# reduced runs on each mesh, judged against the full runs
$(OUT)/red-%.h5 $(OUT)/red-%.csv &: $(OUT)/cub-%.h5 $(call stamp,reduced)
	crom-reducedstep --cubature $< $(RED_FLAGS) $(QUIET) --stats $(OUT)/red-$*.csv -o $(OUT)/red-$*.h5
$(OUT)/diff-%.txt: $(OUT)/red-%.h5 $(OUT)/full-%.h5 $(OUT)/model.h5
	crom-diff $< $(OUT)/full-$*.h5 --model $(OUT)/model.h5 $(ATOMIC)

# the punching run: starts intact, hole K punched before step FIRST + (K-1) GAP
PUNCH := $(shell seq 1 $(NHOLES))
$(OUT)/schedule.txt: $(foreach k,$(PUNCH),$(OUT)/cub-$(k).h5) $(call stamp,reduced)
	for k in $(PUNCH); do echo "$$(( $(FIRST) + (k - 1) * $(GAP) )) $(OUT)/cub-$$k.h5"; done $(ATOMIC)
$(OUT)/punch.h5 $(OUT)/punch.csv &: $(OUT)/cub-0.h5 $(OUT)/schedule.txt
	crom-reducedstep --cubature $< --schedule $(OUT)/schedule.txt $(RED_FLAGS) $(QUIET) \
	  --stats $(OUT)/punch.csv -o $(OUT)/punch.h5
# no full run punches holes mid-run: the punching run is compared with the
# intact block's full run (equal until the first punch) and the fully punched one
$(OUT)/diff-punch-vs-%.txt $(OUT)/diff-punch-vs-%.csv &: $(OUT)/punch.h5 $(OUT)/full-%.h5 $(OUT)/model.h5
	crom-diff $< $(OUT)/full-$*.h5 --model $(OUT)/model.h5 --csv $(OUT)/diff-punch-vs-$*.csv > $(OUT)/diff-punch-vs-$*.txt

$(OUT)/rows.txt: $(foreach k,$(MESHES),$(OUT)/diff-$(k).txt $(OUT)/red-$(k).csv) $(OUT)/diff-punch-vs-0.txt $(OUT)/diff-punch-vs-$(NHOLES).txt
	( for k in $(MESHES); do \
	    case " $(TRAIN) " in *" $$k "*) t=trained;; *) t=unseen;; esac; \
	    echo "$$k-holes($$t) $(OUT)/full-$$k.csv $(OUT)/red-$$k.csv $(OUT)/diff-$$k.txt $(OUT)/cub-$$k.h5 $(OUT)/model.h5"; done; \
	  echo "punching-0-to-$(NHOLES)(vs-intact-full) $(OUT)/full-0.csv $(OUT)/punch.csv $(OUT)/diff-punch-vs-0.txt $(OUT)/cub-$(NHOLES).h5 $(OUT)/model.h5"; \
	  echo "punching-0-to-$(NHOLES)(vs-$(NHOLES)-hole-full) $(OUT)/full-$(NHOLES).csv $(OUT)/punch.csv $(OUT)/diff-punch-vs-$(NHOLES).txt $(OUT)/cub-$(NHOLES).h5 $(OUT)/model.h5" ) $(ATOMIC)
$(OUT)/table.md: $(OUT)/rows.txt
	( $(TOP)/pipelines/table.sh "punching: block with 0..$(NHOLES) tunnels, holes punched during the reduced run (LiCROM Fig. 10)" $<; echo; \
	  echo "No full run punches holes mid-run: the punching run (hole K before step $(FIRST) + (K-1)·$(GAP)) is compared with the"; \
	  echo "intact block's full run (the same until the first punch) and with the $(NHOLES)-hole block's (what it becomes); the latter"; \
	  echo "mostly measures how the punching history differs from having the holes from the start." ) $(ATOMIC)

# pictures: the punching run, each frame on its current mesh, over the full
# runs of the intact and of the fully punched block
$(OUT)/strip.png: $(OUT)/punch.h5 $(OUT)/full-0.h5 $(OUT)/full-$(NHOLES).h5
	crom-export --format strip --follow-schedule --model $(OUT)/model.h5 --compare $(OUT)/full-0.h5 \
	  --compare $(OUT)/full-$(NHOLES).h5 --columns 6 $(QUIET) -o $@ $<
$(OUT)/punch.pvd: $(OUT)/punch.h5
	crom-export --format pvd --follow-schedule --model $(OUT)/model.h5 $(QUIET) -o $@ $<
$(OUT)/punch.xdmf: $(OUT)/punch.h5
	crom-export --format xdmf --follow-schedule --model $(OUT)/model.h5 $(QUIET) -o $@ $<

$(OUT)/loss.plot.png: $(OUT)/model.h5
	$(TOP)/pipelines/plot.sh loss $@ $< "punching: training loss"
$(OUT)/error.plot.png: $(OUT)/diff-punch-vs-0.csv $(OUT)/diff-punch-vs-$(NHOLES).csv
	$(TOP)/pipelines/plot.sh error $@ "punching run: relative error against full runs" \
	  $(OUT)/diff-punch-vs-0.csv=vs-intact $(OUT)/diff-punch-vs-$(NHOLES).csv=vs-$(NHOLES)-holes
$(OUT)/cost.plot.png: $(OUT)/table.md
	$(TOP)/pipelines/plot.sh cost $@ $(OUT)/rows.txt.csv "punching: step cost"
