# make demo — the built-in default run: mesh a shape, summarize it, export it.
# Run through the top-level Makefile (`make demo`), which builds the programs
# first and passes BINDIR. Outputs go to runs/demo/.
SHELL := /bin/bash
.SHELLFLAGS := -euo pipefail -c
.DELETE_ON_ERROR:
BINDIR ?= $(CURDIR)/bin
export PATH := $(BINDIR):$(PATH)
OUT ?= runs/demo
SIZE ?= 0.06
EXPONENT ?= 4

.PHONY: demo
demo: $(OUT)/shape.vtu $(OUT)/surface.obj $(OUT)/surface.ply
	@echo
	@crom-info $(OUT)/shape.h5
	@echo
	@echo "demo: mesh in $(OUT)/shape.h5; open $(OUT)/shape.vtu in ParaView; surfaces $(OUT)/surface.obj, $(OUT)/surface.ply"

$(OUT)/shape.h5:
	@mkdir -p $(@D)
	crom-mesh superquadric --exponent $(EXPONENT) --size $(SIZE) \
	  --region top='y>0.45' --region bottom='y<-0.45' -v -o $@

$(OUT)/shape.vtu: $(OUT)/shape.h5
	crom-export --format vtu -o $@ $<

$(OUT)/surface.obj: $(OUT)/shape.h5
	crom-export --format obj -o $@ $<

$(OUT)/surface.ply: $(OUT)/shape.h5
	crom-export --format ply -o $@ $<
