# shapes.mk — LiCROM §6.1, Fig. 5 and 7: one neural basis trained on five
# shapes from sphere to cube compressed from the top, then reduced runs on the
# five and on two shapes unseen in training, each judged against crom-fullsim.
#
#   make -f pipelines/shapes.mk            # runs/shapes/table.md
#   make -f pipelines/shapes.mk -j2 SIZE=0.035 STEPS=100   # about the paper's 20K vertices
#   make -f pipelines/shapes.mk CUBATURE=metis COUNT=300 ENCODER=pointnet
# experiment defaults come before common.mk's
POINTS ?= 500
include $(dir $(lastword $(MAKEFILE_LIST)))common.mk

OUT ?= runs/shapes
SIZE ?= 0.1
STEPS ?= 40
DT ?= 0.01
# superquadric exponents (box = the cube); the paper spans sphere to cube
TRAIN ?= 2 2.5 3.5 6 box
TEST ?= 2.2 4.5
SCENARIO = --velocity 'top=0,-2,0@0:0.1' --pin bottom --gravity 0,0,0 --dt $(DT) --steps $(STEPS)

ALL := $(TRAIN) $(TEST)
CUB_FLAGS = --scheme $(CUBATURE) --count $(COUNT) --seed $(SEED)
RED_FLAGS = --solver $(SOLVER) $(SCENARIO) $(IND_FLAGS)
$(eval $(call stamp_rule,mesh,$(SIZE)))
$(eval $(call stamp_rule,scenario,$(SCENARIO)))
$(eval $(call stamp_rule,sample,$(POINTS) $(SEED) $(TRAIN)))
$(eval $(call stamp_rule,fit,$(FIT_FLAGS)))
$(eval $(call stamp_rule,cubature,$(CUB_FLAGS)))
$(eval $(call stamp_rule,reduced,$(RED_FLAGS)))

PICTURES = $(foreach s,$(ALL),$(OUT)/strip-$(s).png $(OUT)/red-$(s).pvd)
.PHONY: all pictures
all: $(OUT)/summary.txt
# the closing report, remade (and shown) only when what it reports changes,
# so a finished run has nothing left to do, not even under make -n
$(OUT)/summary.txt: $(OUT)/table.md $(PICTURES)
	@( cat $(OUT)/table.md; \
	  echo "pictures: $(OUT)/strip-*.png (reduced above full); ParaView: $(OUT)/red-*.pvd" ) > $@.tmp && mv $@.tmp $@ && cat $@

pictures: $(PICTURES)
$(OUT)/strip-%.png: $(OUT)/red-%.h5 $(OUT)/full-%.h5 $(OUT)/model.h5
	crom-export --format strip --model $(OUT)/model.h5 --mesh $(OUT)/mesh-$*.h5 --compare $(OUT)/full-$*.h5 \
	  --columns 5 $(QUIET) -o $@ $<
$(OUT)/red-%.pvd: $(OUT)/red-%.h5 $(OUT)/model.h5
	crom-export --format pvd --model $(OUT)/model.h5 --mesh $(OUT)/mesh-$*.h5 $(QUIET) -o $@ $<

# meshes in the bounding cube [-0.5, 0.5]^3; top and bottom layers are regions
$(OUT)/mesh-box.h5: $(call stamp,mesh)
	@mkdir -p $(@D)
	crom-mesh box --size $(SIZE) --region top='y>0.45' --region bottom='y<-0.45' -o $@
$(OUT)/mesh-%.h5: $(call stamp,mesh)
	@mkdir -p $(@D)
	crom-mesh superquadric --exponent $* --size $(SIZE) --region top='y>0.45' --region bottom='y<-0.45' -o $@

# ground truth (and training data for TRAIN)
$(OUT)/full-%.h5 $(OUT)/full-%.csv &: $(OUT)/mesh-%.h5 $(call stamp,scenario)
	crom-fullsim $(SCENARIO) $(QUIET) --stats $(OUT)/full-$*.csv -o $(OUT)/full-$*.h5 $<

$(OUT)/samples.h5: $(foreach s,$(TRAIN),$(OUT)/full-$(s).h5) $(call stamp,sample)
	crom-sample --points $(POINTS) --seed $(SEED) -o $@ $(filter %.h5,$^)

$(OUT)/model.h5: $(OUT)/samples.h5 $(call stamp,fit)
	crom-fitfield $(FIT_FLAGS) -o $@ < $<

# training poses: the training runs in latent coordinates
$(OUT)/poses-%.h5: $(OUT)/model.h5 $(OUT)/full-%.h5
	crom-encode --model $< $(QUIET) -o $@ < $(OUT)/full-$*.h5

POSES = $(foreach s,$(TRAIN),$(OUT)/poses-$(s).h5)
$(OUT)/cub-%.h5: $(OUT)/model.h5 $(OUT)/mesh-%.h5 $(POSES) $(call stamp,cubature)
	crom-cubature --model $< $(CUB_FLAGS) $(foreach p,$(POSES),--poses $(p)) $(QUIET) -o $@ $(OUT)/mesh-$*.h5

$(OUT)/red-%.h5 $(OUT)/red-%.csv &: $(OUT)/cub-%.h5 $(call stamp,reduced)
	crom-reducedstep --cubature $< $(RED_FLAGS) $(QUIET) --stats $(OUT)/red-$*.csv -o $(OUT)/red-$*.h5

$(OUT)/diff-%.txt: $(OUT)/red-%.h5 $(OUT)/full-%.h5 $(OUT)/model.h5
	crom-diff $< $(OUT)/full-$*.h5 --model $(OUT)/model.h5 $(ATOMIC)

$(OUT)/rows.txt: $(foreach s,$(ALL),$(OUT)/diff-$(s).txt $(OUT)/red-$(s).csv $(OUT)/full-$(s).csv)
	( for s in $(TRAIN); do echo "shape-$$s $(OUT)/full-$$s.csv $(OUT)/red-$$s.csv $(OUT)/diff-$$s.txt $(OUT)/cub-$$s.h5 $(OUT)/model.h5"; done; \
	  for s in $(TEST); do echo "unseen-$$s $(OUT)/full-$$s.csv $(OUT)/red-$$s.csv $(OUT)/diff-$$s.txt $(OUT)/cub-$$s.h5 $(OUT)/model.h5"; done ) $(ATOMIC)

$(OUT)/table.md: $(OUT)/rows.txt
	$(TOP)/pipelines/table.sh "shapes: one basis trained on $(words $(TRAIN)) shapes ($(TRAIN)), reduced runs on them and on $(words $(TEST)) unseen ($(TEST)) (LiCROM Fig. 5, 7)" $< $(ATOMIC)
