# make bench — timing tables (medians over steps) for crom's stages, written
# as markdown and CSV under bench/results/. Run through the top-level Makefile
# (`make bench`). Sizes can be changed on the command line, e.g.
#   make bench FULL_SIZES="0.056 0.0355" FULL_STEPS=10
SHELL := /bin/bash
.SHELLFLAGS := -euo pipefail -c
.DELETE_ON_ERROR:
.SECONDARY:
BINDIR ?= $(CURDIR)/bin
export PATH := $(BINDIR):$(PATH)
OUT ?= bench/results
TOP := $(CURDIR)

# full-space compression (LiCROM §6.1): a unit cube, top pushed down at 2 m/s
# for 0.1 s, bottom held; mesh sizes for about 5K, 20K and 80K vertices
FULL_SIZES ?= 0.056 0.0355 0.0224
FULL_STEPS ?= 10
FULL_SCENARIO = --velocity 'top=0,-2,0@0:0.1' --pin bottom --gravity 0,0,0 --dt 0.01

.PHONY: bench fullsim
bench: fullsim
	@echo; cat $(OUT)/fullsim.md

fullsim: $(OUT)/fullsim.md

$(OUT)/mesh-%.h5:
	@mkdir -p $(@D)
	crom-mesh box --size $* --algorithm hxt --region top='y>0.499' --region bottom='y<-0.499' -o $@

$(OUT)/fullsim-%.csv: $(OUT)/mesh-%.h5
	crom-fullsim $(FULL_SCENARIO) --steps $(FULL_STEPS) --stats $@ -q -o /dev/null $<

$(OUT)/fullsim.md: $(foreach s,$(FULL_SIZES),$(OUT)/fullsim-$(s).csv)
	$(TOP)/tests/benchtab.sh fullsim $(OUT) $(FULL_SIZES) > $@.tmp && mv $@.tmp $@
