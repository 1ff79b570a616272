# make demo — the built-in default run, mesh to pictures: a compact version of
# the shapes experiment (LiCROM Fig. 5/7). Three superquadrics from sphere to
# cube are compressed by crom-fullsim; one neural basis is trained on all
# three; each shape, and a fourth unseen in training, is simulated in the
# 20-dimensional subspace and compared with the full simulation. About a
# minute on one core once built. Run through the top-level Makefile
# (`make demo`), which installs missing packages and builds first. It is the
# shapes experiment (pipelines/shapes.mk) with these settings; any of them
# can be given on the command line as for shapes.mk.
OUT ?= runs/demo
TRAIN ?= 2 4 box
TEST ?= 3
SIZE ?= 0.1
STEPS ?= 40
EPOCHS ?= 2500
COUNT ?= 150
include $(dir $(lastword $(MAKEFILE_LIST)))shapes.mk
