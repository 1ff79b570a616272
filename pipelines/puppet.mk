# puppet.mk — Neural Modes' puppet (Wang et al. 2024, §5; issue 19 item 4):
# a body with a head, two arms and two legs (pipelines/puppet.geo, meshed
# by gmsh through crom-mesh import), floating free (no gravity, nothing
# held), is worked by six rods whose rest lengths follow sinusoids
# (--rod): a front and a back rod from the torso to each hand and to the
# head, each pair in anti-phase, so that the arms swing forward and back by
# about 40 degrees and the head nods, and the torso turns and shifts against
# them. Each subspace is the paper's: R shape coordinates (made with the
# torso held) plus 6 rigid degrees of freedom (crom-reducedstep
# --rigid-frame: x = R(θ) x_model(q) + t). The same run in
#   - linear modes (crom-modes, R of them), and R + 10 of them (the paper:
#     "only partly mitigated when adding ten extra basis vectors"),
#   - modes with modal derivatives (a neuralmodes map of the R modes with
#     --derivatives and no training: x = X + W q + ½ Σ Ψ_ij q_i q_j),
#   - neural modes over the R modes (Wang et al.; seeded with the
#     derivatives, trained TMINUTES on a box of BOX m and along the
#     modal-derivative run's coordinates, --latents), over every tet and
#     over an optimized cubature of CUBCOUNT tets,
# against crom-fullsim. Output: OUT/table.md (error over the run, arm
# length change, the torso's motion, ms per step) and OUT/strip-*.png (each
# subspace above the full run).
#
#   make -f pipelines/puppet.mk -j2
#   make -f pipelines/puppet.mk SIZE=0.04 STEPS=60 TMINUTES=0.2   # a quick look
include $(dir $(lastword $(MAKEFILE_LIST)))common.mk

OUT ?= runs/puppet
SIZE ?= 0.022
R ?= 5
STEPS ?= 200
TMINUTES ?= 1
BOX ?= 0.06
# the torso: held while the shape subspaces are made, free in every run
TORSO = box:-0.15,-0.2,-0.1,0.15,0.22,0.1
MAT = --youngs 1e5 --poisson 0.45 --density 1000
PI = 3.14159265358979
# the rods: torso front or back at the shoulder / neck to the hand / head
# (A/B=K,L0,AMP,PERIOD,PHASE: L0 'rest', the ends' rest distance)
RODS = --rod 'box:0.08,0.1,0.09,0.15,0.2,0.1/x>0.55&y>0.09=40,rest,0.12,3,0' \
       --rod 'box:0.08,0.1,-0.1,0.15,0.2,-0.09/x>0.55&y>0.09=40,rest,0.12,3,$(PI)' \
       --rod 'box:-0.15,0.1,0.09,-0.08,0.2,0.1/x<-0.55&y>0.09=40,rest,0.12,3,1.5707963267949' \
       --rod 'box:-0.15,0.1,-0.1,-0.08,0.2,-0.09/x<-0.55&y>0.09=40,rest,0.12,3,4.71238898038469' \
       --rod 'box:-0.05,0.15,0.09,0.05,0.24,0.1/box:-0.04,0.4,0.08,0.04,0.48,0.12=80,rest,0.05,2,0' \
       --rod 'box:-0.05,0.15,-0.1,0.05,0.24,-0.09/box:-0.04,0.4,-0.12,0.04,0.48,-0.08=80,rest,0.05,2,$(PI)'
SCENARIO = $(MAT) --gravity 0,0,0 --dt 0.02 --steps $(STEPS) --damping 3 $(RODS)
NM = --objective neuralmodes --mesh $(OUT)/mesh.h5 --modes $(OUT)/modes.h5 --derivatives --tangent-anchor $(MAT) \
     --pin '$(TORSO)' --gravity 0,0,0 --seed $(SEED) --threads 1
ROWS ?= modes modes10 mderiv neuralmodes nmcub
CUBCOUNT ?= 200

.PHONY: all
all: $(OUT)/table.md $(foreach r,modes mderiv neuralmodes,$(OUT)/strip-$(r).png)
	@cat $<

$(OUT)/mesh.h5: $(TOP)/pipelines/puppet.geo
	@mkdir -p $(@D)
	crom-mesh import $< --size $(SIZE) --region torso='$(TORSO)' $(QUIET) -o $@
$(OUT)/full.h5: $(OUT)/mesh.h5
	crom-fullsim $(SCENARIO) --threads 1 $(QUIET) --stats $(OUT)/full.csv -o $@ $<
$(OUT)/modes.h5: $(OUT)/mesh.h5
	crom-modes $(MAT) --pin '$(TORSO)' --count $(R) --threads 1 $(QUIET) -o $@ $<
$(OUT)/modes10.h5: $(OUT)/mesh.h5
	crom-modes $(MAT) --pin '$(TORSO)' --count $$(( $(R) + 10 )) --threads 1 $(QUIET) -o $@ $<
$(OUT)/mderiv.h5: $(OUT)/modes.h5
	crom-fitfield $(NM) --steps 0 $(QUIET) -o $@
$(OUT)/neuralmodes.h5: $(OUT)/modes.h5 $(OUT)/red-mderiv.h5
	crom-fitfield $(NM) --box $(BOX) --latents $(OUT)/red-mderiv.h5 --steps 1000000 --minutes $(TMINUTES) $(QUIET) -o $@
$(OUT)/red-%.h5: $(OUT)/%.h5 $(OUT)/mesh.h5
	crom-reducedstep --model $< --rigid-frame $(SCENARIO) --threads 1 $(QUIET) --stats $(OUT)/red-$*.csv -o $@
# neural modes over an optimized cubature of CUBCOUNT tets (crom-cubature
# --model: NNLS on the latent forces at samples of the map's box)
$(OUT)/cub-neuralmodes.h5: $(OUT)/neuralmodes.h5
	crom-cubature --model $< --scheme optimized --count $(CUBCOUNT) --seed $(SEED) $(QUIET) -o $@
$(OUT)/red-nmcub.h5: $(OUT)/cub-neuralmodes.h5 $(OUT)/neuralmodes.h5
	crom-reducedstep --model $(OUT)/neuralmodes.h5 --cubature $< --rigid-frame $(SCENARIO) --threads 1 $(QUIET) \
	  --stats $(OUT)/red-nmcub.csv -o $@
$(OUT)/nmcub.h5: $(OUT)/neuralmodes.h5
	ln -sf neuralmodes.h5 $@
$(OUT)/diff-%.txt: $(OUT)/red-%.h5 $(OUT)/full.h5 $(OUT)/%.h5
	crom-diff $< $(OUT)/full.h5 --model $(OUT)/$*.h5 $(ATOMIC)
# four decoded frames of each run (a quarter of the run apart), for the
# table's limb lengths; open them in ParaView too
QUARTERS = $(foreach i,1 2 3 4,$(shell echo $$(( $(STEPS) * $(i) / 4 ))))
$(OUT)/frames-%/done: $(OUT)/red-%.h5 $(OUT)/%.h5 $(OUT)/mesh.h5
	@mkdir -p $(@D)
	for k in $(QUARTERS); do \
	  crom-export --format vtu --model $(OUT)/$*.h5 --mesh $(OUT)/mesh.h5 --frame $$k $(QUIET) -o $(@D)/f$$k.vtu $<; \
	done
	touch $@
$(OUT)/strip-%.png: $(OUT)/red-%.h5 $(OUT)/full.h5 $(OUT)/%.h5
	crom-export --format strip --columns 6 --panel 300x300 --model $(OUT)/$*.h5 --mesh $(OUT)/mesh.h5 \
	  --compare $(OUT)/full.h5 $(QUIET) -o $@ $<
$(OUT)/table.md: $(foreach r,$(ROWS),$(OUT)/diff-$(r).txt $(OUT)/frames-$(r)/done) $(OUT)/full.h5
	/usr/bin/python3 $(TOP)/pipelines/benchtab.py puppet $(OUT) "$(ROWS)" "$(QUARTERS)" $(ATOMIC)
