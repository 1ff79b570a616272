# make demo — the built-in default run, mesh to pictures: a compact version of
# the shapes experiment (LiCROM Fig. 5/7). Three superquadrics from sphere to
# cube are compressed by crom-fullsim; one neural basis is trained on all
# three; each shape, and a fourth unseen in training, is simulated in the
# 20-dimensional subspace and compared with the full simulation. About a
# minute on one core once built. Run through the top-level Makefile
# (`make demo`), which installs missing packages and builds first.
include $(dir $(lastword $(MAKEFILE_LIST)))common.mk

OUT ?= runs/demo
DEMO_VARS = OUT=$(OUT) TRAIN='2 4 box' TEST='3' SIZE=0.1 STEPS=40 EPOCHS=2500 COUNT=150

.PHONY: all
all:
	@echo "demo: meshes, full simulations, training, cubature and reduced runs under $(OUT)/"
	@$(MAKE) --no-print-directory -f $(TOP)/pipelines/shapes.mk $(DEMO_VARS)
	@echo
	@echo "demo: the strips show each reduced run (top row) over the full simulation (bottom row):"
	@ls $(OUT)/strip-*.png | sed 's/^/  /'
	@echo "demo: open $(OUT)/red-3.pvd in ParaView (Warp By Vector on 'displacement') for the unseen shape"
