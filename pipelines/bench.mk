# make bench — crom's versions of LiCROM's Tables 1 and 2 and the speed
# figures the issues ask for, as markdown and CSV under bench/results/ with
# PNG plots. Medians over steps, one core. Run through the top-level Makefile
# (`make bench`); sizes are variables, e.g.
#   make bench T_SIZES="0.056" FULL_SIZES="0.056" SCALE_SIZES="0.1 0.056"   # a quick one
#   make -f pipelines/bench.mk datafree DF_SIZE=0.1 DF_MINUTES=0.1 DF_STEPS=10 OUT=/tmp/df
# About 55 minutes at the defaults on this 2-core machine (scale: about 5, datafree: about 20,
# and about 12 more for the soft bar: its skinning and continuous-field rows).
include $(dir $(lastword $(MAKEFILE_LIST)))common.mk
.SECONDEXPANSION:

OUT ?= bench/results
QUIET ?= -q

# --- full-space simulator (issue 3): compression of a unit cube at about 5K,
#     20K and 80K vertices
FULL_SIZES ?= 0.056 0.0355 0.0207
FULL_STEPS ?= 10
FULL_SCENARIO = --velocity 'top=0,-2,0@0:0.1' --pin bottom --gravity 0,0,0 --dt 0.01

# --- Tables 1 and 2 (issues 4-5): two loadings of a unit cube, compressed from
#     the top and sheared at the top, at about 5K and 20K vertices; r = 20
T_SIZES ?= 0.056 0.0355
T_STEPS ?= 40
T_MINUTES ?= 3
T_COUNT ?= 200
LOAD_compress = --velocity 'top=0,-2,0@0:0.1' --pin bottom --gravity 0,-9.81,0 --dt 0.01 --steps $(T_STEPS)
LOAD_shear    = --velocity 'top=1.5,0,0@0:0.1' --pin bottom --gravity 0,-9.81,0 --dt 0.01 --steps $(T_STEPS)
LOADS = compress shear

# --- training (issue 4): the five cube-to-sphere shapes at a few thousand
#     vertices each, compressed; lsq until 2% (budget TRAIN_MINUTES) and
#     pointnet with the same budget
TRAIN_SIZE ?= 0.06
TRAIN_MINUTES ?= 10
TRAIN_SHAPES = 2 2.5 3.5 6 box

# --- data-free subspaces (issue 7): training time and per-step latent time of
#     each objective on a clamped bar of about 5K vertices sagging under
#     gravity, one core: linear modes (crom-modes, stepped through a cubature of
#     every tet and an optimized one), the energy map (Sharp et al.) and neural
#     modes on the same modes (Wang et al.), both stepped with --model; the
#     material and loading of tests/prog/datafree.sh, r = DF_RANK for all
DF_SIZE ?= 0.02
DF_RANK ?= 10
DF_MINUTES ?= 5
DF_TRAIN_STEPS ?= 1000000
DF_STEPS ?= 100
DF_COUNT ?= $(T_COUNT)
DF_SAMPLES ?= 256
DF_YOUNGS ?= 1e6
DF_MAT = --youngs $(DF_YOUNGS) --poisson 0.3 --density 1000
DF_BC = --pin clamp --gravity 0,-9.81,0
DF_SCENARIO = $(DF_MAT) $(DF_BC) --dt 0.01 --steps $(DF_STEPS) --max-iter 200
# the static sag: the same load, heavily damped until it rests (the last
# frame of each run against the last frame of the damped full run)
DF_STATIC = $(DF_MAT) $(DF_BC) --dt 0.02 --steps 100 --damping 30 --max-iter 200
DF_TRAIN = --rank $(DF_RANK) --steps $(DF_TRAIN_STEPS) --minutes $(DF_MINUTES) --seed $(SEED) --threads 1
# table rows: modes-all and modes-opt step the modes through a cubature
# (df-cub-all.h5, df-cub-opt.h5); energy and neuralmodes their map (--model)
# over every tet, energy-opt and neuralmodes-opt over an optimized cubature
# of the map's features (df-cubm-KIND.h5, fitted at latent samples: no data);
# field is the continuous map (crom-fitfield --objective field), laid on the
# mesh with --mesh like a LiCROM field
DF_ROWS = modes-all modes-opt energy energy-opt neuralmodes neuralmodes-opt field field-opt
df_kind = $(firstword $(subst -, ,$(1)))
df_model = $(OUT)/df-$(call df_kind,$(1)).h5
df_cub = $(if $(filter modes-%,$(1)),$(OUT)/df-cub-$(patsubst modes-%,%,$(1)).h5,$(if $(filter %-opt,$(1)),$(OUT)/df-cubm-$(call df_kind,$(1)).h5))
df_in = $(if $(filter modes-%,$(1)),,$(call df_model,$(1))) $(call df_cub,$(1))
df_mesh = $(if $(filter field%,$(1)),--mesh $(OUT)/df-mesh.h5)
df_args = $(if $(filter modes-%,$(1)),,--model $(call df_model,$(1)) $(call df_mesh,$(1))) $(if $(call df_cub,$(1)),--cubature $(call df_cub,$(1)))

# --- the soft bar of issue 14 (the same mesh): nu = 0.45 and E = DF2_YOUNGS,
#     so that the free end sags more than half the length under gravity (58%
#     at 4e5 Pa, measured), dt = 0.05, 100 steps. Rows KIND-SCHEME: the
#     skinning subspaces of DF2_HANDLES handles with eigen or trained weights
#     (the training stopped by the clock at DF2_MINUTES), over an optimized
#     cubature of at most DF2_COUNT tets fitted, with no data, to the poses of
#     the dynamic and the static run over a METIS cubature of DF2_POSE_PARTS
#     parts (opt), or over a METIS cubature of DF2_METIS parts (metis)
DF2_YOUNGS ?= 4e5
DF2_HANDLES ?= 20
DF2_MINUTES ?= 2
DF2_COUNT ?= 200
DF2_METIS ?= 300
DF2_POSE_PARTS ?= 1000
DF2_MAT = --youngs $(DF2_YOUNGS) --poisson 0.45 --density 1000
DF2_SCENARIO = $(DF2_MAT) $(DF_BC) --dt 0.05 --steps 100
DF2_STATIC = $(DF2_SCENARIO) --damping 10
DF2_ROWS = eigen-opt eigen-metis trained-opt trained-metis mderiv-opt mderiv-metis
df2_kind = $(firstword $(subst -, ,$(1)))
# the continuous fields on the soft bar, latent dim DF_RANK, stepped with
# --model over every tet (all) or an optimized cubature of their features
# fitted at latent samples (opt): sfield, the field over the skinning
# eigenmodes of DF2_HANDLES handles (crom-fitfield --objective field
# --handles, trained DF2_MINUTES), and field, the field with a trained
# feature field W(X) (DF_MINUTES)
# and, over every tet for the trade-off table on this bar, the data-free
# maps of one mesh (energy: Sharp et al.; neuralmodes: Wang et al. on the
# modes, both DF_MINUTES) and the linear modes (modes) stepped the same way;
# nmseed, neural modes seeded with the modal derivatives of their modes and
# not trained (the quadratic manifold), and nmrun, the same seed tangent-
# anchored and trained DF_MINUTES with every other sample near the modal
# coordinates the seed's static run visited (crom-fitfield --latents)
DF2_MAPS = sfield-all sfield-opt sfref-all sfref-opt field-all field-opt energy-all emref-all neuralmodes-all nmseed-all nmrun-all \
  modes-all mderiv-all
# sfref: a skin-field trained DF2_REFINE_MINUTES (sfbase), then refined
# DF2_REFINE_STEPS steps along its own static run (crom-fitfield
# --init-model --latents; no full simulation): 1 min + 9 s + 40 s, within
# issue 14's 2 minutes
DF2_REFINE_MINUTES ?= 1
DF2_REFINE_STEPS ?= 5000
# emref: the energy map trained DF2_EM_BASE_STEPS steps (embase), then
# refined DF2_EM_REFINE_STEPS steps along its own static run: 4.6 min in all
# on one core (the energy row's budget is 5)
DF2_EM_BASE_STEPS ?= 10000
DF2_EM_REFINE_STEPS ?= 3000
# mderiv: DF2_DMODES linear modes and their modal derivatives (crom-modes --derivatives;
# 5: modes 4 and 5 are a pair of equal frequency, both or neither)
DF2_DMODES ?= 5
df2_map_args = --model $(OUT)/df2-map-$(call df2_kind,$(1)).h5 --mesh $(OUT)/df-mesh.h5 --max-iter 200 \
  $(if $(filter %-opt,$(1)),--cubature $(OUT)/df2-mcub-$(call df2_kind,$(1)).h5)
df2_map_in = $(OUT)/df2-map-$(call df2_kind,$(1)).h5 $(if $(filter %-opt,$(1)),$(OUT)/df2-mcub-$(call df2_kind,$(1)).h5)

.PHONY: all fullsim sheets scenes tables training datafree plots micro scale mpi live view
all: fullsim sheets scenes tables training datafree plots micro scale mpi live view
	@cat $(OUT)/fullsim.md $(OUT)/sheets.md $(OUT)/scenes.md $(OUT)/tables.md $(OUT)/training.md $(OUT)/datafree.md \
	  $(OUT)/datafree2.md $(OUT)/micro.md $(OUT)/scale.md $(OUT)/mpi.md $(OUT)/live.md $(OUT)/view.md
	@echo "plots: $(OUT)/steps.png $(OUT)/training.png"

# ---------------------------------------------------------------- fullsim
fullsim: $(OUT)/fullsim.md
$(OUT)/mesh-%.h5:
	@mkdir -p $(@D)
	crom-mesh box --size $* --algorithm hxt --region top='y>0.499' --region bottom='y<-0.499' -o $@
$(OUT)/fullsim-%.csv: $(OUT)/mesh-%.h5
	crom-fullsim $(FULL_SCENARIO) --steps $(FULL_STEPS) --stats $@ $(QUIET) -o /dev/null $<
$(OUT)/fullsim.md: $(foreach s,$(FULL_SIZES),$(OUT)/fullsim-$(s).csv)
	( echo "### crom-fullsim: compression of a unit cube (issue 3)"; echo; \
	  $(TOP)/tests/benchtab.sh fullsim $(OUT) $(FULL_SIZES) ) > $@.tmp && mv $@.tmp $@

# ----------------------------------------------------------------- sheets
# crom-fullsim on a thin shell (issue 16): a 1 x 1 m sheet (crom-mesh sheet,
# edge SHEET_SIZES, 2 mm thick) hanging from its top edge, swinging out of
# plane under a slanted gravity, one core
SHEET_SIZES ?= 0.0212 0.0106
SHEET_STEPS ?= 20
SHEET_SCENARIO = --pin top --youngs 1e6 --poisson 0.3 --density 500 --gravity 0,-9.81,3 --dt 0.02 --threads 1
sheets: $(OUT)/sheets.md
$(OUT)/sheet-%.h5:
	@mkdir -p $(@D)
	crom-mesh sheet --dims 1,1,1 --size $* --thickness 0.002 --region top='y>0.499' -o $@
$(OUT)/sheetsim-%.csv: $(OUT)/sheet-%.h5
	crom-fullsim $(SHEET_SCENARIO) --steps $(SHEET_STEPS) --stats $@ $(QUIET) -o /dev/null $<
$(OUT)/sheets.md: $(foreach s,$(SHEET_SIZES),$(OUT)/sheetsim-$(s).csv)
	( echo "### crom-fullsim on a thin shell: a hanging sheet swinging out of plane (issue 16)"; echo; \
	  $(TOP)/tests/benchtab.sh sheets $(OUT) $(SHEET_SIZES) ) > $@.tmp && mv $@.tmp $@

# ----------------------------------------------------------------- scenes
# crom-fullsim on rigid-body scenes (issue 17, crom-scene): SCENE_STEPS steps
# of each under gravity at dt 2 ms, one core; the ring chains are held by
# contacts alone, the Stewart platform is pushed sideways with no gravity
SCENES ?= pendulum capsules rings minichain klann stewart
SCENE_STEPS ?= 200
scene_args_pendulum = pendulum --angle 80
scene_args_capsules = chain --link capsule --links 24
scene_args_rings = chain --links 24
scene_args_minichain = chain --links 2
scene_args_klann = klann
scene_args_stewart = stewart
scene_run_stewart = --gravity 0,0,0 --force platform=20,0,0
scenes: $(OUT)/scenes.md
$(OUT)/scene-%.h5:
	@mkdir -p $(@D)
	crom-scene $(scene_args_$*) -o $@
$(OUT)/scenesim-%.csv: $(OUT)/scene-%.h5
	crom-fullsim --dt 0.002 --steps $(SCENE_STEPS) --max-iter 200 --threads 1 $(scene_run_$*) --stats $@ $(QUIET) \
	  -o /dev/null $<
$(OUT)/scenes.md: $(foreach s,$(SCENES),$(OUT)/scenesim-$(s).csv)
	( echo "### crom-fullsim on rigid-body scenes (issue 17), dt 2 ms, $(SCENE_STEPS) steps, one core"; echo; \
	  echo "| scene | bodies (DOF) | joints, collision pairs | step, median (ms) | Newton per step, mean (max) |"; \
	  echo "|---|---:|---:|---:|---:|"; \
	  for s in $(SCENES); do \
	    crom-info $(OUT)/scene-$$s.h5 > $(OUT)/scene-$$s.txt; \
	    b=$$(sed -n 's/.*a rigid-body scene: \([0-9]*\) bodies.*; \([0-9]*\) DOF.*/\1 (\2)/p' $(OUT)/scene-$$s.txt); \
	    j=$$(sed -n 's/^ *\([0-9]*\) joints.*, \([0-9]*\) collision pairs.*/\1, \2/p' $(OUT)/scene-$$s.txt); \
	    med=$$(awk -F, 'NR > 1 {print $$6}' $(OUT)/scenesim-$$s.csv | sort -g | \
	      awk '{a[NR] = $$1} END {printf "%.3g", (NR % 2 ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2) * 1e3}'); \
	    awk -F, -v s="$$s" -v b="$$b" -v j="$$j" -v med="$$med" 'NR > 1 {n += $$2; if ($$2 > m) m = $$2; c++} \
	      END {printf "| %s | %s | %s | %s | %.2f (%d) |\n", s, b, j, med, n / c, m}' $(OUT)/scenesim-$$s.csv; \
	  done ) > $@.tmp && mv $@.tmp $@

# ----------------------------------------------------------------- tables
tables: $(OUT)/tables.md
$(OUT)/t-mesh-%.h5:
	@mkdir -p $(@D)
	crom-mesh box --size $* --algorithm hxt --region top='y>0.45' --region bottom='y<-0.45' -o $@
# full runs: the training data and the reference (data generation is timed)
$(OUT)/t-full-%.h5 $(OUT)/t-full-%.csv &: $(OUT)/t-mesh-$$(word 1,$$(subst -, ,$$*)).h5
	crom-fullsim $(LOAD_$(word 2,$(subst -, ,$*))) --stats $(OUT)/t-full-$*.csv $(QUIET) -o $(OUT)/t-full-$*.h5 $<
$(OUT)/t-samples-%.h5: $$(foreach l,$(LOADS),$(OUT)/t-full-$$*-$$(l).h5)
	crom-sample --points 2048 --seed $(SEED) -o $@ $^
$(OUT)/t-model-%.h5: $(OUT)/t-samples-%.h5
	crom-fitfield --rank 20 --minutes $(T_MINUTES) --epochs 100000 --seed $(SEED) -o $@ < $<
$(OUT)/t-poses-%.h5: $(OUT)/t-full-%.h5 $$(OUT)/t-model-$$(word 1,$$(subst -, ,$$*)).h5
	crom-encode --model $(OUT)/t-model-$(word 1,$(subst -, ,$*)).h5 $(QUIET) -o $@ < $<
$(OUT)/t-cub-%.h5: $(OUT)/t-model-%.h5 $(OUT)/t-mesh-%.h5 $$(foreach l,$(LOADS),$(OUT)/t-poses-$$*-$$(l).h5)
	crom-cubature --model $< --scheme optimized --count $(T_COUNT) $(foreach l,$(LOADS),--poses $(OUT)/t-poses-$*-$(l).h5) \
	  $(QUIET) -o $@ $(OUT)/t-mesh-$*.h5
$(OUT)/t-red-%.h5 $(OUT)/t-red-%.csv &: $$(OUT)/t-cub-$$(word 1,$$(subst -, ,$$*)).h5
	crom-reducedstep --cubature $< $(LOAD_$(word 2,$(subst -, ,$*))) --stats $(OUT)/t-red-$*.csv $(QUIET) -o $(OUT)/t-red-$*.h5
$(OUT)/t-diff-%.txt: $(OUT)/t-red-%.h5 $(OUT)/t-full-%.h5
	crom-diff $< $(OUT)/t-full-$*.h5 --model $(OUT)/t-model-$(word 1,$(subst -, ,$*)).h5 $(ATOMIC)
RUNS = $(foreach s,$(T_SIZES),$(foreach l,$(LOADS),$(s)-$(l)))
$(OUT)/tables.md: $(foreach r,$(RUNS),$(OUT)/t-diff-$(r).txt $(OUT)/t-red-$(r).csv)
	/usr/bin/python3 $(TOP)/pipelines/benchtab.py tables $(OUT) "$(T_SIZES)" "$(LOADS)" > $@.tmp && mv $@.tmp $@

# ------------------------------------------------------------------ scale
# the reduced step against the mesh size (issue 18 item 2): the first
# tables model (trained at T_SIZES' first size) laid on unit cubes of about
# 5K and 100K vertices, a METIS cubature of the same SCALE_COUNT tets on
# each, the compression load; the full step (SCALE_FULL_STEPS steps) with its
# peak memory (ru_maxrss of the process)
SCALE_SIZES ?= 0.056 0.0195
SCALE_COUNT ?= 200
SCALE_FULL_STEPS ?= 3
SCALE_MODEL = $(OUT)/t-model-$(word 1,$(T_SIZES)).h5
scale: $(OUT)/scale.md
$(OUT)/sc-mesh-%.h5:
	@mkdir -p $(@D)
	crom-mesh box --size $* --algorithm hxt --region top='y>0.45' --region bottom='y<-0.45' $(QUIET) -o $@
$(OUT)/sc-full-%.csv $(OUT)/sc-rss-%.txt &: $(OUT)/sc-mesh-%.h5
	/usr/bin/python3 -c 'import resource, subprocess, sys; rc = subprocess.call(sys.argv[2:]); \
	  open(sys.argv[1], "w").write("%d\n" % resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); sys.exit(rc)' \
	  $(OUT)/sc-rss-$*.txt crom-fullsim $(LOAD_compress) --steps $(SCALE_FULL_STEPS) --threads 1 \
	  --stats $(OUT)/sc-full-$*.csv $(QUIET) -o /dev/null $<
$(OUT)/sc-cub-%.h5: $(OUT)/sc-mesh-%.h5 $(SCALE_MODEL)
	crom-cubature --model $(SCALE_MODEL) --scheme metis --count $(SCALE_COUNT) $(QUIET) -o $@ $<
$(OUT)/sc-red-%.csv: $(OUT)/sc-cub-%.h5
	crom-reducedstep --cubature $< $(LOAD_compress) --threads 1 --stats $@ $(QUIET) -o /dev/null
$(OUT)/scale.md: $(foreach s,$(SCALE_SIZES),$(OUT)/sc-full-$(s).csv $(OUT)/sc-red-$(s).csv)
	( echo "### the reduced step against the mesh size (issue 18): one model, $(SCALE_COUNT) METIS cubature tets"; \
	  echo; /usr/bin/python3 $(TOP)/pipelines/benchtab.py scale $(OUT) "$(SCALE_SIZES)" ) > $@.tmp && mv $@.tmp $@

# --------------------------------------------------------------- training
training: $(OUT)/training.md
$(OUT)/tr-mesh-box.h5:
	@mkdir -p $(@D)
	crom-mesh box --size $(TRAIN_SIZE) --region top='y>0.45' --region bottom='y<-0.45' -o $@
$(OUT)/tr-mesh-%.h5:
	@mkdir -p $(@D)
	crom-mesh superquadric --exponent $* --size $(TRAIN_SIZE) --region top='y>0.45' --region bottom='y<-0.45' -o $@
$(OUT)/tr-full-%.h5: $(OUT)/tr-mesh-%.h5
	crom-fullsim --velocity 'top=0,-2,0@0:0.1' --pin bottom --gravity 0,0,0 --dt 0.01 --steps 40 $(QUIET) -o $@ $<
$(OUT)/tr-samples.h5: $(foreach s,$(TRAIN_SHAPES),$(OUT)/tr-full-$(s).h5)
	crom-sample --points 2048 --seed $(SEED) -o $@ $^
$(OUT)/tr-lsq.h5 $(OUT)/tr-lsq.log &: $(OUT)/tr-samples.h5
	crom-fitfield --rank 20 --encoder lsq --minutes $(TRAIN_MINUTES) --epochs 4000 --seed $(SEED) -v \
	  -o $(OUT)/tr-lsq.h5 < $< 2> $(OUT)/tr-lsq.log
$(OUT)/tr-pointnet.h5 $(OUT)/tr-pointnet.log &: $(OUT)/tr-samples.h5
	crom-fitfield --rank 20 --encoder pointnet --minutes $(TRAIN_MINUTES) --seed $(SEED) -v \
	  -o $(OUT)/tr-pointnet.h5 < $< 2> $(OUT)/tr-pointnet.log
$(OUT)/training.md: $(OUT)/tr-lsq.h5 $(OUT)/tr-pointnet.h5
	/usr/bin/python3 $(TOP)/pipelines/benchtab.py training $(OUT) > $@.tmp && mv $@.tmp $@

# ------------------------------------------------------------------- live
# crom-live (issue 21): the tables' model and optimized cubature at each
# T_SIZES size, the body pinned at the bottom with its top dragged around a
# circle of 5 cm (one turn a second, the point moved every step): steps per
# second (--no-clock, LIVE_STEPS steps, median step), and paced at 60
# steps/s, the point moved every 20 ms for 3 s: the time from a command to
# the frame that shows it (median, largest) and the steps that ended after
# their simulated time
LIVE_STEPS ?= 2000
live: $(OUT)/live.md
$(OUT)/live-%.txt: $(OUT)/t-cub-%.h5
	awk 'BEGIN {for (i = 0; i < $(LIVE_STEPS); i++) printf "drag top %.6f,%.6f,0 1e6\nstep 1\n", \
	  0.05 * sin(0.0628319 * i), 0.5 + 0.05 * cos(0.0628319 * i)}' | \
	  crom-live --cubature $< --pin bottom --no-clock --threads 1 -o /dev/null 2> $@.tmp
	( for i in $$(seq 150); do awk -v i=$$i 'BEGIN {printf "drag top %.6f,%.6f,0 1e6\n", 0.05 * sin(0.1257 * i), \
	    0.5 + 0.05 * cos(0.1257 * i)}'; sleep 0.02; done; echo quit ) | \
	  crom-live --cubature $< --pin bottom --dt 0.0166667 --threads 1 -o /dev/null 2>> $@.tmp
	mv $@.tmp $@
$(OUT)/live.md: $(foreach s,$(T_SIZES),$(OUT)/live-$(s).txt)
	( echo "crom-live: the tables' models (r = 20, optimized cubature), the top dragged, one core"; echo; \
	  echo "| vertices | cubature tets | step with the drag moving (ms) | steps/s | command to frame at 60 steps/s, median (ms) | largest (ms) | late steps |"; \
	  echo "|---:|---:|---:|---:|---:|---:|---:|"; \
	  for s in $(T_SIZES); do \
	    nv=$$(crom-info $(OUT)/t-mesh-$$s.h5 | awk '/ vertices, / {print $$1; exit}'); \
	    k=$$(crom-info $(OUT)/t-cub-$$s.h5 | awk '$$1 == "count" {print $$2; exit}'); \
	    awk -v nv="$$nv" -v k="$$k" '/a step/ && !a {split($$0, x, "a step "); split(x[2], y, " "); ms = y[1]; \
	        split($$0, z, "; "); split(z[3], w, " "); sps = w[1]; a = 1; next} \
	      /a step/ {split($$0, x, "crom-live: "); split(x[2], y, " "); total = y[1]} \
	      /command to the frame/ {split($$0, x, "shows it: "); split(x[2], y, " "); med = y[1]; \
	        split($$0, z, "at most "); split(z[2], w, " "); mx = w[1]} \
	      /steps ended after/ {split($$0, x, ": "); split(x[2], y, " "); late = y[1]} \
	      END {printf "| %s | %s | %s | %s | %s | %s | %s of %s |\n", nv, k, ms, sps, med, mx, late ? late : 0, total}' \
	      $(OUT)/live-$$s.txt; \
	  done ) > $@.tmp && mv $@.tmp $@

# crom-view (issue 21 items 2, 3): the tables' 19K-vertex body above and the
# 100K-vertex one of `scale` (the same model on SCALE_SIZES' last size, a
# METIS cubature), crom-live paced at 60 steps/s into crom-view, and a page
# in headless Chromium (tests/prog/view_client.py load: ChromeDriver, a
# software GL) whose mouse drags the top round a circle for
# LIVE_VIEW_SECONDS, a point a tenth of a second; the page decodes the
# surface from each frame's q and reports frames received and drawn, its
# decode time and the time from sending a command to the frame that first
# shows it (the stream's commands field)
LIVE_VIEW_SECONDS ?= 8
LIVE_VIEW_CUBS ?= t-cub-$(word 1,$(T_SIZES)) sc-cub-$(lastword $(SCALE_SIZES))
view: $(OUT)/view.md
$(OUT)/view-%.txt: $(OUT)/%.h5
	@command -v chromedriver >/dev/null || { echo "bench view: no chromedriver (make deps installs it)" >&2; exit 1; }
	d=$$(mktemp -d /tmp/crom-bench-view.XXXXXX); mkfifo $$d/f $$d/c; \
	crom-live --cubature $< --pin bottom --gravity 0,0,0 --dt 0.0166667 --drag-stiffness 1e7 --threads 1 \
	  --commands $$d/c > $$d/f 2> $$d/live.err & l=$$!; \
	crom-view --cubature $< --port 0 < $$d/f > $$d/c 2> $$d/view.err & v=$$!; \
	for i in $$(seq 300); do grep -q 'open http' $$d/view.err && break; sleep 0.1; done; \
	port=$$(grep -o '127\.0\.0\.1:[0-9]*' $$d/view.err | head -1 | cut -d: -f2); \
	rc=0; /usr/bin/python3 $(TOP)/tests/prog/view_client.py load $$port $(LIVE_VIEW_SECONDS) > $$d/page.txt || rc=$$?; \
	kill -INT $$v; wait $$v || rc=1; wait $$l || rc=1; \
	cat $$d/live.err $$d/view.err $$d/page.txt > $@.tmp; rm -rf $$d; [ $$rc -eq 0 ] && mv $@.tmp $@
$(OUT)/view.md: $(foreach c,$(LIVE_VIEW_CUBS),$(OUT)/view-$(c).txt)
	( echo "crom-live at 60 steps/s into crom-view, a page in headless Chromium dragging the top ($(LIVE_VIEW_SECONDS) s)"; echo; \
	  echo "| vertices | surface vertices | steps | late steps | frames to the page /s | drawn /s | decode on the page, mean (ms) | command to frame at the page, median (ms) | in crom-live (ms) |"; \
	  echo "|---:|---:|---:|---:|---:|---:|---:|---:|---:|"; \
	  for c in $(LIVE_VIEW_CUBS); do \
	    nv=$$(crom-info $(OUT)/$$c.h5 | awk '/ vertices, / {print $$1; exit}'); \
	    awk -v nv="$$nv" '/surface vertices\)/ {split($$0, x, "r = "); split(x[2], y, " "); ns = y[2]} \
	      /crom-live: [0-9]+ steps,/ {split($$0, x, "crom-live: "); split(x[2], y, " "); steps = y[1]} \
	      /steps ended after/ {split($$0, x, "crom-live: "); split(x[2], y, " "); late = y[1]} \
	      /crom-live: from a command/ {split($$0, x, "shows it: "); split(x[2], y, " "); lat = y[1]} \
	      /^page: / {split($$0, x, " "); fr = x[2]; dr = x[5]; split($$0, z, "decode "); split(z[2], w, " "); dec = w[1]; \
	        split($$0, z, "command to frame "); split(z[2], w, " "); plat = w[1]} \
	      END {printf "| %s | %s | %s | %s | %s | %s | %s | %s | %s |\n", nv, ns, steps, late ? late : 0, \
	        fr, dr, dec, plat, lat}' $(OUT)/view-$$c.txt; \
	  done ) > $@.tmp && mv $@.tmp $@

# -------------------------------------------------------------------- mpi
# data-parallel training (issue 20): the training set above, lsq, MPI_EPOCHS
# epochs with --shards 2, one process against mpirun -n 2 (one core each),
# MPI_REPEATS runs each; the training loop's own clock (crom-fitfield -v:
# "N steps in S s"), medians, and the doubles allreduced per step
MPI_EPOCHS ?= 300
MPI_REPEATS ?= 3
MPIRUN ?= mpirun --allow-run-as-root --oversubscribe --mca btl self,vader --mca btl_vader_single_copy_mechanism none -n 2
mpi: $(OUT)/mpi.md
$(OUT)/mpi.md: $(OUT)/tr-samples.h5
	@command -v mpirun >/dev/null || { echo "bench mpi: no mpirun (make deps installs Open MPI)" >&2; exit 1; }
	@crom-fitfield --help | grep -c 'built with MPI' >/dev/null || { echo "bench mpi: crom-fitfield was built without MPI" >&2; exit 1; }
	A="--rank 20 --encoder lsq --epochs $(MPI_EPOCHS) --shards 2 --threads 1 --seed $(SEED) -v"; \
	for k in $$(seq $(MPI_REPEATS)); do \
	  crom-fitfield $$A -o $(OUT)/mpi-1.h5 $< 2> $(OUT)/mpi-1-$$k.log; \
	  $(MPIRUN) crom-fitfield $$A -o $(OUT)/mpi-2.h5 $< 2> $(OUT)/mpi-2-$$k.log; \
	done; \
	/usr/bin/python3 $(TOP)/pipelines/benchtab.py mpi $(OUT) $(MPI_REPEATS) > $@.tmp && mv $@.tmp $@

# --------------------------------------------------------------- datafree
datafree: $(OUT)/datafree.md $(OUT)/datafree2.md
$(eval $(call stamp_rule,df-mesh,$(DF_SIZE)))
$(eval $(call stamp_rule,df-scenario,$(DF_SCENARIO)))
$(eval $(call stamp_rule,df-static,$(DF_STATIC)))
$(eval $(call stamp_rule,df-modes,$(DF_MAT) $(DF_RANK)))
$(eval $(call stamp_rule,df-train,$(DF_MAT) $(DF_BC) $(DF_TRAIN)))
$(eval $(call stamp_rule,df-cubature,$(DF_COUNT) $(DF_YOUNGS) $(SEED)))
$(eval $(call stamp_rule,df-metrics,$(DF_SAMPLES) $(SEED)))
$(OUT)/df-mesh.h5: $(call stamp,df-mesh)
	@mkdir -p $(@D)
	crom-mesh box --dims 1,0.2,0.2 --size $(DF_SIZE) --algorithm hxt --region clamp='x<-0.49' $(QUIET) -o $@
# the reference, and the step cost the latent steps are measured against
$(OUT)/df-full.h5 $(OUT)/df-full.csv &: $(OUT)/df-mesh.h5 $(call stamp,df-scenario)
	crom-fullsim $(DF_SCENARIO) --threads 1 --stats $(OUT)/df-full.csv $(QUIET) -o $(OUT)/df-full.h5 $<
# training: the modes (their timing is in the -v log), then the data-free
# objectives for DF_MINUTES each (the clock stops them, not DF_TRAIN_STEPS;
# issue 14: at most 5 minutes on one core), at their default settings
$(OUT)/df-modes.h5 $(OUT)/df-modes.log &: $(OUT)/df-mesh.h5 $(call stamp,df-modes)
	crom-modes $(DF_MAT) --pin clamp --count $(DF_RANK) --threads 1 -v -o $(OUT)/df-modes.h5 $< 2> $(OUT)/df-modes.log
$(OUT)/df-energy.h5: $(OUT)/df-mesh.h5 $(call stamp,df-train)
	crom-fitfield --objective energy --mesh $< $(DF_MAT) $(DF_BC) $(DF_TRAIN) $(QUIET) -o $@
$(OUT)/df-neuralmodes.h5: $(OUT)/df-mesh.h5 $(OUT)/df-modes.h5 $(call stamp,df-train)
	crom-fitfield --objective neuralmodes --mesh $< --modes $(OUT)/df-modes.h5 $(DF_TRAIN) $(QUIET) -o $@
$(OUT)/df-field.h5: $(OUT)/df-mesh.h5 $(call stamp,df-train)
	crom-fitfield --objective field --mesh $< $(DF_MAT) $(DF_BC) $(DF_TRAIN) $(QUIET) -o $@
# the modes' cubatures: every tet (what --model integrates too), and an
# optimized one fitted to the poses of that run (no data beyond the modes)
$(OUT)/df-cub-all.h5: $(OUT)/df-modes.h5 $(OUT)/df-mesh.h5
	crom-cubature --model $< --scheme all --threads 1 $(QUIET) -o $@ $(OUT)/df-mesh.h5
$(OUT)/df-cub-opt.h5: $(OUT)/df-modes.h5 $(OUT)/df-mesh.h5 $(OUT)/df-red-modes-all.h5 $(call stamp,df-cubature)
	crom-cubature --model $< --scheme optimized --count $(DF_COUNT) --poses $(OUT)/df-red-modes-all.h5 \
	  --youngs $(DF_YOUNGS) --poisson 0.3 --seed $(SEED) --threads 1 $(QUIET) -o $@ $(OUT)/df-mesh.h5
# the maps' cubatures: their features, fitted at latent samples of the
# training distribution
$(OUT)/df-cubm-%.h5: $(OUT)/df-%.h5 $(OUT)/df-mesh.h5 $(call stamp,df-cubature)
	crom-cubature --model $< --scheme optimized --count $(DF_COUNT) --seed $(SEED) --threads 1 $(QUIET) -o $@ \
	  $(if $(filter field,$*),$(OUT)/df-mesh.h5)
# the latent runs (step costs in the --stats CSV) and their error against the full run
$(OUT)/df-red-%.h5 $(OUT)/df-red-%.csv &: $$(call df_in,$$*) $(call stamp,df-scenario)
	crom-reducedstep $(call df_args,$*) $(DF_SCENARIO) --threads 1 \
	  --stats $(OUT)/df-red-$*.csv $(QUIET) -o $(OUT)/df-red-$*.h5
# the static sag, full and in each subspace
$(OUT)/df-sfull.h5: $(OUT)/df-mesh.h5 $(call stamp,df-static)
	crom-fullsim $(DF_STATIC) --threads 1 $(QUIET) -o $@ $<
$(OUT)/df-sred-%.h5: $$(call df_in,$$*) $(call stamp,df-static)
	crom-reducedstep $(call df_args,$*) $(DF_STATIC) --threads 1 $(QUIET) -o $@
$(OUT)/df-sdiff-%.txt: $(OUT)/df-sred-%.h5 $(OUT)/df-sfull.h5 $$(call df_model,$$*)
	crom-diff $< $(OUT)/df-sfull.h5 --model $(call df_model,$*) $(call df_mesh,$*) --threads 1 $(ATOMIC)
$(OUT)/df-diff-%.txt: $(OUT)/df-red-%.h5 $(OUT)/df-full.h5 $$(call df_model,$$*)
	crom-diff $< $(OUT)/df-full.h5 --model $(call df_model,$*) $(call df_mesh,$*) --threads 1 $(ATOMIC)
# energy at random latents, and collapsed dimensions (the maps against the modes)
$(OUT)/df-metrics-%.txt: $(OUT)/df-%.h5 $(OUT)/df-modes.h5 $(call stamp,df-metrics)
	crom-metrics $(if $(filter-out modes,$*),--compare $(OUT)/df-modes.h5) $(call df_mesh,$*) --samples $(DF_SAMPLES) --seed $(SEED) \
	  --threads 1 $< $(ATOMIC)
$(OUT)/datafree.md: $(OUT)/df-mesh.h5 $(OUT)/df-full.csv $(OUT)/df-modes.log \
                    $(foreach r,$(DF_ROWS),$(OUT)/df-red-$(r).csv $(OUT)/df-diff-$(r).txt $(OUT)/df-sdiff-$(r).txt) \
                    $(foreach m,modes energy neuralmodes field,$(OUT)/df-metrics-$(m).txt)
	( /usr/bin/python3 $(TOP)/pipelines/benchtab.py datafree $(OUT) "$(DF_ROWS)"; echo; \
	  echo "First step from rest (crom-diff, frame 1 of the dynamic run against crom-fullsim; every map starts"; \
	  echo "exactly at rest, x(0) = X):"; echo; echo "| row | first-step error |"; echo "|---|---:|"; \
	  for r in $(DF_ROWS); do awk -v r=$$r '$$1 == 1 { printf "| %s | %.4f |\n", r, $$3 }' $(OUT)/df-diff-$$r.txt; done \
	) > $@.tmp && mv $@.tmp $@

# the soft bar (issue 14): full runs, skinning weights, a METIS cubature for
# data-free poses, the optimized cubature, the runs and their errors
$(eval $(call stamp_rule,df2-scenario,$(DF2_SCENARIO)))
$(eval $(call stamp_rule,df2-static,$(DF2_STATIC)))
$(eval $(call stamp_rule,df2-train,$(DF2_MAT) $(DF2_HANDLES) $(DF2_MINUTES) $(SEED)))
$(eval $(call stamp_rule,df2-cubature,$(DF2_COUNT) $(DF2_METIS) $(DF2_POSE_PARTS) $(DF2_YOUNGS) $(SEED)))
$(OUT)/df2-full.h5 $(OUT)/df2-full.csv &: $(OUT)/df-mesh.h5 $(call stamp,df2-scenario)
	crom-fullsim $(DF2_SCENARIO) --threads 1 --stats $(OUT)/df2-full.csv $(QUIET) -o $(OUT)/df2-full.h5 $<
$(OUT)/df2-sfull.h5: $(OUT)/df-mesh.h5 $(call stamp,df2-static)
	crom-fullsim $(DF2_STATIC) --threads 1 $(QUIET) -o $@ $<
# (mderiv-metis: the modes and their modal derivatives through the same linear path)
$(OUT)/df2-skin-mderiv.h5: $(OUT)/df2-map-mderiv.h5
	cp $< $@
$(OUT)/df2-skin-%.h5: $(OUT)/df-mesh.h5 $(call stamp,df2-train)
	crom-fitfield --objective skinning --weights $* --handles $(DF2_HANDLES) --mesh $< $(DF2_MAT) --pin clamp \
	  $(if $(filter trained,$*),--steps 1000000 --minutes $(DF2_MINUTES)) --seed $(SEED) --threads 1 $(QUIET) -o $@
$(OUT)/df2-pcub-%.h5: $(OUT)/df2-skin-%.h5 $(OUT)/df-mesh.h5 $(call stamp,df2-cubature)
	crom-cubature --model $< --scheme metis --count $(DF2_POSE_PARTS) --threads 1 $(QUIET) -o $@ $(OUT)/df-mesh.h5
$(OUT)/df2-poses-%.h5: $(OUT)/df2-pcub-%.h5 $(call stamp,df2-scenario)
	crom-reducedstep --cubature $< $(DF2_SCENARIO) --threads 1 $(QUIET) -o $@
$(OUT)/df2-sposes-%.h5: $(OUT)/df2-pcub-%.h5 $(call stamp,df2-static)
	crom-reducedstep --cubature $< $(DF2_STATIC) --threads 1 $(QUIET) -o $@
$(OUT)/df2-cub-%-opt.h5: $(OUT)/df2-skin-%.h5 $(OUT)/df2-poses-%.h5 $(OUT)/df2-sposes-%.h5 $(OUT)/df-mesh.h5 \
                         $(call stamp,df2-cubature)
	crom-cubature --model $< --scheme optimized --count $(DF2_COUNT) --max-poses 80 --poses $(OUT)/df2-poses-$*.h5 \
	  --poses $(OUT)/df2-sposes-$*.h5 --youngs $(DF2_YOUNGS) --poisson 0.45 --seed $(SEED) --threads 1 $(QUIET) \
	  -o $@ $(OUT)/df-mesh.h5
$(OUT)/df2-cub-%-metis.h5: $(OUT)/df2-skin-%.h5 $(OUT)/df-mesh.h5 $(call stamp,df2-cubature)
	crom-cubature --model $< --scheme metis --count $(DF2_METIS) --threads 1 $(QUIET) -o $@ $(OUT)/df-mesh.h5
$(OUT)/df2-red-%.h5 $(OUT)/df2-red-%.csv &: $(OUT)/df2-cub-%.h5 $(call stamp,df2-scenario)
	crom-reducedstep --cubature $< $(DF2_SCENARIO) --threads 1 --stats $(OUT)/df2-red-$*.csv $(QUIET) \
	  -o $(OUT)/df2-red-$*.h5
$(OUT)/df2-sred-%.h5: $(OUT)/df2-cub-%.h5 $(call stamp,df2-static)
	crom-reducedstep --cubature $< $(DF2_STATIC) --threads 1 $(QUIET) -o $@
$(OUT)/df2-diff-%.txt: $(OUT)/df2-red-%.h5 $(OUT)/df2-full.h5 $$(OUT)/df2-skin-$$(call df2_kind,$$*).h5
	crom-diff $< $(OUT)/df2-full.h5 --model $(OUT)/df2-skin-$(call df2_kind,$*).h5 --mesh $(OUT)/df-mesh.h5 \
	  --threads 1 $(ATOMIC)
$(OUT)/df2-sdiff-%.txt: $(OUT)/df2-sred-%.h5 $(OUT)/df2-sfull.h5 $$(OUT)/df2-skin-$$(call df2_kind,$$*).h5
	crom-diff $< $(OUT)/df2-sfull.h5 --model $(OUT)/df2-skin-$(call df2_kind,$*).h5 --mesh $(OUT)/df-mesh.h5 \
	  --threads 1 $(ATOMIC)
$(OUT)/df2-metrics-%.txt: $(OUT)/df2-skin-%.h5 $(OUT)/df-mesh.h5
	crom-metrics --mesh $(OUT)/df-mesh.h5 --samples $(DF_SAMPLES) --seed $(SEED) --threads 1 $< $(ATOMIC)
$(eval $(call stamp_rule,df2-maps,$(DF2_MAT) $(DF2_HANDLES) $(DF2_MINUTES) $(DF_MINUTES) $(DF_RANK) $(DF2_DMODES) $(DF2_REFINE_MINUTES) $(DF2_EM_BASE_STEPS) $(SEED)))
$(OUT)/df2-map-sfield.h5: $(OUT)/df-mesh.h5 $(call stamp,df2-maps)
	crom-fitfield --objective field --handles $(DF2_HANDLES) --rank $(DF_RANK) --mesh $< $(DF2_MAT) $(DF_BC) \
	  --steps 1000000 --minutes $(DF2_MINUTES) --seed $(SEED) --threads 1 $(QUIET) -o $@
$(OUT)/df2-map-sfbase.h5: $(OUT)/df-mesh.h5 $(call stamp,df2-maps)
	crom-fitfield --objective field --handles $(DF2_HANDLES) --rank $(DF_RANK) --mesh $< $(DF2_MAT) $(DF_BC) \
	  --steps 1000000 --minutes $(DF2_REFINE_MINUTES) --seed $(SEED) --threads 1 $(QUIET) -o $@
$(OUT)/df2-map-sfref.h5: $(OUT)/df-mesh.h5 $(OUT)/df2-map-sfbase.h5 $(OUT)/df2-msred-sfbase-all.h5
	crom-fitfield --objective field --handles $(DF2_HANDLES) --rank $(DF_RANK) --mesh $< $(DF2_MAT) $(DF_BC) \
	  --init-model $(OUT)/df2-map-sfbase.h5 --latents $(OUT)/df2-msred-sfbase-all.h5 --lr 1e-4 \
	  --steps $(DF2_REFINE_STEPS) --seed $(SEED) --threads 1 $(QUIET) -o $@
$(OUT)/df2-map-field.h5: $(OUT)/df-mesh.h5 $(call stamp,df2-maps)
	crom-fitfield --objective field --rank $(DF_RANK) --mesh $< $(DF2_MAT) $(DF_BC) \
	  --steps 1000000 --minutes $(DF_MINUTES) --seed $(SEED) --threads 1 $(QUIET) -o $@
$(OUT)/df2-map-energy.h5: $(OUT)/df-mesh.h5 $(call stamp,df2-maps)
	crom-fitfield --objective energy --rank $(DF_RANK) --mesh $< $(DF2_MAT) $(DF_BC) \
	  --steps 1000000 --minutes $(DF_MINUTES) --seed $(SEED) --threads 1 $(QUIET) -o $@
$(OUT)/df2-map-embase.h5: $(OUT)/df-mesh.h5 $(call stamp,df2-maps)
	crom-fitfield --objective energy --rank $(DF_RANK) --mesh $< $(DF2_MAT) $(DF_BC) \
	  --steps $(DF2_EM_BASE_STEPS) --seed $(SEED) --threads 1 $(QUIET) -o $@
$(OUT)/df2-map-emref.h5: $(OUT)/df-mesh.h5 $(OUT)/df2-map-embase.h5 $(OUT)/df2-msred-embase-all.h5
	crom-fitfield --objective energy --rank $(DF_RANK) --mesh $< $(DF2_MAT) $(DF_BC) \
	  --init-model $(OUT)/df2-map-embase.h5 --latents $(OUT)/df2-msred-embase-all.h5 --lr 1e-4 \
	  --steps $(DF2_EM_REFINE_STEPS) --seed $(SEED) --threads 1 $(QUIET) -o $@
$(OUT)/df2-map-modes.h5: $(OUT)/df-mesh.h5 $(call stamp,df2-maps)
	crom-modes $(DF2_MAT) --pin clamp --count $(DF_RANK) --threads 1 $(QUIET) -o $@ $<
$(OUT)/df2-map-mderiv.h5: $(OUT)/df-mesh.h5 $(call stamp,df2-maps)
	crom-modes $(DF2_MAT) --pin clamp --count $(DF2_DMODES) --derivatives --threads 1 $(QUIET) -o $@ $<
$(OUT)/df2-map-neuralmodes.h5: $(OUT)/df-mesh.h5 $(OUT)/df2-map-modes.h5 $(call stamp,df2-maps)
	crom-fitfield --objective neuralmodes --mesh $< --modes $(OUT)/df2-map-modes.h5 \
	  --steps 1000000 --minutes $(DF_MINUTES) --seed $(SEED) --threads 1 $(QUIET) -o $@
$(OUT)/df2-map-nmseed.h5: $(OUT)/df-mesh.h5 $(OUT)/df2-map-modes.h5 $(call stamp,df2-maps)
	crom-fitfield --objective neuralmodes --mesh $< --modes $(OUT)/df2-map-modes.h5 --derivatives --steps 0 \
	  --threads 1 $(QUIET) -o $@
$(OUT)/df2-map-nmrun.h5: $(OUT)/df-mesh.h5 $(OUT)/df2-map-modes.h5 $(OUT)/df2-msred-nmseed-all.h5
	crom-fitfield --objective neuralmodes --mesh $< --modes $(OUT)/df2-map-modes.h5 --derivatives --tangent-anchor \
	  --latents $(OUT)/df2-msred-nmseed-all.h5 --steps 1000000 --minutes $(DF_MINUTES) --seed $(SEED) --threads 1 \
	  $(QUIET) -o $@
$(OUT)/df2-mcub-%.h5: $(OUT)/df2-map-%.h5 $(OUT)/df-mesh.h5 $(call stamp,df2-cubature)
	crom-cubature --model $< --scheme optimized --count $(DF2_COUNT) --seed $(SEED) --threads 1 $(QUIET) -o $@ \
	  $(OUT)/df-mesh.h5
$(OUT)/df2-mred-%.h5 $(OUT)/df2-mred-%.csv &: $$(call df2_map_in,$$*) $(call stamp,df2-scenario)
	crom-reducedstep $(call df2_map_args,$*) $(DF2_SCENARIO) --threads 1 --stats $(OUT)/df2-mred-$*.csv $(QUIET) \
	  -o $(OUT)/df2-mred-$*.h5
$(OUT)/df2-msred-%.h5: $$(call df2_map_in,$$*) $(call stamp,df2-static)
	crom-reducedstep $(call df2_map_args,$*) $(DF2_STATIC) --threads 1 $(QUIET) -o $@
$(OUT)/df2-mdiff-%.txt: $(OUT)/df2-mred-%.h5 $(OUT)/df2-full.h5 $$(OUT)/df2-map-$$(call df2_kind,$$*).h5
	crom-diff $< $(OUT)/df2-full.h5 --model $(OUT)/df2-map-$(call df2_kind,$*).h5 --mesh $(OUT)/df-mesh.h5 \
	  --threads 1 $(ATOMIC)
$(OUT)/df2-msdiff-%.txt: $(OUT)/df2-msred-%.h5 $(OUT)/df2-sfull.h5 $$(OUT)/df2-map-$$(call df2_kind,$$*).h5
	crom-diff $< $(OUT)/df2-sfull.h5 --model $(OUT)/df2-map-$(call df2_kind,$*).h5 --mesh $(OUT)/df-mesh.h5 \
	  --threads 1 $(ATOMIC)
$(OUT)/df2-mmetrics-%.txt: $(OUT)/df2-map-%.h5 $(OUT)/df-mesh.h5
	crom-metrics --mesh $(OUT)/df-mesh.h5 --samples $(DF_SAMPLES) --seed $(SEED) --threads 1 $< $(ATOMIC)
$(OUT)/datafree2.md: $(OUT)/df-mesh.h5 $(OUT)/df2-full.csv $(OUT)/df2-sfull.h5 \
                     $(foreach r,$(DF2_ROWS),$(OUT)/df2-red-$(r).csv $(OUT)/df2-diff-$(r).txt $(OUT)/df2-sdiff-$(r).txt \
                       $(OUT)/df2-metrics-$(call df2_kind,$(r)).txt $(OUT)/df2-cub-$(r).h5) \
                     $(foreach r,$(DF2_MAPS),$(OUT)/df2-mred-$(r).csv $(OUT)/df2-mdiff-$(r).txt \
                       $(OUT)/df2-msdiff-$(r).txt $(OUT)/df2-mmetrics-$(call df2_kind,$(r)).txt \
                       $(call df2_map_in,$(r)))
	/usr/bin/python3 $(TOP)/pipelines/benchskin.py $(OUT) "$(DF2_ROWS)" "$(DF2_MAPS)" > $@.tmp && mv $@.tmp $@

# ------------------------------------------------------------------ micro
# the micro-benchmarks of lib/ (tests/unit/bench_*.c, built by `make bench`,
# which passes their paths in BENCHES): element assembly and the MLP field
BENCHES ?= $(wildcard $(TOP)/build/tests/bench_*)
micro: $(OUT)/micro.md
$(OUT)/micro.md: $(wildcard $(BENCHES))
	@mkdir -p $(@D)
	( echo "### micro-benchmarks of lib/ (one core)"; echo; echo '```'; \
	  for b in $(BENCHES); do echo "\$$ $$(basename $$b)"; OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 $$b; done; \
	  echo '```' ) > $@.tmp && mv $@.tmp $@

# ------------------------------------------------------------------ plots
plots: $(OUT)/steps.png $(OUT)/training.png
$(OUT)/steps.png: $(OUT)/tables.md
	gnuplot -e "set terminal pngcairo size 900,500; set output '$@'; set datafile separator ','; \
	  set style data histogram; set style histogram clustered; set style fill solid 0.8; set logscale y; \
	  set yrange [0.1:*]; set key top left; set ylabel 'median step cost (ms)'; \
	  set title 'crom: full vs reduced step cost (one core)'; set xtics rotate by -20; \
	  plot '$(OUT)/table1.csv' every ::1 using 6:xtic(sprintf('%s, %.0fK vertices', strcol(1), column(2)/1000)) \
	    title 'full', '' every ::1 using 7 title 'reduced'"
$(OUT)/training.png: $(OUT)/training.md
	gnuplot -e "set terminal pngcairo size 900,500; set output '$@'; set datafile separator ','; \
	  set logscale y; set xlabel 'training time (s)'; set ylabel 'relative reconstruction error'; \
	  set title 'crom-fitfield on five shapes, r = 20, one core'; set key top right; \
	  plot '$(OUT)/training-lsq.csv' using 2:3 with lines lw 2 title 'lsq (variable projection)', \
	       '$(OUT)/training-pointnet.csv' using 2:3 with lines lw 2 title 'pointnet (joint, LiCROM eq. 4)', \
	       0.02 with lines dt 2 title '2%'"
