# tug.mk — LiCROM §6.2, Fig. 3: a soft column standing on its pinned base is
# tugged at a handle (its top) by a scheduled force, then let go, and wobbles.
# One basis is trained on a few tugs in different directions; the reduced run
# then tugs in a new direction and, mid-run, swaps the whole mesh for a shape
# never seen in training (crom-remesh swap --fit: same frame, the predicate
# regions base and handle re-evaluated on it, a cubature of its own). The
# state carries over in q: after the swap the new body continues the motion,
# with the physical response of its own geometry.
#
#   make -f pipelines/tug.mk -j2            # runs/tug/table.md, strip.png, swap.pvd, swap.xdmf, *.plot.png
#   make -f pipelines/tug.mk -j2 SIZE=0.013   # about the paper's interactive size (~100K vertices, estimated)
#   make -f pipelines/tug.mk OTHER='superquadric --exponent 8 --dims 0.6,1,0.6' SWAP=30
#
# Measured: 3 min 06 s for the defaults with make -j2 on the 2-core machine
# (shared with other jobs): SIZE=0.04 gives a 3.2K-vertex column and a 2.7K-
# vertex box, 3 training tugs x 80 steps; training (EPOCHS=3000 from
# common.mk) takes 150 s of it.
#
# experiment defaults come before common.mk's (the column at SIZE has ~3K vertices)
POINTS ?= 1000
include $(dir $(lastword $(MAKEFILE_LIST)))common.mk

OUT ?= runs/tug
SIZE ?= 0.04
STEPS ?= 80
DT ?= 0.01
YOUNGS ?= 5e5
# the body: a column of radius 0.25 and height 1; base pinned, handle tugged
BODY ?= cylinder --radius 0.25 --height 1
REGIONS = --region base='y<-0.45' --region handle='y>0.4'
# the shape swapped in mid-run (fitted into the body's frame)
OTHER ?= box --dims 0.4,1,0.4
# tug forces on the handle (N), applied during [0, PULL] s, then released
LOADS ?= 800,0,0 0,0,800 -600,0,-600
PULL ?= 0.3
# the test tug (a direction not in LOADS) and the step before which the mesh is swapped
TUG ?= 500,0,-500
SWAP ?= $(shell echo $$(( $(STEPS) / 2 )))
scenario = --youngs $(YOUNGS) --pin base --force 'handle=$(1)@0:$(PULL)' --gravity 0,-9.81,0 --dt $(DT) --steps $(STEPS)
NLOADS := $(shell seq 1 $(words $(LOADS)))

CUB_FLAGS = --scheme $(CUBATURE) --count $(COUNT) --seed $(SEED)
$(eval $(call stamp_rule,mesh,$(SIZE) $(BODY) $(OTHER) $(REGIONS)))
$(eval $(call stamp_rule,scenario,$(call scenario,$(LOADS) $(TUG) $(PULL))))
$(eval $(call stamp_rule,sample,$(POINTS) $(SEED)))
$(eval $(call stamp_rule,fit,$(FIT_FLAGS)))
$(eval $(call stamp_rule,cubature,$(CUB_FLAGS)))
$(eval $(call stamp_rule,reduced,$(SOLVER) $(SWAP)))

PLOTS = $(OUT)/loss.plot.png $(OUT)/error.plot.png $(OUT)/cost.plot.png
.PHONY: all plots
all: $(OUT)/summary.txt
# the closing report, remade (and shown) only when what it reports changes,
# so a finished run has nothing left to do, not even under make -n
$(OUT)/summary.txt: $(OUT)/table.md $(OUT)/strip.png $(OUT)/swap.pvd $(OUT)/swap.xdmf $(PLOTS)
	@( cat $(OUT)/table.md; echo; \
	   echo "pictures: $(OUT)/strip.png (the swapping reduced run over the full runs of the body and of the other shape); plots: $(OUT)/*.plot.png"; \
	   echo "ParaView: $(OUT)/swap.pvd or $(OUT)/swap.xdmf (the swapping run, each frame on the mesh it had)" ) > $@.tmp && mv $@.tmp $@ && cat $@
plots: $(PLOTS)

$(OUT)/body.h5: $(call stamp,mesh)
	@mkdir -p $(@D)
	crom-mesh $(BODY) --size $(SIZE) $(REGIONS) $(QUIET) -o $@
$(OUT)/other-raw.h5: $(call stamp,mesh)
	@mkdir -p $(@D)
	crom-mesh $(OTHER) --size $(SIZE) $(QUIET) -o $@
# the unseen shape in the body's frame, with base and handle re-evaluated on it
$(OUT)/other.h5: $(OUT)/body.h5 $(OUT)/other-raw.h5
	crom-remesh swap $(OUT)/other-raw.h5 --fit $(QUIET) -o $@ $<

# training data: tug K of LOADS on the body
$(OUT)/full-load%.h5 $(OUT)/full-load%.csv &: $(OUT)/body.h5 $(call stamp,scenario)
	crom-fullsim $(call scenario,$(word $*,$(LOADS))) $(QUIET) --stats $(OUT)/full-load$*.csv -o $(OUT)/full-load$*.h5 $<
# ground truth of the test tug on the body and on the other shape
$(OUT)/full-tug-%.h5 $(OUT)/full-tug-%.csv &: $(OUT)/%.h5 $(call stamp,scenario)
	crom-fullsim $(call scenario,$(TUG)) $(QUIET) --stats $(OUT)/full-tug-$*.csv -o $(OUT)/full-tug-$*.h5 $<

$(OUT)/samples.h5: $(foreach k,$(NLOADS),$(OUT)/full-load$(k).h5) $(call stamp,sample)
	crom-sample --points $(POINTS) --seed $(SEED) -o $@ $(filter %.h5,$^)

$(OUT)/model.h5: $(OUT)/samples.h5 $(call stamp,fit)
	crom-fitfield $(FIT_FLAGS) $(QUIET) -o $@ < $<

$(OUT)/poses-%.h5: $(OUT)/model.h5 $(OUT)/full-%.h5
	crom-encode --model $< $(QUIET) -o $@ < $(OUT)/full-$*.h5

POSES = $(foreach k,$(NLOADS),$(OUT)/poses-load$(k).h5)
$(OUT)/cub-%.h5: $(OUT)/model.h5 $(OUT)/%.h5 $(POSES) $(call stamp,cubature)
	crom-cubature --model $< $(CUB_FLAGS) $(addprefix --poses ,$(POSES)) $(QUIET) -o $@ $(OUT)/$*.h5

# reduced runs: the training tugs and the test tug on the body, the test tug
# on the other shape from the start, and the swap
$(OUT)/red-load%.h5 $(OUT)/red-load%.csv &: $(OUT)/cub-body.h5 $(call stamp,reduced) $(call stamp,scenario)
	crom-reducedstep --cubature $< --solver $(SOLVER) $(IND_FLAGS) $(call scenario,$(word $*,$(LOADS))) $(QUIET) \
	  --stats $(OUT)/red-load$*.csv -o $(OUT)/red-load$*.h5
$(OUT)/red-tug-%.h5 $(OUT)/red-tug-%.csv &: $(OUT)/cub-%.h5 $(call stamp,reduced) $(call stamp,scenario)
	crom-reducedstep --cubature $< --solver $(SOLVER) $(IND_FLAGS) $(call scenario,$(TUG)) $(QUIET) \
	  --stats $(OUT)/red-tug-$*.csv -o $(OUT)/red-tug-$*.h5
$(OUT)/schedule.txt: $(OUT)/cub-other.h5 $(call stamp,reduced)
	echo "$(SWAP) $<" $(ATOMIC)
$(OUT)/swap.h5 $(OUT)/swap.csv &: $(OUT)/cub-body.h5 $(OUT)/schedule.txt $(call stamp,scenario)
	crom-reducedstep --cubature $< --schedule $(OUT)/schedule.txt --solver $(SOLVER) $(IND_FLAGS) $(call scenario,$(TUG)) $(QUIET) \
	  --stats $(OUT)/swap.csv -o $(OUT)/swap.h5

$(OUT)/diff-load%.txt: $(OUT)/red-load%.h5 $(OUT)/full-load%.h5 $(OUT)/model.h5
	crom-diff $< $(OUT)/full-load$*.h5 --model $(OUT)/model.h5 $(ATOMIC)
$(OUT)/diff-tug-%.txt $(OUT)/diff-tug-%.csv &: $(OUT)/red-tug-%.h5 $(OUT)/full-tug-%.h5 $(OUT)/model.h5
	crom-diff $< $(OUT)/full-tug-$*.h5 --model $(OUT)/model.h5 --csv $(OUT)/diff-tug-$*.csv > $(OUT)/diff-tug-$*.txt
# no full run swaps meshes: the swap is compared, decoded on each mesh, with
# the full run of the body (equal until the swap) and with that of the other
# shape (whose motion the swapped body takes on)
$(OUT)/diff-swap-vs-%.txt $(OUT)/diff-swap-vs-%.csv &: $(OUT)/swap.h5 $(OUT)/full-tug-%.h5 $(OUT)/model.h5
	crom-diff $< $(OUT)/full-tug-$*.h5 --model $(OUT)/model.h5 --csv $(OUT)/diff-swap-vs-$*.csv > $(OUT)/diff-swap-vs-$*.txt

$(OUT)/rows.txt: $(foreach k,$(NLOADS),$(OUT)/diff-load$(k).txt) $(OUT)/diff-tug-body.txt $(OUT)/diff-tug-other.txt \
                 $(OUT)/diff-swap-vs-body.txt $(OUT)/diff-swap-vs-other.txt
	( for k in $(NLOADS); do \
	    echo "trained-tug-$$k $(OUT)/full-load$$k.csv $(OUT)/red-load$$k.csv $(OUT)/diff-load$$k.txt $(OUT)/cub-body.h5 $(OUT)/model.h5"; done; \
	  echo "new-tug $(OUT)/full-tug-body.csv $(OUT)/red-tug-body.csv $(OUT)/diff-tug-body.txt $(OUT)/cub-body.h5 $(OUT)/model.h5"; \
	  echo "unseen-shape(new-tug) $(OUT)/full-tug-other.csv $(OUT)/red-tug-other.csv $(OUT)/diff-tug-other.txt $(OUT)/cub-other.h5 $(OUT)/model.h5"; \
	  echo "swap-at-step-$(SWAP)(vs-body-full) $(OUT)/full-tug-body.csv $(OUT)/swap.csv $(OUT)/diff-swap-vs-body.txt $(OUT)/cub-other.h5 $(OUT)/model.h5"; \
	  echo "swap-at-step-$(SWAP)(vs-other-full) $(OUT)/full-tug-other.csv $(OUT)/swap.csv $(OUT)/diff-swap-vs-other.txt $(OUT)/cub-other.h5 $(OUT)/model.h5" ) $(ATOMIC)
$(OUT)/table.md: $(OUT)/rows.txt
	( $(TOP)/pipelines/table.sh "tug: a column tugged at its top, trained on $(words $(LOADS)) tugs (forces $(LOADS) N); a new tug ($(TUG) N) on it, on an unseen shape, and swapping to that shape before step $(SWAP) (LiCROM Fig. 3)" $<; echo; \
	  echo "No full run swaps meshes: the swapping run is compared, decoded on each mesh, with the column's full run of the"; \
	  echo "new tug (the same until the swap) and with the unseen shape's (tugged from rest: it shows how the swapped body's"; \
	  echo "motion differs from the one it would have had from the start)." ) $(ATOMIC)

# pictures: the swapping run (each frame on its mesh) over the full runs of
# the test tug on the body and on the other shape
$(OUT)/strip.png: $(OUT)/swap.h5 $(OUT)/full-tug-body.h5 $(OUT)/full-tug-other.h5 $(OUT)/model.h5
	crom-export --format strip --follow-schedule --model $(OUT)/model.h5 --compare $(OUT)/full-tug-body.h5 \
	  --compare $(OUT)/full-tug-other.h5 --columns 6 $(QUIET) -o $@ $<
$(OUT)/swap.pvd: $(OUT)/swap.h5 $(OUT)/model.h5
	crom-export --format pvd --follow-schedule --model $(OUT)/model.h5 $(QUIET) -o $@ $<
$(OUT)/swap.xdmf: $(OUT)/swap.h5 $(OUT)/model.h5
	crom-export --format xdmf --follow-schedule --model $(OUT)/model.h5 $(QUIET) -o $@ $<

$(OUT)/loss.plot.png: $(OUT)/model.h5
	$(TOP)/pipelines/plot.sh loss $@ $< "tug: training loss"
$(OUT)/error.plot.png: $(OUT)/diff-tug-body.csv $(OUT)/diff-tug-other.csv $(OUT)/diff-swap-vs-body.csv $(OUT)/diff-swap-vs-other.csv
	$(TOP)/pipelines/plot.sh error $@ "tug: reduced vs full, relative error (swap before step $(SWAP))" \
	  $(OUT)/diff-tug-body.csv=new-tug $(OUT)/diff-tug-other.csv=unseen-shape \
	  $(OUT)/diff-swap-vs-body.csv=swap-vs-body $(OUT)/diff-swap-vs-other.csv=swap-vs-other
$(OUT)/cost.plot.png: $(OUT)/table.md
	$(TOP)/pipelines/plot.sh cost $@ $(OUT)/rows.txt.csv "tug: step cost"
