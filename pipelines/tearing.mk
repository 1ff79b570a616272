# tearing.mk — LiCROM §6.1, Fig. 6: a plate clamped at its border sags under
# gravity; one basis is trained on the intact plate and on the plate with a
# full Y-shaped cut; the reduced run then grows the cut progressively by
# switching cubature meshes mid-run (the state stays in q).
#
#   make -f pipelines/tearing.mk              # runs/tearing/table.md, strip.png, tear.pvd
#   make -f pipelines/tearing.mk SIZE=0.02 STAGES=8   # finer plate
include $(dir $(lastword $(MAKEFILE_LIST)))common.mk

OUT ?= runs/tearing
SIZE ?= 0.04
THICK ?= 0.04
STEPS ?= 60
DT ?= 0.01
STAGES ?= 5
COUNT ?= 150
# interior (default): random points in the tets; vertices (with POINTS at most
# the intact plate's 1675 vertices): the field trains 3.6x faster, as well (README)
SAMPLE_MODE ?= interior
YOUNGS ?= 1e5
# the plate lies in the xz-plane, thin along y; its border is clamped
SCENARIO = --youngs $(YOUNGS) --pin 'x<-0.49' --pin 'x>0.49' --pin 'z<-0.49' --pin 'z>0.49' \
           --gravity 0,-9.81,0 --dt $(DT) --steps $(STEPS)
# the Y: a stem from z = -0.35 up to the fork at the centre, two branches to the far side
Y = --segment 0,-0.35,0,0 --segment 0,0,-0.25,0.3 --segment 0,0,0.25,0.3
# CUT_FEATURES=1 (default): the field takes, besides X, one feature per segment
# of the Y that jumps across it (crom-fitfield --cut-segment), so that it can
# open the crack; 0: a field of X alone, as in the paper
CUT_FEATURES ?= 1
FIT_FLAGS += $(if $(filter 1,$(CUT_FEATURES)),$(subst --segment,--cut-segment,$(Y)) --cut-axis y)

.PHONY: all
all: $(OUT)/summary.txt
# the closing report, remade (and shown) only when what it reports changes,
# so a finished run has nothing left to do, not even under make -n
$(OUT)/summary.txt: $(OUT)/table.md $(OUT)/strip.png $(OUT)/basis.png $(OUT)/tear.pvd
	@( cat $(OUT)/table.md; echo "pictures: $(OUT)/strip.png, the basis fields $(OUT)/basis.png; ParaView: $(OUT)/tear.pvd" ) \
	  > $@.tmp && mv $@.tmp $@ && cat $@

$(OUT)/intact.h5:
	@mkdir -p $(@D)
	crom-mesh plate --dims 1,$(THICK),1 --size $(SIZE) -o $@

# stage_K.h5 for K = 1..STAGES; stage_$(STAGES) is the full Y
$(OUT)/stages/stage_$(STAGES).h5: $(OUT)/intact.h5
	crom-remesh cut $(Y) --axis y --stages $(STAGES) --all-stages $(OUT)/stages $(QUIET) < $<
$(OUT)/cut.h5: $(OUT)/stages/stage_$(STAGES).h5
	cp $< $@

# training data: the intact and the fully cut plate
$(OUT)/full-%.h5 $(OUT)/full-%.csv &: $(OUT)/%.h5
	crom-fullsim $(SCENARIO) $(QUIET) --stats $(OUT)/full-$*.csv -o $(OUT)/full-$*.h5 $<

$(OUT)/samples.h5: $(OUT)/full-intact.h5 $(OUT)/full-cut.h5
	crom-sample --points $(POINTS) --mode $(SAMPLE_MODE) --seed $(SEED) -o $@ $^

$(OUT)/model.h5: $(OUT)/samples.h5
	crom-fitfield $(FIT_FLAGS) -o $@ < $<

$(OUT)/poses-%.h5: $(OUT)/model.h5 $(OUT)/full-%.h5
	crom-encode --model $< $(QUIET) -o $@ < $(OUT)/full-$*.h5

POSES = --poses $(OUT)/poses-intact.h5 --poses $(OUT)/poses-cut.h5
CUBFLAGS = --scheme $(CUBATURE) --count $(COUNT) $(POSES) --seed $(SEED) $(QUIET)
$(OUT)/cub-intact.h5 $(OUT)/cub-cut.h5: $(OUT)/cub-%.h5: $(OUT)/model.h5 $(OUT)/%.h5 $(OUT)/poses-intact.h5 $(OUT)/poses-cut.h5
	crom-cubature --model $< $(CUBFLAGS) -o $@ $(OUT)/$*.h5
$(OUT)/cub-stage-%.h5: $(OUT)/model.h5 $(OUT)/stages/stage_$(STAGES).h5 $(OUT)/poses-intact.h5 $(OUT)/poses-cut.h5
	crom-cubature --model $< $(CUBFLAGS) -o $@ $(OUT)/stages/stage_$*.h5

# reduced runs on the two training meshes, judged against the full runs
$(OUT)/red-%.h5 $(OUT)/red-%.csv &: $(OUT)/cub-%.h5
	crom-reducedstep --cubature $< --solver $(SOLVER) $(SCENARIO) $(IND_FLAGS) $(QUIET) --stats $(OUT)/red-$*.csv -o $(OUT)/red-$*.h5
$(OUT)/diff-%.txt: $(OUT)/red-%.h5 $(OUT)/full-%.h5 $(OUT)/model.h5
	crom-diff $< $(OUT)/full-$*.h5 --model $(OUT)/model.h5 $(ATOMIC)

# the progressive tear: the cut grows during the second half of the run
STAGE_LIST := $(shell seq 1 $(STAGES))
$(OUT)/schedule.txt: $(foreach k,$(STAGE_LIST),$(OUT)/cub-stage-$(k).h5)
	for k in $(STAGE_LIST); do echo "$$(( $(STEPS) / 2 + (k - 1) * $(STEPS) / (2 * $(STAGES)) + 1 )) $(OUT)/cub-stage-$$k.h5"; done $(ATOMIC)
$(OUT)/tear.h5 $(OUT)/tear.csv &: $(OUT)/cub-intact.h5 $(OUT)/schedule.txt
	crom-reducedstep --cubature $< --schedule $(OUT)/schedule.txt --solver $(SOLVER) $(SCENARIO) $(IND_FLAGS) $(QUIET) \
	  --stats $(OUT)/tear.csv -o $(OUT)/tear.h5
$(OUT)/diff-tear.txt: $(OUT)/tear.h5 $(OUT)/full-intact.h5 $(OUT)/model.h5
	crom-diff $< $(OUT)/full-intact.h5 --model $(OUT)/model.h5 $(ATOMIC)

$(OUT)/rows.txt: $(OUT)/diff-intact.txt $(OUT)/diff-cut.txt $(OUT)/diff-tear.txt
	( echo "intact $(OUT)/full-intact.csv $(OUT)/red-intact.csv $(OUT)/diff-intact.txt $(OUT)/cub-intact.h5 $(OUT)/model.h5"; \
	  echo "Y-cut $(OUT)/full-cut.csv $(OUT)/red-cut.csv $(OUT)/diff-cut.txt $(OUT)/cub-cut.h5 $(OUT)/model.h5"; \
	  echo "progressive-tear(vs-intact) $(OUT)/full-intact.csv $(OUT)/tear.csv $(OUT)/diff-tear.txt $(OUT)/cub-stage-$(STAGES).h5 $(OUT)/model.h5" ) $(ATOMIC)
$(OUT)/table.md: $(OUT)/rows.txt
	$(TOP)/pipelines/table.sh "tearing: intact and Y-cut plate, cut grown during the reduced run (LiCROM Fig. 6)" $< $(ATOMIC)

# pictures: the torn run, each frame on the mesh cut so far, over the full
# runs of both meshes
$(OUT)/strip.png: $(OUT)/tear.h5 $(OUT)/full-cut.h5 $(OUT)/full-intact.h5
	crom-export --format strip --model $(OUT)/model.h5 --follow-schedule --compare $(OUT)/full-cut.h5 \
	  --compare $(OUT)/full-intact.h5 --columns 5 $(QUIET) -o $@ $<
# the first four basis fields (at most the rank) on the cut plate, each as the
# displacement of 8 cm of its latent (LiCROM Fig. 8: the field jumps across the cut)
$(OUT)/basis.png: $(OUT)/model.h5 $(OUT)/cut.h5
	crom-keyframe --model $< --mesh $(OUT)/cut.h5 --between 0 $(QUIET) -o $(OUT)/basis-keys.h5 \
	  $$(for k in $$(seq 0 $$(( $(RANK) < 4 ? $(RANK) - 1 : 3 ))); do \
	       printf -- '--key %s ' "$$(awk -v r=$(RANK) -v k=$$k 'BEGIN { for (i = 0; i < r; i++) printf "%s%s", i ? "," : "", i == k ? "0.08" : "0" }')"; done)
	crom-export --format strip --model $< --mesh $(OUT)/cut.h5 --columns 4 $(QUIET) -o $@ $(OUT)/basis-keys.h5
$(OUT)/tear.pvd: $(OUT)/tear.h5
	crom-export --format pvd --model $(OUT)/model.h5 --follow-schedule $(QUIET) -o $@ $<
